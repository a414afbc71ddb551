// `bgkmap build` on several cores, with the same map bit for bit as one core.
//
// Scans are read and prepared in parallel (PrepareScan is pure, as on the server's ingest pool).
// The map is then cut into bands of whole tiles along its longer axis, at most one band per
// thread, so that the largest band's work (its observed cells and its halo's) is the least
// (band_cut.h); each thread integrates every scan, restricted to its band grown by
// the halo (RestrictScan: the cells within reach of the band), into a map of its own, in scan
// order. A cell's statistics depend only on the observed cells within that reach, so each band's
// own tiles come out exactly as the single map's would (the cluster's partitions rest on the same
// rule, docs/scale-out.md); the other bands' own tiles are then copied into the first band's
// map, whose halo tiles are dropped. A map longer than 2^21 cells along its longer axis (a stray
// point far from the rest) is integrated as one band, on one thread.
//
// Memory: every prepared scan is held until the bands are integrated (a prepared scan is its
// binned cells, 24 bytes each: tens of thousands per lidar scan, far less than its points).
#pragma once

#include <cstdint>
#include <memory>

#include "bgkmap/core/terrain_map.h"
#include "scan_source.h"

namespace bgkmap::cli {

struct MappingTotals {
  ScanPointCounts counts;
  StageTimes times;  // summed over the threads' bands: CPU time, not wall time
};

// Maps every scan of `source` into a new map of `params`, on `threads` threads (>= 1). A scan's
// map time is its time (times.txt; without, k / rate_hz: ScanTimeS) since the first scan, plus
// 1 s. Fails with "scan k: ..." naming the first scan that cannot be read or prepared.
Result<std::unique_ptr<TerrainMap>> MapScans(const MapParams& params, const ScanSource& source,
                                             int threads, double rate_hz, MappingTotals* totals);

}  // namespace bgkmap::cli
