// The compact point encoding of a scan (docs/server.md "Compact scans"), shared by the client
// that encodes and the server that decodes, so both ends dequantize the same way.
//
// Each coordinate is quantized in the sensor frame to an integer q = round(x / step), |q| <
// 2^30, and a point's dequantized coordinate is, by definition,
//   static_cast<float>(static_cast<double>(q) * step).
// The server integrates exactly these points: the map of a compact scan is the map of its
// dequantized points, bit for bit. The integers travel in one of three orders, whichever the
// encoder finds smaller, then zstd:
//   kScanOrder:   the points in the order sent; per point the zigzagged int32 difference to the
//                 previous point (the first to 0), laid out as 12 byte planes (byte b of axis c
//                 for every point, b outer, c inner), 12 bytes per point before zstd.
//   kScanRay:     the points in the order sent, each predicted from the two before it, for a
//                 spinning lidar's points along a ring, where what the prediction misses is mostly
//                 the range: P = 2 q[i-1] - q[i-2] (P = q[0] for point 1, 0 for point 0); the
//                 error e = q[i] - P; m the axis of q[i-1]'s largest |coordinate| (the first of
//                 equals; 0 for point 0); on m the residual is e_m, on each other axis c it is
//                 e_c - round(e_m * q[i-1]_c / q[i-1]_m) (0 subtracted when q[i-1]_m = 0),
//                 rounded half away from zero in integers. Residuals zigzagged int32 in 12 byte
//                 planes as kScanOrder. Integers only, so every machine decodes the same points.
//   kSpatialSort: the points sorted by the Morton key of (q + 2^20) per axis (21 bits each, so
//                 |q| < 2^20); the differences of the sorted keys as LEB128 varints.
// Pure: no I/O, no protobuf. Malformed input is a Status naming what is wrong.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

enum class PointOrder : uint8_t { kScanOrder = 0, kSpatialSort = 1, kScanRay = 2 };

// The default step: 2 mm, so a coordinate moves at most 1 mm, far below any cell.
inline constexpr double kDefaultCompactStep = 0.002;
// Steps the decoder accepts: finite, in (0, kMaxCompactStep].
inline constexpr double kMaxCompactStep = 0.01;

struct CompactPoints {
  double step = kDefaultCompactStep;
  uint32_t count = 0;  // points encoded
  PointOrder order = PointOrder::kScanOrder;
  std::string data;  // one zstd frame
};

// The dequantized value of one coordinate (the rule above).
inline float Dequantize(int64_t q, double step) {
  return static_cast<float>(static_cast<double>(q) * step);
}

struct QuantizedPoint {
  int64_t q[3];
};

// q = round(coordinate / step) per axis; false for a point that has none (a non-finite
// coordinate, or |q| >= 2^30).
bool QuantizePoint(const Point3f& p, double step, QuantizedPoint* out);
inline Point3f DequantizePoint(const QuantizedPoint& p, double step) {
  return {Dequantize(p.q[0], step), Dequantize(p.q[1], step), Dequantize(p.q[2], step)};
}

// Encodes quantized points (each from QuantizePoint with `step`, which must be finite and in
// (0, kMaxCompactStep]). Picks the smaller of kScanRay and kSpatialSort, or `order` if given.
// Where the asked order cannot hold the points the scan order takes them: the spatial sort
// needs every |q| < 2^20, kScanRay every residual within int32.
Result<CompactPoints> EncodeQuantizedPoints(std::span<const QuantizedPoint> points, double step,
                                            std::optional<PointOrder> order = std::nullopt);

// Quantizes and encodes `points`. Points that have no quantized value are left out (the map
// drops a non-finite point anyway); `*skipped` (optional) counts them.
Result<CompactPoints> EncodeCompactPoints(std::span<const Point3f> points, double step,
                                          uint64_t* skipped = nullptr,
                                          std::optional<PointOrder> order = std::nullopt);

// Decodes and dequantizes. INVALID_ARGUMENT-style errors (Status kInvalidArgument) name the
// fault: a step not finite or outside (0, kMaxCompactStep], more than `max_points` points, an
// unknown order, a frame that is not zstd, inflates beyond or short of `count` points, or
// integers out of range.
Result<std::vector<Point3f>> DecodeCompactPoints(const CompactPoints& compact, uint64_t max_points);

}  // namespace bgkmap
