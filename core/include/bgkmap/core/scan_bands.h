// One scan's integration cut into bands of whole tiles that can run on several threads and still
// change the map exactly as the whole scan does, bit for bit (the rule of RestrictScan: a cell
// depends only on the observed cells within ScanReachCells of it).
//
// Each band integrates the scan restricted to its reach. It writes the tiles it owns in place and
// private copies of the other tiles it reads or changes (its halo), taken before any band runs
// and dropped after: so no two bands touch the same tile, and every band reads the map as it was
// before the scan, as the whole scan would. A dense sensor's scan (120k points) then integrates on
// the cores a server has idle instead of on one.
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "bgkmap/core/band_cut.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/terrain_map.h"

namespace bgkmap {

// Cuts the map into up to `count` bands along the longer axis of the scans' observed cells, at
// tile borders, so that the slowest band's work (the observed cells within its halo, summed over
// the scans) is the least (band_cut.h). One band, the whole map, when `count` <= 1, when there is
// nothing to cut, or when the cells span more than 2^21 cells along that axis (210 km at 0.1 m:
// a stray point far from the rest).
std::vector<TileBand> CutScansIntoBands(const MapParams& params,
                                        std::span<const PreparedScan> scans, int count);

// One band's part of a scan's integration into the tiles of `whole` (the scan's window,
// TerrainMap::MakeWindow). Construct every band's part before running any of them (the copies
// are the tiles as they are before the scan); then Run() them concurrently, one thread each.
class BandIntegration {
 public:
  // nullopt if a tile the band must change is not in `whole` (never for bands of one cut; the
  // caller then integrates the scan whole).
  static std::optional<BandIntegration> Make(const MapParams& params, const PreparedScan& scan,
                                             const TileWindow& whole, const TileBand& band);

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

// The whole scan's report from its bands' reports: the changed tiles in order, the point counts
// and observed cells of `scan`, the stage times summed (thread seconds). feature_cells and
// contradicted_cells are summed too, so a halo's cells count once per band that worked on them.
ScanReport MergeBandReports(const PreparedScan& scan, std::vector<ScanReport> parts);

}  // namespace bgkmap
