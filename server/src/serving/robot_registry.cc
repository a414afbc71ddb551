#include "serving/robot_registry.h"

namespace bgkmap {

void RobotRegistry::Restore(const std::map<std::string, uint64_t>& sequences) {
  std::lock_guard lock(mu_);
  for (const auto& [id, sequence] : sequences) {
    RobotProgress& r = robots_[id];
    r.robot_id = id;
    r.last_sequence = sequence;
  }
}

RobotRegistry::Admission RobotRegistry::Admit(const std::string& robot_id, uint64_t sequence,
                                              Stamp stamp, uint64_t points, uint64_t* previous) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  const uint64_t last = it == robots_.end() ? 0 : it->second.last_sequence;
  *previous = last;
  if (it != robots_.end() && sequence <= last) {
    ++it->second.scans_duplicate;
    return Admission::kDuplicate;
  }
  if (max_sequence_jump_ != 0 && sequence - last > max_sequence_jump_) {  // sequence > last here
    if (it != robots_.end()) ++it->second.scans_rejected;
    return Admission::kSequenceJump;
  }
  if (it == robots_.end()) {
    if (robots_.size() >= max_robots_) return Admission::kTooManyRobots;
    it = robots_.emplace(robot_id, RobotProgress{}).first;
    it->second.robot_id = robot_id;
  }
  RobotProgress& r = it->second;
  *previous = r.last_sequence;
  r.last_sequence = sequence;
  r.last_stamp = stamp;
  ++r.scans_applied;
  r.points_kept += points;
  return Admission::kAdmitted;
}

void RobotRegistry::Withdraw(const std::string& robot_id, uint64_t sequence, uint64_t previous,
                             uint64_t points) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return;
  RobotProgress& r = it->second;
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

std::optional<RobotProgress> RobotRegistry::Retire(const std::string& robot_id) {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return std::nullopt;
  RobotProgress gone = std::move(it->second);
  robots_.erase(it);
  return gone;
}

void RobotRegistry::Unretire(const RobotProgress& robot) {
  std::lock_guard lock(mu_);
  robots_.try_emplace(robot.robot_id, robot);
}

std::optional<uint64_t> RobotRegistry::LastSequence(const std::string& robot_id) const {
  std::lock_guard lock(mu_);
  auto it = robots_.find(robot_id);
  if (it == robots_.end()) return std::nullopt;
  return it->second.last_sequence;
}

std::vector<RobotProgress> RobotRegistry::Robots() const {
  std::lock_guard lock(mu_);
  std::vector<RobotProgress> out;
  out.reserve(robots_.size());
  for (const auto& [_, r] : robots_) out.push_back(r);
  return out;
}

}  // namespace bgkmap
