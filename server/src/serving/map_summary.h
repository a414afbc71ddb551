// Counts and bounds of the whole served map, kept per tile so that Info and /metrics never lock
// or walk the map. A change only marks the tiles it touched (cheap: a scan touches hundreds of
// tiles, and recounting each one on every scan cost a third of the ingest rate); a reader
// recounts the marked tiles, under their tile locks, when it next asks. Consecutive scans touch
// mostly the same tiles, so the recount is paid once per read, not once per scan, and not at
// all while nobody asks.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile_summary.h"

namespace bgkmap {

struct MapSummary {
  uint64_t tile_count = 0;  // tiles with a known cell
  uint64_t known_cells = 0;
  CellBox known_bounds;  // empty when nothing is known
};

class MapSummaryIndex {
 public:
  // The current summaries of `keys` (sorted), read without the index's locks held.
  using Recount = std::function<std::vector<TileSummary>(std::span<const TileKey> keys)>;

  // After a change, before it is acknowledged: its tiles' summaries are out of date.
  void MarkStale(std::span<const TileKey> keys);
  // Sets the summaries of `keys` (same order) as one step.
  void Update(std::span<const TileKey> keys, std::span<const TileSummary> summaries);
  // Recounts the stale tiles with `recount`, then answers. A change acknowledged before the
  // call is counted; one running meanwhile may or may not be.
  MapSummary Get(const Recount& recount);

 private:
  // Requires mu_. The union of every tile's box: after a tile shrank or went.
  void RecomputeBounds();

  std::mutex recount_mu_;  // one recount at a time
  std::mutex mu_;
  std::unordered_set<TileKey, TileKeyHash> stale_;
  std::unordered_map<TileKey, TileSummary, TileKeyHash> tiles_;  // known tiles only
  uint64_t known_cells_ = 0;
  CellBox bounds_;
};

}  // namespace bgkmap
