#include "bgkmap/io/tf_buffer.h"

#include <fmt/format.h>

#include <cmath>

#include "bgkmap/io/cdr_reader.h"

namespace bgkmap::io {
namespace {

Eigen::Isometry3d ToIsometry(const StampedTransform& t) {
  Eigen::Isometry3d iso = Eigen::Isometry3d::Identity();
  iso.linear() = t.rotation.toRotationMatrix();
  iso.translation() = t.translation;
  return iso;
}

std::string Stamp(int64_t ns) {
  return fmt::format("{}.{:09d}", ns / 1'000'000'000, std::abs(ns % 1'000'000'000));
}

}  // namespace

Result<std::vector<StampedTransform>> DecodeTfMessage(std::span<const uint8_t> cdr,
                                                      RosEncoding encoding) {
  CdrReader r(cdr, kTfMessageSchema, encoding);
  std::vector<StampedTransform> out(r.SequenceLength("transforms", 4 + 4 + 4 + 4 + 7 * 8));
  for (StampedTransform& t : out) {
    if (r.ros1()) r.U32("transforms[].header.seq");
    const int32_t sec = r.I32("transforms[].header.stamp.sec");
    const uint32_t nanosec = r.U32("transforms[].header.stamp.nanosec");
    t.stamp_ns = int64_t{sec} * 1'000'000'000 + nanosec;
    t.parent = r.String("transforms[].header.frame_id");
    t.child = r.String("transforms[].child_frame_id");
    for (int i = 0; i < 3; ++i) t.translation[i] = r.F64("transforms[].transform.translation");
    const double x = r.F64("transforms[].transform.rotation.x");
    const double y = r.F64("transforms[].transform.rotation.y");
    const double z = r.F64("transforms[].transform.rotation.z");
    const double w = r.F64("transforms[].transform.rotation.w");
    if (!r.ok()) return r.status();
    t.rotation = Eigen::Quaterniond(w, x, y, z);
    const double norm = t.rotation.norm();
    if (!t.translation.allFinite() || !std::isfinite(norm) || std::abs(norm - 1.0) > 1e-3) {
      return Status::DataLoss(fmt::format(
          "{}: transform {} -> {} at {}: not a rigid transform (quaternion norm {}, or a "
          "non-finite translation)",
          kTfMessageSchema, t.parent, t.child, Stamp(t.stamp_ns), norm));
    }
    // Unit norm within 1e-3 is what tf2 accepts; normalise so the rotation is orthonormal.
    if (norm != 1.0) t.rotation.normalize();
  }
  if (!r.ok()) return r.status();
  return out;
}

Status TfBuffer::Add(const StampedTransform& t, bool is_static) {
  if (t.parent.empty() || t.child.empty() || t.parent == t.child) {
    return Status::DataLoss(
        fmt::format("{}: transform '{}' -> '{}': frames must be named and differ", kTfMessageSchema,
                    t.parent, t.child));
  }
  Edge& edge = edges_[t.child];
  if (edge.samples.empty()) {
    edge.parent = t.parent;
    edge.is_static = is_static;
  } else if (edge.parent != t.parent) {
    return Status::DataLoss(fmt::format("{}: frame '{}' has two parents, '{}' and '{}'",
                                        kTfMessageSchema, t.child, edge.parent, t.parent));
  }
  if (is_static) {
    edge.is_static = true;
    edge.samples.clear();
  }
  edge.samples[t.stamp_ns] = t;
  return Status::Ok();
}

Result<Eigen::Isometry3d> TfBuffer::EdgeAt(const std::string& child, const Edge& edge,
                                           int64_t stamp_ns) const {
  if (edge.is_static) return ToIsometry(edge.samples.rbegin()->second);
  auto after = edge.samples.lower_bound(stamp_ns);
  if (after != edge.samples.end() && after->first == stamp_ns) return ToIsometry(after->second);
  if (after == edge.samples.begin() || after == edge.samples.end()) {
    return Status::OutOfRange(fmt::format(
        "no transform {} -> {} at {} (its samples span {} to {}; tf never extrapolates)",
        edge.parent, child, Stamp(stamp_ns), Stamp(edge.samples.begin()->first),
        Stamp(edge.samples.rbegin()->first)));
  }
  const auto before = std::prev(after);
  const double s = static_cast<double>(stamp_ns - before->first) /
                   static_cast<double>(after->first - before->first);
  StampedTransform mid;
  mid.translation = (1.0 - s) * before->second.translation + s * after->second.translation;
  mid.rotation = before->second.rotation.slerp(s, after->second.rotation);
  return ToIsometry(mid);
}

Result<std::vector<std::pair<std::string, Eigen::Isometry3d>>> TfBuffer::Chain(
    const std::string& frame, int64_t stamp_ns) const {
  std::vector<std::pair<std::string, Eigen::Isometry3d>> chain;
  chain.emplace_back(frame, Eigen::Isometry3d::Identity());
  for (auto it = edges_.find(frame); it != edges_.end(); it = edges_.find(it->second.parent)) {
    if (chain.size() > edges_.size()) {
      return Status::DataLoss(
          fmt::format("{}: the frames above '{}' form a cycle", kTfMessageSchema, frame));
    }
    Result<Eigen::Isometry3d> edge = EdgeAt(it->first, it->second, stamp_ns);
    if (!edge.ok()) return edge.status();
    // The first edge is taken as is, so a one-edge chain is the sample itself, bit for bit.
    chain.emplace_back(it->second.parent,
                       chain.size() == 1 ? *edge : Eigen::Isometry3d(*edge * chain.back().second));
  }
  return chain;
}

Result<Pose> TfBuffer::Lookup(const std::string& target, const std::string& source,
                              int64_t stamp_ns) const {
  auto up_source = Chain(source, stamp_ns);
  if (!up_source.ok()) return up_source.status();
  auto up_target = Chain(target, stamp_ns);
  if (!up_target.ok()) return up_target.status();
  for (const auto& [ancestor, t_ancestor_target] : *up_target) {
    for (const auto& [name, t_ancestor_source] : *up_source) {
      if (name != ancestor) continue;
      Pose pose;
      if (ancestor == target) {  // target above source: no inverse, no identity product
        pose.rotation = t_ancestor_source.linear();
        pose.translation = t_ancestor_source.translation();
      } else {
        const Eigen::Isometry3d t = t_ancestor_target.inverse() * t_ancestor_source;
        pose.rotation = t.linear();
        pose.translation = t.translation();
      }
      return pose;
    }
  }
  return Status::OutOfRange(
      fmt::format("no chain of transforms from '{}' to '{}'", source, target));
}

}  // namespace bgkmap::io
