#include "bgkmap/core/scan_bands.h"

#include <algorithm>
#include <memory>
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

namespace {

// One band's part of a scan's integration into the tiles of `whole`. Every band's part is made
// before any runs (the copies are the tiles as they are before the scan); then they run
// concurrently, one thread each.
class BandIntegration {
 public:
  // nullopt if a tile the band must change is not in `whole`.
  static std::optional<BandIntegration> Make(
      const MapParams& params, const PreparedScan& scan, const TileWindow& whole,
      const TileBand& band, std::shared_ptr<const std::vector<ObservedCell>> whole_cells);

  // Integrates the band's part; the report names only the band's own tiles.
  ScanReport Run(const TerrainMap& map, uint64_t version) const;

 private:
  BandIntegration() = default;
  TileBand band_;
  int tile_size_ = 0;
  PreparedScan scan_;  // restricted to the band's reach
  TileWindow window_;  // own tiles: the map's; the others: copies_
  std::vector<std::unique_ptr<Tile>> copies_;
};

std::optional<BandIntegration> BandIntegration::Make(
    const MapParams& params, const PreparedScan& scan, const TileWindow& whole,
    const TileBand& band, std::shared_ptr<const std::vector<ObservedCell>> whole_cells) {
  BandIntegration part;
  part.band_ = band;
  part.tile_size_ = params.tile_size;
  part.scan_ =
      RestrictScan(params, scan, band.Reach(ScanReachCells(params)), std::move(whole_cells));
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

// The whole scan's report from its bands' reports.
ScanReport MergeBandReports(const PreparedScan& scan, std::vector<ScanReport> parts) {
  ScanReport out;
  out.counts = scan.counts;
  out.observed_cells = scan.cells.size();
  std::vector<std::pair<TileKey, TileBlocks>> changed;
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

}  // namespace

std::optional<ScanReport> IntegrateInBands(const TerrainMap& map, const PreparedScan& scan,
                                           const TileWindow& whole,
                                           const std::vector<TileBand>& bands, uint64_t version,
                                           const RunTasks& run) {
  std::vector<BandIntegration> parts;
  // One copy of the whole scan's cells for every band (transient objects' sight test).
  const std::shared_ptr<const std::vector<ObservedCell>> whole_cells =
      WholeCellsOf(map.params(), scan);
  for (const TileBand& band : bands) {
    std::optional<BandIntegration> part =
        BandIntegration::Make(map.params(), scan, whole, band, whole_cells);
    if (!part) return std::nullopt;
    parts.push_back(std::move(*part));
  }
  std::vector<ScanReport> reports(parts.size());
  std::vector<std::function<void()>> tasks;
  for (size_t b = 0; b < parts.size(); ++b) {
    tasks.push_back([&, b] { reports[b] = parts[b].Run(map, version); });
  }
  run(tasks);
  return MergeBandReports(scan, std::move(reports));
}

}  // namespace bgkmap
