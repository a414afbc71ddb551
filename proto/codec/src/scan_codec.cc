#include "bgkmap/proto/scan_codec.h"

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

}  // namespace bgkmap
