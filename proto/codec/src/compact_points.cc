#include "bgkmap/proto/compact_points.h"

#include <zstd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>
#include <utility>

namespace bgkmap {
namespace {

constexpr int64_t kScanOrderLimit = int64_t{1} << 30;  // |q| below it: deltas fit int32
constexpr int64_t kMortonOffset = int64_t{1} << 20;    // 21 bits per axis
constexpr size_t kBytesPerScanOrderPoint = 12;
constexpr size_t kMaxVarintBytes = 10;
// Level 1: on the real sweeps as small as level 3 (KITTI +1%, Ouster -0.2%, the hall the same)
// in about two thirds of the time (docs/benchmarks.md, "Wire bytes per scan").
constexpr int kZstdLevel = 1;

Status CheckStep(double step) {
  if (!std::isfinite(step) || !(step > 0.0) || step > kMaxCompactStep) {
    std::ostringstream m;
    m << "compact_points.step: " << step << " m must be finite and in (0, " << kMaxCompactStep
      << "]";
    return Status::InvalidArgument(m.str());
  }
  return Status::Ok();
}

uint32_t ZigZag(int64_t d) { return static_cast<uint32_t>((d << 1) ^ (d >> 63)); }
int64_t UnZigZag(uint32_t z) { return static_cast<int64_t>(z >> 1) ^ -static_cast<int64_t>(z & 1); }

// Spreads the low 21 bits of v to every third bit.
uint64_t Spread(uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

uint64_t Compact(uint64_t v) {
  v &= 0x1249249249249249ULL;
  v = (v ^ (v >> 2)) & 0x10c30c30c30c30c3ULL;
  v = (v ^ (v >> 4)) & 0x100f00f00f00f00fULL;
  v = (v ^ (v >> 8)) & 0x1f0000ff0000ffULL;
  v = (v ^ (v >> 16)) & 0x1f00000000ffffULL;
  v = (v ^ (v >> 32)) & 0x1fffff;
  return v;
}

void PutPlanes(uint32_t z, size_t n, size_t i, int c, std::string* out) {
  for (int b = 0; b < 4; ++b) (*out)[(b * 3 + c) * n + i] = static_cast<char>(z >> (8 * b));
}

uint32_t GetPlanes(const std::string& bytes, size_t n, size_t i, int c) {
  uint32_t z = 0;
  for (int b = 0; b < 4; ++b) {
    z |= static_cast<uint32_t>(static_cast<uint8_t>(bytes[(b * 3 + c) * n + i])) << (8 * b);
  }
  return z;
}

std::string ScanOrderBytes(const std::span<const QuantizedPoint> points) {
  const size_t n = points.size();
  std::string out(n * kBytesPerScanOrderPoint, '\0');
  int64_t prev[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      PutPlanes(ZigZag(points[i].q[c] - prev[c]), n, i, c, &out);
      prev[c] = points[i].q[c];
    }
  }
  return out;
}

// kScanRay's prediction of point i from the two before it (compact_points.h has the rule).
struct RayPrediction {
  int64_t base[3];  // the linear prediction
  int64_t prev[3];  // q_{i-1}, whose largest axis carries the ray
  int axis = 0;     // that axis
};

RayPrediction PredictRay(const int64_t* prev, const int64_t* before, size_t i) {
  RayPrediction p{};
  for (int c = 0; c < 3; ++c) {
    p.prev[c] = i >= 1 ? prev[c] : 0;
    p.base[c] = i >= 2 ? 2 * prev[c] - before[c] : p.prev[c];
  }
  for (int c = 1; c < 3; ++c) {
    if (std::abs(p.prev[c]) > std::abs(p.prev[p.axis])) p.axis = c;
  }
  return p;
}

// a / b rounded half away from zero, b != 0 (integers only: both ends agree on every machine).
int64_t DivideRounded(int64_t a, int64_t b) {
  const int64_t half = std::abs(b) / 2;
  return (a >= 0 ? a + half : a - half) / b;
}

// The part of the other axes' error the ray's axis predicts: the point moved along its ray.
int64_t AlongRay(const RayPrediction& p, int64_t error_on_axis, int c) {
  if (c == p.axis || p.prev[p.axis] == 0) return 0;
  return DivideRounded(error_on_axis * p.prev[c], p.prev[p.axis]);
}

// None if a residual does not fit int32 (points far apart: the scan order takes them).
std::optional<std::string> ScanRayBytes(const std::span<const QuantizedPoint> points) {
  const size_t n = points.size();
  std::string out(n * kBytesPerScanOrderPoint, '\0');
  for (size_t i = 0; i < n; ++i) {
    const RayPrediction p =
        PredictRay(i >= 1 ? points[i - 1].q : nullptr, i >= 2 ? points[i - 2].q : nullptr, i);
    const int64_t on_axis = points[i].q[p.axis] - p.base[p.axis];
    for (int c = 0; c < 3; ++c) {
      const int64_t r = points[i].q[c] - p.base[c] - AlongRay(p, on_axis, c);
      if (r < std::numeric_limits<int32_t>::min() || r > std::numeric_limits<int32_t>::max()) {
        return std::nullopt;
      }
      PutPlanes(ZigZag(r), n, i, c, &out);
    }
  }
  return out;
}

// Sorts `keys` ascending: least significant byte first, every byte's histogram counted in one
// pass, skipping the bytes every key shares; several times faster than std::sort on 100k keys.
void RadixSort(std::vector<uint64_t>* keys) {
  constexpr int kBytes = 8;
  std::vector<std::array<uint32_t, 256>> count(kBytes);
  for (uint64_t k : *keys) {
    for (int b = 0; b < kBytes; ++b) ++count[b][(k >> (8 * b)) & 0xff];
  }
  std::vector<uint64_t> other(keys->size());
  for (int b = 0; b < kBytes; ++b) {
    const int shift = 8 * b;
    std::array<uint32_t, 256>& start = count[b];
    if (keys->empty() || start[((*keys)[0] >> shift) & 0xff] == keys->size()) continue;
    uint32_t at = 0;
    for (uint32_t& c : start) at += std::exchange(c, at);
    for (uint64_t k : *keys) other[start[(k >> shift) & 0xff]++] = k;
    keys->swap(other);
  }
}

std::string SpatialSortBytes(const std::span<const QuantizedPoint> points) {
  std::vector<uint64_t> keys;
  keys.reserve(points.size());
  for (const QuantizedPoint& p : points) {
    uint64_t key = 0;
    for (int c = 0; c < 3; ++c) key |= Spread(static_cast<uint64_t>(p.q[c] + kMortonOffset)) << c;
    keys.push_back(key);
  }
  RadixSort(&keys);
  std::string out;
  out.reserve(keys.size() * 3);
  uint64_t prev = 0;
  for (uint64_t key : keys) {
    uint64_t d = key - prev;
    prev = key;
    while (d >= 0x80) {
      out.push_back(static_cast<char>(d | 0x80));
      d >>= 7;
    }
    out.push_back(static_cast<char>(d));
  }
  return out;
}

// One zstd context per thread, kept: a fresh one per scan costs its tables' allocation and
// page faults every time (encoders run on several threads of a client at once).
ZSTD_CCtx* CompressContext() {
  thread_local const std::unique_ptr<ZSTD_CCtx, size_t (*)(ZSTD_CCtx*)> context(ZSTD_createCCtx(),
                                                                                ZSTD_freeCCtx);
  return context.get();
}

ZSTD_DCtx* DecompressContext() {
  thread_local const std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> context(ZSTD_createDCtx(),
                                                                                ZSTD_freeDCtx);
  return context.get();
}

std::string Compress(const std::string& bytes) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  const size_t n = ZSTD_compressCCtx(CompressContext(), out.data(), out.size(), bytes.data(),
                                     bytes.size(), kZstdLevel);
  out.resize(ZSTD_isError(n) ? 0 : n);  // cannot fail with a bound-sized buffer
  return out;
}

// Inflates into at most `capacity` bytes; a frame that needs more is refused unread.
Result<std::string> Inflate(const std::string& data, size_t capacity) {
  const unsigned long long declared = ZSTD_getFrameContentSize(data.data(), data.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR) {
    return Status::InvalidArgument("compact_points.data: not a zstd frame");
  }
  if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared > capacity) {
    return Status::InvalidArgument("compact_points.data: inflates to " + std::to_string(declared) +
                                   " bytes, more than count allows (" + std::to_string(capacity) +
                                   ")");
  }
  std::string out(capacity, '\0');
  const size_t n =
      ZSTD_decompressDCtx(DecompressContext(), out.data(), out.size(), data.data(), data.size());
  if (ZSTD_isError(n)) {
    return Status::InvalidArgument(std::string("compact_points.data: ") + ZSTD_getErrorName(n) +
                                   " (inflating to at most " + std::to_string(capacity) +
                                   " bytes, as count allows)");
  }
  out.resize(n);
  return out;
}

