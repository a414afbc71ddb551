#include "scan_encoding.h"

#include <cmath>
#include <utility>
#include <vector>

#include "bgkmap/core/point_filter.h"
#include "bgkmap/proto/compact_points.h"
#include "bgkmap/proto/scan_codec.h"
#include "proto_codec.h"

namespace bgkmap::client_codec {
namespace {

// The pose as the server makes it of the quaternion (normalised); none if it has no norm.
std::optional<Pose> ServerPose(const ScanPose& p) {
  const double norm = std::sqrt(p.qw * p.qw + p.qx * p.qx + p.qy * p.qy + p.qz * p.qz);
  if (!std::isfinite(norm) || norm == 0.0) return std::nullopt;
  return Pose::FromQuaternion(p.qw / norm, p.qx / norm, p.qy / norm, p.qz / norm, p.tx, p.ty, p.tz);
}

// Counts `fate` in `here`; true if the point is sent.
bool Keep(PointFilter fate, bool drop_height, ScanPointCounts* here) {
  switch (fate) {
    case PointFilter::kKept:
      return true;
    case PointFilter::kNonFinite:
      ++here->dropped_nonfinite;
      return false;
    case PointFilter::kRange:
      ++here->dropped_range;
      return false;
    case PointFilter::kHeight:
      if (!drop_height) return true;
      ++here->dropped_height;
      return false;
  }
  return true;
}

// The float32 points worth sending.
std::vector<Point3f> FilterRaw(const ScanData& scan, const MapParams* params, bool drop_height,
                               const std::optional<Pose>& pose, ScanPointCounts* here) {
  std::vector<Point3f> kept;
  kept.reserve(scan.points.size());
  for (const Point3f& p : scan.points) {
    if (params == nullptr || !pose ||
        Keep(FilterSensorPoint(*params, *pose, p), drop_height, here)) {
      kept.push_back(p);
    }
  }
  return kept;
}

// The quantized points worth sending, judged by their dequantized values (what the server
// integrates); false if a finite point has no quantized value.
bool FilterQuantized(const ScanData& scan, double step, const MapParams* params, bool drop_height,
                     const std::optional<Pose>& pose, std::vector<QuantizedPoint>* kept,
                     ScanPointCounts* here) {
  kept->reserve(scan.points.size());
  for (const Point3f& p : scan.points) {
    QuantizedPoint q;
    if (!QuantizePoint(p, step, &q)) {
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) return false;
      ++here->dropped_nonfinite;  // the server drops it too
      continue;
    }
    if (params == nullptr || !pose ||
        Keep(FilterSensorPoint(*params, *pose, DequantizePoint(q, step)), drop_height, here)) {
      kept->push_back(q);
    }
  }
  return true;
}

}  // namespace

std::optional<PointOrder> OrderHint::For(uint64_t index) const {
  const int order = order_.load(std::memory_order_relaxed);
  if (index % kProbeEvery == 0 || order < 0) return std::nullopt;
  return static_cast<PointOrder>(order);
}

void OrderHint::Learn(PointOrder chosen) {
  order_.store(static_cast<int>(chosen), std::memory_order_relaxed);
}

ScanPointCounts EncodeScan(const ScanData& scan, const ScanEncoding& encoding, v1::Scan* out,
                           std::optional<PointOrder> order, PointOrder* chosen) {
  ScanData header = scan;
  header.points = {};
  ToProto(header, out);
  const std::optional<Pose> pose = ServerPose(scan.pose);
  const MapParams* params = encoding.filter ? &*encoding.filter : nullptr;
  ScanPointCounts here;
  here.input = scan.points.size();
  if (encoding.step > 0) {
    std::vector<QuantizedPoint> kept;
    if (FilterQuantized(scan, encoding.step, params, encoding.drop_height, pose, &kept, &here)) {
      Result<CompactPoints> compact = EncodeQuantizedPoints(kept, encoding.step, order);
      if (compact.ok()) {
        if (chosen != nullptr) *chosen = compact->order;
        bgkmap::ToProto(std::move(*compact), out->mutable_compact_points());
        return here;
      }
    }
    here = ScanPointCounts{};
    here.input = scan.points.size();
  }
  const std::vector<Point3f> kept = FilterRaw(scan, params, encoding.drop_height, pose, &here);
  out->mutable_points()->assign(reinterpret_cast<const char*>(kept.data()),
                                kept.size() * sizeof(Point3f));
  return here;
}

ScanPointCounts EncodeHinted(const ScanData& scan, uint64_t index, const ScanEncoding& encoding,
                             OrderHint* hint, v1::Scan* out) {
  const std::optional<PointOrder> order = hint->For(index);
  PointOrder chosen = PointOrder::kScanOrder;
  const ScanPointCounts here = EncodeScan(scan, encoding, out, order, &chosen);
  if (!order && out->has_compact_points()) hint->Learn(chosen);
  return here;
}

void AddDroppedHere(const ScanPointCounts& here, ScanPointCounts* ack) {
  const uint64_t dropped = here.dropped_nonfinite + here.dropped_range + here.dropped_height;
  ack->input += dropped;
  ack->dropped_nonfinite += here.dropped_nonfinite;
  ack->dropped_range += here.dropped_range;
  ack->dropped_height += here.dropped_height;
}

}  // namespace bgkmap::client_codec
