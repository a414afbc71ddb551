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

#include <functional>
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

// Runs every task before it returns, on whichever threads it chooses.
using RunTasks = std::function<void(std::span<const std::function<void()>>)>;

// `scan` integrated into the tiles of `whole` (its window, TerrainMap::MakeWindow) in `bands` (a
// cut: every tile in exactly one band), one task per band handed to `run`. Returns the whole
// scan's report (changed tiles and blocks in order; feature_cells and contradicted_cells count a
// halo's cells once per band that worked on them, the stage times are summed thread seconds);
// nullopt, with nothing changed, if a tile a band must change is not in `whole` (never for the
// bands of one cut).
std::optional<ScanReport> IntegrateInBands(const TerrainMap& map, const PreparedScan& scan,
                                           const TileWindow& whole,
                                           const std::vector<TileBand>& bands, uint64_t version,
                                           const RunTasks& run);

}  // namespace bgkmap