// The byte planes of `n` points: 12 bytes each.
Status CheckPlaneBytes(const std::string& bytes, size_t n) {
  if (bytes.size() == n * kBytesPerScanOrderPoint) return Status::Ok();
  return Status::InvalidArgument(
      "compact_points.data: inflates to " + std::to_string(bytes.size()) +
      " bytes, not 12 x count = " + std::to_string(n * kBytesPerScanOrderPoint));
}

Status OutOfRange(size_t i) {
  return Status::InvalidArgument("compact_points.data: point " + std::to_string(i) +
                                 " leaves the quantized range |q| < 2^30");
}

Result<std::vector<Point3f>> DecodeScanOrder(const std::string& bytes, uint32_t count,
                                             double step) {
  const size_t n = count;
  if (Status s = CheckPlaneBytes(bytes, n); !s.ok()) return s;
  std::vector<Point3f> points(n);
  int64_t q[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    float xyz[3];
    for (int c = 0; c < 3; ++c) {
      q[c] += UnZigZag(GetPlanes(bytes, n, i, c));
      if (q[c] <= -kScanOrderLimit || q[c] >= kScanOrderLimit) return OutOfRange(i);
      xyz[c] = Dequantize(q[c], step);
    }
    points[i] = {xyz[0], xyz[1], xyz[2]};
  }
  return points;
}

