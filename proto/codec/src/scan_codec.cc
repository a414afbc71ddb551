#include "bgkmap/proto/scan_codec.h"

#include <utility>

namespace bgkmap {

void ToProto(const ScanPointCounts& c, v1::PointCounts* out) {
  out->set_input(c.input);
  out->set_kept(c.kept);
  out->set_dropped_nonfinite(c.dropped_nonfinite);
  out->set_dropped_range(c.dropped_range);
  out->set_dropped_height(c.dropped_height);
  out->set_dropped_out_of_bounds(c.dropped_out_of_bounds);
}

ScanPointCounts FromProto(const v1::PointCounts& c) {
  ScanPointCounts counts;
  counts.input = c.input();
  counts.kept = c.kept();
  counts.dropped_nonfinite = c.dropped_nonfinite();
  counts.dropped_range = c.dropped_range();
  counts.dropped_height = c.dropped_height();
  counts.dropped_out_of_bounds = c.dropped_out_of_bounds();
  return counts;
}

void ToProto(CompactPoints compact, v1::CompactPoints* out) {
  out->set_step(compact.step);
  out->set_count(compact.count);
  switch (compact.order) {
    case PointOrder::kSpatialSort:
      out->set_order(v1::POINT_ORDER_SPATIAL_SORT);
      break;
    case PointOrder::kScanRay:
      out->set_order(v1::POINT_ORDER_SCAN_RAY);
      break;
    default:
      out->set_order(v1::POINT_ORDER_SCAN);
  }
  out->set_data(std::move(compact.data));
}

CompactPoints FromProto(const v1::CompactPoints& compact) {
  CompactPoints out;
  out.step = compact.step();
  out.count = compact.count();
  switch (compact.order()) {
    case v1::POINT_ORDER_SCAN:
      out.order = PointOrder::kScanOrder;
      break;
    case v1::POINT_ORDER_SPATIAL_SORT:
      out.order = PointOrder::kSpatialSort;
      break;
    case v1::POINT_ORDER_SCAN_RAY:
      out.order = PointOrder::kScanRay;
      break;
    default:
      out.order = static_cast<PointOrder>(0xff);
  }
  out.data = compact.data();
  return out;
}

}  // namespace bgkmap
