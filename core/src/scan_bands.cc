#include "bgkmap/core/scan_bands.h"

#include <algorithm>
#include <utility>

namespace bgkmap {

std::vector<TileBand> CutScansIntoBands(const MapParams& params,
                                        std::span<const PreparedScan> scans, int count) {
  CellBox box;
  for (const PreparedScan& s : scans) {
    for (const ObservedCell& c : s.cells) box.Extend(c.cell);
  }
  const bool along_x = box.width() >= box.height();
  const int64_t extent = along_x ? box.width() : box.height();
  if (count <= 1 || box.empty() || extent > (int64_t{1} << 21)) return {TileBand{}};
  const int first = along_x ? box.min.x : box.min.y;
  std::vector<int64_t> cells(static_cast<size_t>(extent), 0);
  for (const PreparedScan& s : scans) {
    for (const ObservedCell& c : s.cells) {
      ++cells[static_cast<size_t>((along_x ? c.cell.x : c.cell.y) - first)];
    }
  }
  return BandsBetween(CutBorders(cells, first, params.tile_size, ScanReachCells(params), count),
                      along_x);
}

std::optional<BandIntegration> BandIntegration::Make(const MapParams& params,
                                                     const PreparedScan& scan,
                                                     const TileWindow& whole,
                                                     const TileBand& band) {
  BandIntegration part;
  part.band_ = band;
  part.tile_size_ = params.tile_size;
  part.scan_ = RestrictScan(params, scan, band.Reach(ScanReachCells(params)));
  // The keys MakeWindow would resolve for the restricted scan.
  const std::vector<TileKey> changeable = part.scan_.ChangeableTiles();
  std::vector<TileKey> keys;
  keys.reserve(changeable.size() + part.scan_.read_tiles.size());
  std::merge(changeable.begin(), changeable.end(), part.scan_.read_tiles.begin(),
             part.scan_.read_tiles.end(), std::back_inserter(keys));
  part.window_ = TileWindow(keys);
  const std::vector<TileKey>& writes = part.scan_.write_tiles;
  for (const TileKey& k : keys) {
    Tile* tile = whole.at(k);
    if (tile == nullptr) {
      // A tile the band writes must exist (created by the whole scan's window); the others may
      // be absent (unknown cells).
      if (std::binary_search(writes.begin(), writes.end(), k)) return std::nullopt;
      continue;
    }
    if (!band.Owns(k, params.tile_size)) {
      part.copies_.push_back(std::make_unique<Tile>(*tile));
      tile = part.copies_.back().get();
    }
    part.window_.set(k, tile);
  }
  return part;
}

ScanReport BandIntegration::Run(const TerrainMap& map, uint64_t version) const {
  if (scan_.cells.empty() && scan_.footprint_cells.empty()) return {};
  ScanReport report = map.Integrate(scan_, window_, version);
  // Only the band's own tiles are the map's: the copies' changes go with them.
  size_t kept = 0;
  for (size_t i = 0; i < report.changed_tiles.size(); ++i) {
    if (!band_.Owns(report.changed_tiles[i], tile_size_)) continue;
    report.changed_tiles[kept] = report.changed_tiles[i];
    report.changed_blocks[kept] = report.changed_blocks[i];
    ++kept;
  }
  report.changed_tiles.resize(kept);
  report.changed_blocks.resize(kept);
  return report;
}

ScanReport MergeBandReports(const PreparedScan& scan, std::vector<ScanReport> parts) {
  ScanReport out;
  out.counts = scan.counts;
  out.observed_cells = scan.cells.size();
  std::vector<std::pair<TileKey, uint64_t>> changed;
  for (const ScanReport& p : parts) {
    out.feature_cells += p.feature_cells;
    out.contradicted_cells += p.contradicted_cells;
    out.times.elevation += p.times.elevation;
    out.times.features += p.times.features;
    out.times.traversability += p.times.traversability;
    for (size_t i = 0; i < p.changed_tiles.size(); ++i) {
      changed.emplace_back(p.changed_tiles[i], p.changed_blocks[i]);
    }
  }
  std::sort(changed.begin(), changed.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  out.changed_tiles.reserve(changed.size());
  out.changed_blocks.reserve(changed.size());
  for (const auto& [key, blocks] : changed) {
    out.changed_tiles.push_back(key);
    out.changed_blocks.push_back(blocks);
  }
  return out;
}

}  // namespace bgkmap
