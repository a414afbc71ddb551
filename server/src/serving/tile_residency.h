// Which tiles of the served map are in memory, and in which form. Every operation first pins the
// tiles it touches, which loads the stored ones not in memory and makes dense the packed ones
// (tile.h): the engine and every pinned reader see dense tiles only. Evict() first packs
// unpinned dense tiles, least recently used first, when the dense ones take more than their
// budget (dirty ones too: a packed tile is as authoritative as a dense one), then drops clean,
// unpinned tiles, least recently used first, to stay under a byte bound. A tile in memory is
// authoritative; a tile not in memory is what the backing stores. With a backing that persists
// nothing (a map in memory), nothing is ever evicted, and pins cost nothing unless tiles are
// packed (a dense budget).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "bgkmap/core/status.h"
#include "durability/stored_tiles.h"
#include "serving/residency_stats.h"
#include "serving/tile_table.h"

namespace bgkmap {

class TileResidency {
 public:
  // Tiles an operation uses: they stay in memory until the pins are destroyed.
  class Pins {
   public:
    Pins() = default;
    Pins(Pins&& other) noexcept;
    Pins& operator=(Pins&& other) noexcept;
    Pins(const Pins&) = delete;
    Pins& operator=(const Pins&) = delete;
    ~Pins() { Release(); }
    void Release();

   private:
    friend class TileResidency;
    TileResidency* owner_ = nullptr;
    std::vector<TileKey> keys_;
  };

  // `pack_after_idle`: a tile used more recently than this is not packed even over the dense
  // budget (the tiles the robots are working in: packing them would only have the next scan
  // unpack them again). `persists`: the backing holds tiles (else nothing is evicted). When the
  // tiles in memory exceed `memory_limit_bytes` (0: never; only when persisting), or the dense ones
  // `dense_limit_bytes` (0: tiles are never packed), `on_over_limit` is called (from the thread
  // that crossed it, without locks held) so that someone calls Evict().
  TileResidency(TileTable& table, const StoredTiles& backing, bool persists,
                uint64_t memory_limit_bytes, std::function<void()> on_over_limit,
                uint64_t dense_limit_bytes = 0,
                std::chrono::milliseconds pack_after_idle = std::chrono::seconds(1));

  // Pins `keys` (sorted, unique) and loads the stored ones not in memory: IoError if the store
  // cannot be read. `strict`: a stored tile failing its checksum is DataLoss naming it (readers);
  // otherwise it is left out, and the change starts it afresh (the store keeps it listed).
  Result<Pins> Pin(std::vector<TileKey> keys, bool strict);
  // Pin() without waiting: empty (nothing pinned) if the residency's lock is held right now or
  // any tile would have to be loaded from the store. Packed tiles stay packed (a reader of
  // cells reads either form, tile.h). For a reader that would rather hand its work to another
  // thread than wait on this one.
  std::optional<Pins> TryPinInMemory(std::vector<TileKey> keys);
  // Pin() of a scan's write and read tiles, non-strict (a change starts a corrupt tile afresh).
  Result<Pins> PinScan(const PreparedScan& scan);
  // Pin() of every tile in memory or stored in [min, max].
  Result<Pins> PinRange(TileKey min, TileKey max, bool strict);
  // The keys in [min, max] in memory or stored (sorted, unique).
  std::vector<TileKey> KeysIn(TileKey min, TileKey max) const;

  // Packs unpinned dense tiles idle for `pack_after_idle`, least recently used first, until the
  // dense ones take at most 80% of the dense budget (in batches, not after every scan) if they
  // exceed it; then drops
  // clean, unpinned tiles, least recently used first, until the tiles in memory take at most
  // `target_bytes` (a map that persists). Returns the bytes still held. Tiles changed since the
  // backing's last checkpoint stay: a checkpoint makes them clean.
  uint64_t Evict(uint64_t target_bytes);
  ResidencyStats Stats() const;
  // After tiles were added to memory other than by Pin() (a change creating them).
  void SignalIfOverLimit() const;

 private:
  struct Use {
    uint32_t pins = 0;
    uint64_t last_use = 0;
    std::chrono::steady_clock::time_point used_at;
  };
  void Unpin(const std::vector<TileKey>& keys);
  // With mu_ held: counts a pin and a use of each key.
  void PinLocked(const std::vector<TileKey>& keys);
  // With mu_ held: uses_ kept to the tiles in memory or pinned; the unpinned tiles in memory,
  // (last use, key, bytes), those dense and those clean.
  struct Candidates {
    std::vector<std::pair<uint64_t, TileKey>> dense;
    std::vector<std::tuple<uint64_t, TileKey, uint64_t>> clean;
  };
  Candidates CollectLocked();
  // Packs the least recently used of `dense` when the dense tiles are over their budget; true
  // if it packed any.
  bool PackLocked(std::vector<std::pair<uint64_t, TileKey>>& dense);

  TileTable& table_;
  const StoredTiles& backing_;
  const bool persists_;
  const uint64_t dense_limit_bytes_;
  const std::chrono::milliseconds pack_after_idle_;
  const bool tracks_;  // pins are counted: the map persists or packs
  const uint64_t memory_limit_bytes_;
  const std::function<void()> on_over_limit_;
  std::mutex mu_;  // uses_ and use_clock_
  std::unordered_map<TileKey, Use, TileKeyHash> uses_;
  uint64_t use_clock_ = 0;
  std::atomic<uint64_t> tiles_loaded_{0};
  std::atomic<uint64_t> tiles_evicted_{0};
  std::atomic<uint64_t> tiles_packed_{0};
};

}  // namespace bgkmap
