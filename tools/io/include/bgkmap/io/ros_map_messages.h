// A map region as ROS 2 messages, in CDR, and the MCAP that carries them:
//   grid_map_msgs/msg/GridMap on /grid_map: every layer of the raster under core's layer names,
//     in grid_map's storage: each layer a column-major size_x x size_y matrix whose index (0, 0)
//     is the cell at the largest x and largest y (x runs down the rows, y along the columns,
//     both decreasing), info.pose the region's centre; unknown is NaN.
//   nav_msgs/msg/OccupancyGrid on /map: row-major from the south-west cell (origin), -1
//     unknown, 100 lethal, otherwise round(100 * traversability) capped at 99.
//   nav2_msgs/msg/Costmap on /costmap: the same cells on Nav2's cost scale: 255 unknown, 254
//     lethal, 253 within robot_radius of a lethal cell (inscribed), otherwise
//     round(252 * traversability).
// "Lethal" is the map's own state layer: a known cell the map calls non-traversable
// (traversability mean >= trav_threshold or its variance >= variance_threshold, or a step over
// step_crit: docs/semantics.md). traversability is a cost in bgkmap (0 flat, 1 blocked).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct RosMapOptions {
  std::string frame_id = "map";
  int64_t stamp_ns = 0;
  double robot_radius = 0;  // metres; > 0 marks the costmap's inscribed cells
};

inline constexpr char kGridMapSchema[] = "grid_map_msgs/msg/GridMap";
inline constexpr char kOccupancyGridSchema[] = "nav_msgs/msg/OccupancyGrid";
inline constexpr char kCostmapSchema[] = "nav2_msgs/msg/Costmap";

// The occupancy values of the raster, row-major from the south-west cell. Needs kState (and
// kTraversability for the graded values; without it every free cell is 0).
Result<std::vector<int8_t>> OccupancyValues(const Raster& raster);

// Nav2 costs, same order.
Result<std::vector<uint8_t>> CostmapValues(const Raster& raster, double robot_radius);

std::string EncodeGridMap(const Raster& raster, const RosMapOptions& options);
Result<std::string> EncodeOccupancyGrid(const Raster& raster, const RosMapOptions& options);
Result<std::string> EncodeCostmap(const Raster& raster, const RosMapOptions& options);

// The "ros2msg" schema text of one of the three types above, dependencies included.
std::string RosMapSchemaText(const std::string& type);

// Writes the three messages to an MCAP (zstd chunks, summary): /grid_map, /map, /costmap.
Status WriteRosMapMcap(const Raster& raster, const std::string& path, const RosMapOptions& options);

}  // namespace bgkmap::io
