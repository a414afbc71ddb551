// bgkmap's map, poses and scans as Foxglove messages (foxglove.Grid, foxglove.FrameTransforms,
// foxglove.PointCloud; proto/foxglove/schemas.proto), encoded, and each schema as the protocol
// advertises it. Pure: what the port sends is tested here without a socket.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/raster.h"
#include "foxglove/protocol.h"
#include "serving/latest_scans.h"

namespace bgkmap::foxglove {

// The map's frame in every message ("map"); a robot's sensor is the frame named by its id.
inline constexpr const char* kMapFrame = "map";

// The channels bgkmapd offers, with their schemas (a FileDescriptorSet of the schema's file and
// its imports, base64).
inline constexpr uint32_t kGridChannel = 1;
inline constexpr uint32_t kTransformsChannel = 2;
inline constexpr uint32_t kScansChannel = 3;
std::vector<Channel> Channels();

// A region of the map as a Grid in the map frame: one FLOAT32 field per layer of the raster,
// named as core's LayerName, in the raster's layer order; rows from south to north (the
// Grid's y-major order; a Raster runs north to south), NaN for unknown cells. `time_ns` is the
// Grid's timestamp.
std::string EncodeGrid(const Raster& raster, uint64_t time_ns);

// Every robot's latest pose as the transform map -> <robot id>, at its scan's stamp.
std::string EncodeTransforms(const std::vector<std::shared_ptr<const RobotScan>>& robots);

// A robot's last scan as a PointCloud in the robot's frame (named by its id; identity pose), the
// points (x, y, z FLOAT32) as sent, at the scan's stamp: the viewer places it with the /tf
// transform of the same stamp, as a ROS viewer places a sensor's cloud.
std::string EncodeScan(const RobotScan& scan);

// The cells of the metric rectangle [x0, x1) x [y0, y1) as a region query reads its bounding box:
// half-open, an edge within a micro-cell of a cell border snapping to it (so -20 / 0.1 =
// -200.00000000000003 starts at cell -200), so the Grid covers the cells a QueryRegion of the same
// box answers.
CellBox RegionCells(const GridGeometry& geometry, double x0, double y0, double x1, double y1);

// A scan's stamp in ns (0 when unstamped or out of range).
uint64_t StampNs(const Stamp& stamp);

}  // namespace bgkmap::foxglove