Result<std::vector<Point3f>> DecodeScanRay(const std::string& bytes, uint32_t count, double step) {
  const size_t n = count;
  if (Status s = CheckPlaneBytes(bytes, n); !s.ok()) return s;
  std::vector<Point3f> points(n);
  int64_t prev[3] = {0, 0, 0}, before[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i) {
    const RayPrediction p = PredictRay(prev, before, i);
    // |residual| <= 2^31 and |q| < 2^30: every product below fits int64.
    const int64_t on_axis = UnZigZag(GetPlanes(bytes, n, i, p.axis));
    int64_t q[3];
    for (int c = 0; c < 3; ++c) {
      const int64_t r = c == p.axis ? on_axis : UnZigZag(GetPlanes(bytes, n, i, c));
      q[c] = p.base[c] + r + AlongRay(p, on_axis, c);
      if (q[c] <= -kScanOrderLimit || q[c] >= kScanOrderLimit) return OutOfRange(i);
    }
    std::copy(prev, prev + 3, before);
    std::copy(q, q + 3, prev);
    points[i] = {Dequantize(q[0], step), Dequantize(q[1], step), Dequantize(q[2], step)};
  }
  return points;
}

Result<std::vector<Point3f>> DecodeSpatialSort(const std::string& bytes, uint32_t count,
                                               double step) {
  std::vector<Point3f> points;
  points.reserve(count);
  uint64_t key = 0;
  size_t at = 0;
  for (uint32_t i = 0; i < count; ++i) {
    uint64_t d = 0;
    for (int shift = 0;; shift += 7) {
      if (at >= bytes.size() || shift > 63) {
        return Status::InvalidArgument("compact_points.data: key " + std::to_string(i) +
                                       " is truncated or over 64 bits");
      }
      const auto byte = static_cast<uint8_t>(bytes[at++]);
      d |= static_cast<uint64_t>(byte & 0x7f) << shift;
      if ((byte & 0x80) == 0) break;
    }
    if (__builtin_add_overflow(key, d, &key) || key >= (uint64_t{1} << 63)) {
      return Status::InvalidArgument("compact_points.data: key " + std::to_string(i) +
                                     " exceeds 63 bits");
    }
    float xyz[3];
    for (int c = 0; c < 3; ++c) {
      xyz[c] = Dequantize(static_cast<int64_t>(Compact(key >> c)) - kMortonOffset, step);
    }
    points.push_back({xyz[0], xyz[1], xyz[2]});
  }
  if (at != bytes.size()) {
    return Status::InvalidArgument("compact_points.data: " + std::to_string(bytes.size() - at) +
                                   " bytes after the last of count keys");
  }
  return points;
}

