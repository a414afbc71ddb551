// The CDR message decoders on arbitrary bytes: the first byte picks sensor_msgs/PointCloud2 or
// tf2_msgs/TFMessage, the rest is the message. Never crashes, never reads past the buffer;
// a cloud it returns has height x width points, transforms it returns go into a TF buffer that
// answers a lookup without crashing.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "bgkmap/io/point_cloud2.h"
#include "bgkmap/io/tf_buffer.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  if (size < 1) return 0;
  const std::span<const uint8_t> message(data + 1, size - 1);
  if (data[0] % 2 == 0) {
    Result<io::PointCloud2> cloud = io::DecodePointCloud2(message);
    if (cloud.ok() && cloud->points.size() != uint64_t{cloud->height} * cloud->width) std::abort();
    return 0;
  }
  Result<std::vector<io::StampedTransform>> tf = io::DecodeTfMessage(message);
  if (!tf.ok()) return 0;
  io::TfBuffer buffer;
  for (const io::StampedTransform& t : *tf) (void)buffer.Add(t, data[0] % 4 == 1);
  if (!tf->empty()) {
    Result<Pose> p = buffer.Lookup(tf->front().parent, tf->back().child, tf->back().stamp_ns);
    if (p.ok() && !p->rotation.allFinite()) std::abort();
  }
  return 0;
}
