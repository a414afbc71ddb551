#include "bgkmap/io/point_cloud2.h"

#include <fmt/format.h>

#include <array>

#include "bgkmap/io/cdr_reader.h"

namespace bgkmap::io {
namespace {

// sensor_msgs/msg/PointField datatypes.
constexpr uint8_t kFloat32 = 7;
constexpr uint8_t kFloat64 = 8;

struct Coordinate {
  bool found = false;
  uint32_t offset = 0;
  uint8_t datatype = 0;
};

RosHeader ReadHeader(CdrReader& r) {
  RosHeader h;
  if (r.ros1()) r.U32("header.seq");
  const int32_t sec = r.I32("header.stamp.sec");
  const uint32_t nanosec = r.U32("header.stamp.nanosec");
  h.stamp_ns = int64_t{sec} * 1'000'000'000 + nanosec;
  h.frame_id = r.String("header.frame_id");
  return h;
}

Status CheckCoordinate(const Coordinate& c, const char* name, uint32_t point_step) {
  if (!c.found) {
    return Status::DataLoss(fmt::format("{}: no field '{}' among its fields (x, y, z are needed)",
                                        kPointCloud2Schema, name));
  }
  if (c.datatype != kFloat32 && c.datatype != kFloat64) {
    return Status::DataLoss(
        fmt::format("{}: field '{}' has datatype {} (only FLOAT32 = 7 and FLOAT64 = 8 are read)",
                    kPointCloud2Schema, name, c.datatype));
  }
  const uint32_t size = c.datatype == kFloat32 ? 4 : 8;
  if (c.offset > point_step || size > point_step - c.offset) {
    return Status::DataLoss(fmt::format("{}: field '{}' at offset {} overruns point_step {}",
                                        kPointCloud2Schema, name, c.offset, point_step));
  }
  return Status::Ok();
}

float LoadCoordinate(const uint8_t* point, const Coordinate& c, bool big_endian) {
  return c.datatype == kFloat32
             ? LoadScalar<float>(point + c.offset, big_endian)
             : static_cast<float>(LoadScalar<double>(point + c.offset, big_endian));
}

}  // namespace

Result<PointCloud2> DecodePointCloud2(std::span<const uint8_t> cdr, RosEncoding encoding) {
  CdrReader r(cdr, kPointCloud2Schema, encoding);
  PointCloud2 cloud;
  cloud.header = ReadHeader(r);
  cloud.height = r.U32("height");
  cloud.width = r.U32("width");
  std::array<Coordinate, 3> xyz;
  const uint32_t nfields = r.SequenceLength("fields", 13);
  for (uint32_t i = 0; i < nfields && r.ok(); ++i) {
    const std::string name = r.String("fields[].name");
    const uint32_t offset = r.U32("fields[].offset");
    const uint8_t datatype = r.U8("fields[].datatype");
    const uint32_t count = r.U32("fields[].count");
    const int axis = name == "x" ? 0 : name == "y" ? 1 : name == "z" ? 2 : -1;
    if (axis >= 0 && count == 1) xyz[axis] = {true, offset, datatype};
  }
  const bool big_endian = r.Bool("is_bigendian");
  const uint32_t point_step = r.U32("point_step");
  const uint32_t row_step = r.U32("row_step");
  const std::span<const uint8_t> data = r.Bytes("data");
  r.Bool("is_dense");
  if (!r.ok()) return r.status();
  const char* names[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    if (Status s = CheckCoordinate(xyz[a], names[a], point_step); !s.ok()) return s;
  }
  // Every row must hold width points and every row start must lie inside data.
  const uint64_t height = cloud.height, width = cloud.width;
  const uint64_t row_bytes = width * point_step;  // < 2^64: both factors < 2^32
  if (height > 0 && width > 0 &&
      (row_step < row_bytes || row_bytes > data.size() ||
       (height - 1) * row_step > data.size() - row_bytes)) {
    return Status::DataLoss(fmt::format(
        "{}: data of {} bytes is too short for {} x {} points of point_step {}, row_step {}",
        kPointCloud2Schema, data.size(), height, width, point_step, row_step));
  }
  // No points (and no loop over a declared 2^32 empty rows): width or height 0.
  if (height == 0 || width == 0) return cloud;
  cloud.points.resize(height * width);
  size_t k = 0;
  for (uint64_t row = 0; row < height; ++row) {
    const uint8_t* p = data.data() + row * row_step;
    for (uint64_t col = 0; col < width; ++col, p += point_step) {
      cloud.points[k++] = {LoadCoordinate(p, xyz[0], big_endian),
                           LoadCoordinate(p, xyz[1], big_endian),
                           LoadCoordinate(p, xyz[2], big_endian)};
    }
  }
  return cloud;
}

}  // namespace bgkmap::io
