// The TF tree of a recording: tf2_msgs/msg/TFMessage decoded from CDR, and a buffer answering
// "where is frame F in frame M at time t" through any chain of transforms, as tf2 does: each
// child frame has one parent; a dynamic edge is interpolated between its two samples around t
// (linear translation, slerp rotation) and never extrapolated; a /tf_static edge holds at every
// time. A lookup with no chain, or a time outside an edge's samples, is an error, not a guess.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/io/cdr_reader.h"

namespace bgkmap::io {

inline constexpr char kTfMessageSchema[] = "tf2_msgs/msg/TFMessage";

// geometry_msgs/msg/TransformStamped: p_parent = rotation * p_child + translation.
struct StampedTransform {
  int64_t stamp_ns = 0;
  std::string parent, child;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

// DataLoss naming the field on a truncated or malformed message, or a non-finite or zero
// quaternion.
// With RosEncoding::kRos1, ROS 1's tf2_msgs/TFMessage (or tf/tfMessage: the same fields).
Result<std::vector<StampedTransform>> DecodeTfMessage(std::span<const uint8_t> cdr,
                                                      RosEncoding encoding = RosEncoding::kCdr);

class TfBuffer {
 public:
  // Adds a sample of the edge parent -> child. A child that already has another parent is
  // refused (the tree would be ambiguous).
  Status Add(const StampedTransform& t, bool is_static);

  // T_target_source at `stamp_ns`: maps points of frame `source` into frame `target`.
  Result<Pose> Lookup(const std::string& target, const std::string& source, int64_t stamp_ns) const;

 private:
  struct Edge {
    std::string parent;
    bool is_static = false;
    std::map<int64_t, StampedTransform> samples;  // by stamp; a static edge keeps its last
  };
  // T_parent_child of `child`'s edge at the stamp, or an error naming the edge.
  Result<Eigen::Isometry3d> EdgeAt(const std::string& child, const Edge& edge,
                                   int64_t stamp_ns) const;
  // T_ancestor_frame for every ancestor of `frame` (the frame itself first, with identity).
  Result<std::vector<std::pair<std::string, Eigen::Isometry3d>>> Chain(const std::string& frame,
                                                                       int64_t stamp_ns) const;

  std::map<std::string, Edge> edges_;  // by child frame
};

}  // namespace bgkmap::io
