// PCD v0.7 reader (the Point Cloud Library's format): DATA ascii or binary, any field set that
// includes x, y and z of TYPE F with SIZE 4 or 8 and COUNT 1. Other fields are skipped and
// VIEWPOINT is ignored (points are returned as stored). binary_compressed is refused.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/io/point_cloud.h"

namespace bgkmap::io {

struct PcdCloud {
  std::vector<std::string> fields;  // FIELDS, in file order
  uint64_t width = 0;
  uint64_t height = 0;
  std::vector<Point3d> points;  // every record, NaN points of organised clouds included
};

// Reads a whole PCD file; one DataLoss line naming the file on a malformed header, a missing
// x/y/z field or short data.
Result<PcdCloud> ReadPcd(const std::string& path);

}  // namespace bgkmap::io
