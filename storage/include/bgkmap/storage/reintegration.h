// Re-integration: the map's tiles as they would be had some logged scans been different (a pose
// correction prepares them again; a removal drops them), rebuilt exactly from a retained
// checkpoint (TileStore::Bases()) and the log after it, without touching the rest of the map.
//
// Which records are replayed, over the history H = the log's records in (base, end):
//   - affected tiles A: from the first revised scan on, the revised scans' tiles before
//     (`seed_tiles`) and after the revision, then, in version order, the tiles a record changes if
//     it reads a tile of A (or is revised): a scan's traversability reads the elevation around it,
//     so a later scan over a corrected region changes too. Only tiles of A can differ from the map
//     as it is.
//   - needed tiles N: A, then, in reverse version order, every tile read by a record that
//     changes a tile of N. The records replayed are those that change a tile of N, onto N's
//     tiles as they were at the base; tiles outside N are neither read nor needed.
// The result equals, bit for bit on A, replaying the whole history from the base with the
// revisions, because every record a tile of A depends on is replayed in the same order onto the
// same state. The work is bounded by the base (the newest retained checkpoint below the oldest
// revised scan) and by N.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/core/tile.h"
#include "bgkmap/storage/tile_store.h"

namespace bgkmap::storage {

struct ReintegrationRequest {
  uint64_t base = 0;                // a retained checkpoint below every revised version
  uint64_t end = 0;                 // the history is the log's records with base < version < end
  std::vector<TileKey> seed_tiles;  // the tiles the revised scans changed as first logged
  // Revised scans that the log does not hold yet, by version: the new training set, or null
  // for a scan that is removed.
  std::map<uint64_t, std::shared_ptr<const PreparedScan>> replacements;
  // Revised scans whose records the log already holds revised (recovery of a correction).
  std::vector<uint64_t> revised_in_log;
  bool plan_only = false;  // compute A and N only, rebuild nothing
};

struct Reintegration {
  std::vector<TileKey> affected;             // A, sorted
  std::vector<std::unique_ptr<Tile>> tiles;  // A's rebuilt tiles (null: none); not plan_only
  std::vector<TileKey> needed;               // N, sorted
  uint64_t records_in_history = 0;
  uint64_t records_replayed = 0;
  double seconds = 0;
};

// The forward half of the rule above: the affected tiles A, grown record by record in version
// order from the first revised scan on. Shared with the cluster (docs/scale-out.md,
// "Corrections are log entries"), whose shards stamp exactly these tiles with a correction's
// version, as a single server's re-integration does.
class AffectedTiles {
 public:
  // The revised scans' tiles as the log held them before the revision (`seed_tiles`).
  void Seed(const std::vector<TileKey>& tiles) { tiles_.insert(tiles.begin(), tiles.end()); }
  // The next scan record of the history (as the revisions make it; a removed scan is no record).
  // `revised`: one of the correction's own revised scans.
  void Add(const PreparedScan& scan, bool revised);
  const std::set<TileKey>& tiles() const { return tiles_; }

 private:
  std::set<TileKey> tiles_;
};

// InvalidArgument if `base` is not retained or a replacement's version is not a scan record
// of the history; DataLoss if a record of the history or a needed tile is corrupt.
Result<Reintegration> Reintegrate(const TileStore& store, const ReintegrationRequest& request);

}  // namespace bgkmap::storage
