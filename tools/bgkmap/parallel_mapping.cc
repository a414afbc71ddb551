#include "parallel_mapping.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <thread>

#include "bgkmap/core/scan_bands.h"
#include "bgkmap/io/progress_bar.h"

namespace bgkmap::cli {
namespace {

// Runs fn(0..threads-1) on `threads` threads (the caller's included) and joins them.
template <typename Fn>
void RunOnThreads(int threads, Fn fn) {
  std::vector<std::thread> others;
  for (int t = 1; t < threads; ++t) others.emplace_back(fn, t);
  fn(0);
  for (std::thread& t : others) t.join();
}

struct PreparedScans {
  std::vector<PreparedScan> scans;
  Status error;  // the lowest-numbered scan's failure
};

// Reads and prepares every scan on `threads` threads; scans are taken in order from a counter.
// Each scan is read once: the stamps, which count from the first scan's time, are set after.
PreparedScans PrepareAll(const MapParams& params, const ScanSource& source, int threads,
                         double rate_hz) {
  PreparedScans out;
  out.scans.resize(source.size());
  std::vector<Status> errors(source.size());
  std::vector<double> times(source.size(), std::nan(""));
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  RunOnThreads(threads, [&](int) {
    for (size_t k = next++; k < source.size() && !failed; k = next++) {
      Result<SourceScan> scan = source.Read(k);
      if (!scan.ok()) {
        errors[k] = scan.status();
        failed = true;
        break;
      }
      Result<PreparedScan> prepared =
          PrepareScan(params, scan->points, scan->pose, scan->frame_is_map);
      if (!prepared.ok()) {
        // Only the message reaches the user (one line, exit 1).
        errors[k] = Status::InvalidArgument("scan " + std::to_string(k) + ": " +
                                            prepared.status().message());
        failed = true;
        break;
      }
      times[k] = ScanTimeS(*scan, k, rate_hz);
      out.scans[k] = std::move(prepared).value();
    }
  });
  for (Status& s : errors) {
    if (!s.ok()) {
      out.error = s;
      return out;
    }
  }
  // Map time (forgetting).
  const double first_time = times.empty() ? std::nan("") : times[0];
  for (size_t k = 0; k < out.scans.size(); ++k) {
    out.scans[k].stamp_ns = MapTimeNs(times[k], first_time);
  }
  return out;
}

// The whole scan's cells a band's restriction carries (transient objects' sight test), shared
// with the scan instead of copied once per band: `scans` outlive every band (MapScans).
std::shared_ptr<const std::vector<ObservedCell>> WholeCellsView(const MapParams& params,
                                                                const PreparedScan& scan) {
  if (!KeepsTransients(params) || !scan.has_sensor) return nullptr;
  return {std::shared_ptr<const void>(), &scan.cells};  // aliasing, owning nothing
}

// Integrates every scan, restricted to the band's reach, into `map`, in scan order.
StageTimes IntegrateBand(const MapParams& params, const std::vector<PreparedScan>& scans,
                         const TileBand& band, TerrainMap& map, io::ProgressBar* progress) {
  const CellBox keep = band.Reach(ScanReachCells(params));
  StageTimes times;
  PreparedScan restricted;
  for (size_t k = 0; k < scans.size(); ++k) {
    if (progress != nullptr) progress->Add();
    // The whole map (one thread) takes every scan as it is.
    if (!band.IsWholeMap()) {
      restricted = RestrictScan(params, scans[k], keep, WholeCellsView(params, scans[k]));
    }
    const PreparedScan& scan = band.IsWholeMap() ? scans[k] : restricted;
    if (scan.cells.empty() && scan.footprint_cells.empty()) continue;
    const TileWindow window = map.MakeWindow(scan);
    const ScanReport r = map.Integrate(scan, window, k + 1);
    times.elevation += r.times.elevation;
    times.features += r.times.features;
    times.traversability += r.times.traversability;
  }
  return times;
}

}  // namespace

Result<std::unique_ptr<TerrainMap>> MapScans(const MapParams& params, const ScanSource& source,
                                             int threads, double rate_hz, MappingTotals* totals) {
  if (Result<std::unique_ptr<TerrainMap>> created = TerrainMap::Create(params); !created.ok()) {
    return created.status();
  }
  threads = std::max(1, threads);
  PreparedScans prepared = PrepareAll(params, source, threads, rate_hz);
  if (!prepared.error.ok()) return prepared.error;
  for (const PreparedScan& s : prepared.scans) {
    totals->counts.input += s.counts.input;
    totals->counts.kept += s.counts.kept;
    totals->counts.dropped_nonfinite += s.counts.dropped_nonfinite;
    totals->counts.dropped_range += s.counts.dropped_range;
    totals->counts.dropped_height += s.counts.dropped_height;
    totals->counts.dropped_out_of_bounds += s.counts.dropped_out_of_bounds;
  }
  const std::vector<TileBand> bands = CutScansIntoBands(params, prepared.scans, threads);
  std::vector<std::unique_ptr<TerrainMap>> maps(bands.size());
  std::vector<StageTimes> times(bands.size());
  // One bar, as the first band's thread integrates (the bands keep about the same pace).
  io::ProgressBar progress("mapping", prepared.scans.size(), "scans");
  RunOnThreads(static_cast<int>(bands.size()), [&](int b) {
    maps[b] = std::move(TerrainMap::Create(params)).value();  // the same params validated above
    times[b] =
        IntegrateBand(params, prepared.scans, bands[b], *maps[b], b == 0 ? &progress : nullptr);
  });
  // The first band's map becomes the map: its halo's tiles go, the other bands' own tiles are
  // copied in (bitwise, version and stamp included: SetTile).
  std::unique_ptr<TerrainMap> map = std::move(maps[0]);
  std::vector<TileKey> halo;
  map->ForEachTile([&](TileKey key, const Tile&) {
    if (!bands[0].Owns(key, params.tile_size)) halo.push_back(key);
  });
  for (const TileKey& key : halo) map->EraseTile(key);
  for (size_t b = 1; b < bands.size(); ++b) {
    maps[b]->ForEachTile([&](TileKey key, const Tile& tile) {
      if (bands[b].Owns(key, params.tile_size)) map->SetTile(key, tile);
    });
    maps[b].reset();
  }
  for (const StageTimes& t : times) {
    totals->times.elevation += t.elevation;
    totals->times.features += t.features;
    totals->times.traversability += t.traversability;
  }
  map->set_version(source.size());
  return map;
}

}  // namespace bgkmap::cli
