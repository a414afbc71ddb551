#include "serving/latest_scans.h"

#include <algorithm>

namespace bgkmap {

std::vector<Point3f> ThinPoints(std::span<const Point3f> points, size_t max_points) {
  if (max_points == 0) return {};
  const size_t step = (points.size() + max_points - 1) / max_points;
  if (step <= 1) return {points.begin(), points.end()};
  std::vector<Point3f> kept;
  kept.reserve(points.size() / step + 1);
  for (size_t i = 0; i < points.size(); i += step) kept.push_back(points[i]);
  return kept;
}

LatestScans::LatestScans(size_t max_robots, size_t max_points)
    : max_robots_(std::max<size_t>(max_robots, 1)), max_points_(max_points) {}

void LatestScans::Record(const std::string& robot_id, uint64_t sequence, Stamp stamp,
                         const Pose& pose, std::span<const Point3f> points) {
  // Thinned outside the lock: the copy is the expensive part.
  auto scan = std::make_shared<RobotScan>();
  scan->robot_id = robot_id;
  scan->sequence = sequence;
  scan->stamp = stamp;
  scan->pose = pose;
  scan->points = ThinPoints(points, max_points_);
  scan->points_sent = points.size();
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it != robots_.end() && it->second.scan->sequence > sequence) return;
  if (it == robots_.end() && robots_.size() >= max_robots_) {
    auto oldest = std::min_element(
        robots_.begin(), robots_.end(),
        [](const auto& a, const auto& b) { return a.second.updated < b.second.updated; });
    robots_.erase(oldest);
  }
  robots_[robot_id] = Entry{std::move(scan), ++updates_};
  for (auto& [id, listener] : listeners_) listener(robot_id);
}

std::vector<std::shared_ptr<const RobotScan>> LatestScans::All() const {
  std::lock_guard lock(mu_);
  std::vector<std::shared_ptr<const RobotScan>> out;
  out.reserve(robots_.size());
  for (const auto& [id, entry] : robots_) out.push_back(entry.scan);
  return out;
}

std::shared_ptr<const RobotScan> LatestScans::Find(const std::string& robot_id) const {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  return it == robots_.end() ? nullptr : it->second.scan;
}

uint64_t LatestScans::Listen(Listener listener) {
  std::lock_guard lock(mu_);
  const uint64_t id = next_listener_++;
  listeners_[id] = std::move(listener);
  return id;
}

void LatestScans::Unlisten(uint64_t id) {
  std::lock_guard lock(mu_);
  listeners_.erase(id);
}

}  // namespace bgkmap
