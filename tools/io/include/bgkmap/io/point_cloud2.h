// sensor_msgs/msg/PointCloud2 from its CDR bytes: any field layout with x, y and z as FLOAT32 or
// FLOAT64 (count 1) at any offset, any point_step and row_step, organized (height > 1) or not,
// is_bigendian honoured for the point data. NaN points are kept (the engine counts and drops
// them). Other fields are skipped.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/io/cdr_reader.h"

namespace bgkmap::io {

inline constexpr char kPointCloud2Schema[] = "sensor_msgs/msg/PointCloud2";

struct RosHeader {
  int64_t stamp_ns = 0;  // sec * 1e9 + nanosec
  std::string frame_id;
};

struct PointCloud2 {
  RosHeader header;
  uint32_t height = 0, width = 0;
  std::vector<Point3f> points;  // height * width points, row by row
};

// DataLoss naming the field on a truncated message, a missing x/y/z field, an unsupported x/y/z
// type, or a data array too short for height, width, point_step and row_step.
// With RosEncoding::kRos1, ROS 1's sensor_msgs/PointCloud2 (its header has a seq first).
Result<PointCloud2> DecodePointCloud2(std::span<const uint8_t> cdr,
                                      RosEncoding encoding = RosEncoding::kCdr);

}  // namespace bgkmap::io
