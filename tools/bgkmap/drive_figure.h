// The driven cells' figure of `bgkmap eval` with a footprint: the map around the path, each cell
// coloured by its state and, where it is non-traversable, by why (eval/drive_score.h), the driven
// cells in bright colours (docs/results.md, "Real drives").
#pragma once

#include <span>
#include <string>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/eval/drive_score.h"

namespace bgkmap::cli {

// Writes the PNG over `box` (empty: the driven cells' bounding box grown by 10 m).
Status WriteDriveFigure(const TerrainMap& map, std::span<const eval::DrivenCell> driven,
                        const std::string& path, CellBox box = {});

}  // namespace bgkmap::cli
