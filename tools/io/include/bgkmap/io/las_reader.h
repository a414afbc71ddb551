// ASPRS LAS 1.0-1.4 reader: uncompressed point formats 0-10. Coordinates come out in the file's
// own (map, usually UTM) frame as doubles: X*scale+offset. LAZ is refused with a clear error.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/io/point_cloud.h"

namespace bgkmap::io {

struct LasHeader {
  uint8_t version_major = 0;
  uint8_t version_minor = 0;
  uint16_t header_size = 0;
  uint32_t point_data_offset = 0;
  uint8_t point_format = 0;  // 0-10
  uint16_t point_record_length = 0;
  uint64_t point_count = 0;  // the 1.4 64-bit count when present and non-zero, else legacy
  std::array<double, 3> scale{};
  std::array<double, 3> offset{};
  std::array<double, 3> min{};  // bounds as stored in the header
  std::array<double, 3> max{};
  // The coordinate reference system the variable-length records declare: "EPSG:<code>" from a
  // GeoKeyDirectory (projected, else geographic), or the OGC WKT record's text; empty if none
  // (or unreadable: the points are usable without it).
  std::string crs;
};

struct LasCloud {
  LasHeader header;
  std::vector<Point3d> points;          // kept points, map coordinates
  std::vector<uint8_t> classification;  // ASPRS class of each kept point (2 = ground)
};

struct LasReadOptions {
  // Keep only points of these classes; empty keeps all.
  std::vector<uint8_t> classes;
};

// Parses and checks the header: signature, version, format, record length against the format's
// minimum, and that the file holds all the points the header promises.
Result<LasHeader> ReadLasHeader(const std::string& path);

// Reads the points (filtered by class). Truncated or inconsistent files fail with one DataLoss
// line naming the file.
Result<LasCloud> ReadLas(const std::string& path, const LasReadOptions& options = {});

}  // namespace bgkmap::io