// std::round(v) for |v| < 2^30 without the libm call: the truncation, then the fraction (v - t is
// exact: both are within a factor of 2 of each other, or t = 0) decides the step away from zero.
int64_t RoundHalfAway(double v) {
  const auto t = static_cast<int64_t>(v);
  const double fraction = v - static_cast<double>(t);
  return t + (fraction >= 0.5) - (fraction <= -0.5);
}

}  // namespace

bool QuantizePoint(const Point3f& p, double step, QuantizedPoint* out) {
  const double xyz[3] = {p.x, p.y, p.z};
  for (int c = 0; c < 3; ++c) {
    const double v = xyz[c] / step;
    // |v| < 2^30 - 1/2 is exactly |round(v)| < 2^30; the negation also refuses NaN.
    if (!(std::abs(v) < static_cast<double>(kScanOrderLimit) - 0.5)) return false;
    out->q[c] = RoundHalfAway(v);
  }
  return true;
}

Result<CompactPoints> EncodeQuantizedPoints(std::span<const QuantizedPoint> points, double step,
                                            std::optional<PointOrder> order) {
  if (Status s = CheckStep(step); !s.ok()) return s;
  if (points.size() > std::numeric_limits<uint32_t>::max()) {
    return Status::InvalidArgument("points: more than 2^32 - 1 points");
  }
  bool fits_morton = true;
  for (const QuantizedPoint& p : points) {
    for (int64_t q : p.q) fits_morton = fits_morton && std::abs(q) < kMortonOffset;
  }
  CompactPoints out;
  out.step = step;
  out.count = static_cast<uint32_t>(points.size());
  // In the order sent: along the rays where every residual fits int32, else plain differences.
  if (order != PointOrder::kSpatialSort || !fits_morton) {
    std::optional<std::string> ray;
    if (order != PointOrder::kScanOrder) ray = ScanRayBytes(points);
    out.order = ray ? PointOrder::kScanRay : PointOrder::kScanOrder;
    out.data = Compress(ray ? *ray : ScanOrderBytes(points));
  }
  if (fits_morton && (!order || order == PointOrder::kSpatialSort)) {
    std::string sorted = Compress(SpatialSortBytes(points));
    if (order || sorted.size() < out.data.size()) {
      out.order = PointOrder::kSpatialSort;
      out.data = std::move(sorted);
    }
  }
  return out;
}

Result<CompactPoints> EncodeCompactPoints(std::span<const Point3f> points, double step,
                                          uint64_t* skipped, std::optional<PointOrder> order) {
  if (Status s = CheckStep(step); !s.ok()) return s;
  std::vector<QuantizedPoint> quantized;
  quantized.reserve(points.size());
  for (const Point3f& p : points) {
    QuantizedPoint q;
    if (QuantizePoint(p, step, &q)) quantized.push_back(q);
  }
  if (skipped != nullptr) *skipped = points.size() - quantized.size();
  return EncodeQuantizedPoints(quantized, step, order);
}

Result<std::vector<Point3f>> DecodeCompactPoints(const CompactPoints& compact,
                                                 uint64_t max_points) {
  if (Status s = CheckStep(compact.step); !s.ok()) return s;
  if (compact.count > max_points) {
    return Status::InvalidArgument("compact_points.count: " + std::to_string(compact.count) +
                                   " points exceed the limit of " + std::to_string(max_points));
  }
  if (compact.count == 0 && compact.data.empty()) return std::vector<Point3f>();
  switch (compact.order) {
    case PointOrder::kScanOrder: {
      Result<std::string> bytes = Inflate(compact.data, compact.count * kBytesPerScanOrderPoint);
      if (!bytes.ok()) return bytes.status();
      return DecodeScanOrder(*bytes, compact.count, compact.step);
    }
    case PointOrder::kScanRay: {
      Result<std::string> bytes = Inflate(compact.data, compact.count * kBytesPerScanOrderPoint);
      if (!bytes.ok()) return bytes.status();
      return DecodeScanRay(*bytes, compact.count, compact.step);
    }
    case PointOrder::kSpatialSort: {
      Result<std::string> bytes = Inflate(compact.data, compact.count * kMaxVarintBytes);
      if (!bytes.ok()) return bytes.status();
      return DecodeSpatialSort(*bytes, compact.count, compact.step);
    }
  }
  return Status::InvalidArgument(
      "compact_points.order: " + std::to_string(static_cast<int>(compact.order)) + " is unknown");
}

}  // namespace bgkmap
