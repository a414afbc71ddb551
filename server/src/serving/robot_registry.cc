#include "serving/robot_registry.h"

namespace bgkmap {

void RobotRegistry::Restore(const std::map<std::string, uint64_t>& sequences) {
  std::lock_guard lock(mu_);
  for (const auto& [id, sequence] : sequences) {
    RobotStats& r = robots_[id];
    r.robot_id = id;
    r.last_sequence = sequence;
  }
}

RobotRegistry::Admission RobotRegistry::Admit(const std::string& robot_id, uint64_t sequence,
                                              Stamp stamp, uint64_t points, uint64_t* previous) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  const bool known = it != robots_.end();
  *previous = known ? it->second.last_sequence : 0;
  const Admission a = rule_.Judge(known ? std::optional<uint64_t>(*previous) : std::nullopt,
                                  sequence, robots_.size());
  if (known && a == Admission::kDuplicate) ++it->second.scans_duplicate;
  if (known && a == Admission::kSequenceJump) ++it->second.scans_rejected;
  if (a != Admission::kAdmitted) return a;
  if (!known) {
    it = robots_.emplace(robot_id, RobotStats{}).first;
    it->second.robot_id = robot_id;
  }
  RobotStats& r = it->second;
  *previous = r.last_sequence;
  r.last_sequence = sequence;
  r.last_stamp = stamp;
  ++r.scans_applied;
  r.points_kept += points;
  return Admission::kAdmitted;
}

void RobotRegistry::RecordPose(const std::string& robot_id, const RobotPose& pose) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return;
  std::vector<RobotPose>& poses = it->second.recent_poses;
  if (poses.size() >= RobotStats::kRecentPoses) poses.erase(poses.begin());
  poses.push_back(pose);
}

void RobotRegistry::Withdraw(const std::string& robot_id, uint64_t sequence, uint64_t previous,
                             uint64_t points) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return;
  RobotStats& r = it->second;
  --r.scans_applied;
  r.points_kept -= points;
  if (r.last_sequence == sequence) r.last_sequence = previous;
}

bool RobotRegistry::IsDuplicate(const std::string& robot_id, uint64_t sequence,
                                uint64_t* last) const {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end() || sequence > it->second.last_sequence) return false;
  if (last != nullptr) *last = it->second.last_sequence;
  return true;
}

void RobotRegistry::CountRejected(const std::string& robot_id) {
  std::lock_guard lock(mu_);
  if (auto it = robots_.find(robot_id); it != robots_.end()) ++it->second.scans_rejected;
}

void RobotRegistry::CountDuplicate(const std::string& robot_id) {
  std::lock_guard lock(mu_);
  if (auto it = robots_.find(robot_id); it != robots_.end()) ++it->second.scans_duplicate;
}

std::optional<RobotStats> RobotRegistry::Retire(const std::string& robot_id) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return std::nullopt;
  RobotStats gone = std::move(it->second);
  robots_.erase(it);
  return gone;
}

void RobotRegistry::Unretire(const RobotStats& robot) {
  std::lock_guard lock(mu_);
  robots_.try_emplace(robot.robot_id, robot);
}

std::optional<uint64_t> RobotRegistry::LastSequence(const std::string& robot_id) const {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return std::nullopt;
  return it->second.last_sequence;
}

std::vector<RobotStats> RobotRegistry::Robots() const {
  std::lock_guard lock(mu_);
  std::vector<RobotStats> out;
  out.reserve(robots_.size());
  for (const auto& [_, r] : robots_) out.push_back(r);
  return out;
}

}  // namespace bgkmap
