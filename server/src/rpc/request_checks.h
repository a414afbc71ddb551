// Validation of incoming requests against the server limits. Every failure is a gRPC status
// whose message names the field, the offending value and the limit (with its config key).
#pragma once

#include <grpcpp/support/status.h>

#include <memory>
#include <string>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/server/server_config.h"
#include "bgkmap/v1/ingest.pb.h"
#include "bgkmap/v1/types.pb.h"

namespace bgkmap {

// Checks a scan (robot id, packed float32 or compact points, pose) and prepares it. Pure: reads
// no map state. Compact points are dequantized first (proto/codec's compact_points.h) and the
// scan is prepared from exactly those points. `raw` (optional) receives the raw scan as
// integrated, for a map that retains scans. `pose` (optional): prepared with this checked pose
// instead of the scan's own (a pose correction on a shard: as a single server prepares a
// retained scan again with its corrected pose).
grpc::Status PrepareScanMessage(const v1::Scan& scan, const MapParams& params,
                                const ServerLimits& limits, PreparedScan* out,
                                std::shared_ptr<RawScan>* raw = nullptr,
                                const Pose* pose_override = nullptr);

// A finite pose within the coordinate limits whose quaternion has unit norm (within
// server.quaternion_tolerance), as the engine's Pose; the message names pose.<field>.
grpc::Status CheckPose(const v1::Pose3& pose, const MapParams& params, const ServerLimits& limits,
                       Pose* out);

// Cheap checks done before anything else (robot id: 1..128 bytes, no control characters), so
// even duplicates are well-formed.
grpc::Status CheckRobotId(const std::string& robot_id);

// The cells covered by a metric box (half-open), widened to multiples of `stride` aligned with
// the global grid. With `limit_cells`, more than limits.max_region_cells output pixels (cells /
// stride^2) or more than limits.max_region_read_cells map cells is INVALID_ARGUMENT (a fixed
// limit: no retry fits).
grpc::Status RegionCells(const v1::BoundingBox& box, const std::string& field,
                         const GridGeometry& geometry, int stride, const ServerLimits& limits,
                         bool limit_cells, CellBox* out);

// A finite coordinate within limits.max_coordinate.
grpc::Status CheckCoordinate(double value, const std::string& field, const ServerLimits& limits);

}  // namespace bgkmap
