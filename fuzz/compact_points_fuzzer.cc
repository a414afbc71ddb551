// The compact point decoder (proto/codec's compact_points.h) on arbitrary bytes: 8 bytes of step
// (a double), 4 of count, 1 of order, then the zstd frame. Never crashes, never allocates beyond
// what the count allows (at most 1 << 16 points here); an accepted payload decodes to exactly
// `count` finite points within 2^30 steps of the sensor, and decoding is deterministic.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "bgkmap/proto/compact_points.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  constexpr size_t kHeader = 8 + 4 + 1;
  constexpr uint64_t kMaxPoints = 1 << 16;
  if (size < kHeader) return 0;
  bgkmap::CompactPoints compact;
  std::memcpy(&compact.step, data, 8);
  std::memcpy(&compact.count, data + 8, 4);
  compact.order = static_cast<bgkmap::PointOrder>(data[12]);
  compact.data.assign(reinterpret_cast<const char*>(data + kHeader), size - kHeader);
  bgkmap::Result<std::vector<bgkmap::Point3f>> points =
      bgkmap::DecodeCompactPoints(compact, kMaxPoints);
  if (!points.ok()) return 0;
  if (points->size() != compact.count) std::abort();
  const double bound = std::ldexp(compact.step, 30);
  for (const bgkmap::Point3f& p : *points) {
    for (float v : {p.x, p.y, p.z}) {
      if (!std::isfinite(v) || std::abs(v) > bound) std::abort();
    }
  }
  bgkmap::Result<std::vector<bgkmap::Point3f>> again =
      bgkmap::DecodeCompactPoints(compact, kMaxPoints);
  if (!again.ok() || again->size() != points->size() ||
      (!points->empty() &&
       std::memcmp(again->data(), points->data(), points->size() * sizeof(bgkmap::Point3f)) != 0)) {
    std::abort();
  }
  return 0;
}
