// The robots that stream to the map: each one's last admitted sequence number and counters.
//
// Sequence numbers follow RobotSequenceRule (serving/robot_sequence.h). A scan admitted but
// then refused by the journal is withdrawn, so that its retry is accepted.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/server/robot_stats.h"
#include "serving/robot_sequence.h"

namespace bgkmap {

class RobotRegistry {
 public:
  // max_sequence_jump 0: no limit.
  explicit RobotRegistry(uint32_t max_robots, uint64_t max_sequence_jump = 0)
      : rule_{max_robots, max_sequence_jump} {}

  // Before anything is admitted: continue from a recovered map.
  void Restore(const std::map<std::string, uint64_t>& sequences);

  using Admission = RobotAdmission;
  // Admits a scan with `points` kept points; `previous` receives the robot's last sequence
  // number before it (for Withdraw(); for a duplicate or a jump, what to tell the robot).
  Admission Admit(const std::string& robot_id, uint64_t sequence, Stamp stamp, uint64_t points,
                  uint64_t* previous);
  // Appends the pose of an admitted scan to the robot's recent poses (dropping the oldest
  // beyond RobotStats::kRecentPoses); a robot not known is ignored.
  void RecordPose(const std::string& robot_id, const RobotPose& pose);
  // Undoes Admit() of a scan that was not applied.
  void Withdraw(const std::string& robot_id, uint64_t sequence, uint64_t previous, uint64_t points);

  // Cheap early check (the admission decides): would this sequence number be a duplicate?
  // `last` receives the robot's last sequence number when it would.
  bool IsDuplicate(const std::string& robot_id, uint64_t sequence, uint64_t* last = nullptr) const;
  uint64_t max_sequence_jump() const { return rule_.max_sequence_jump; }
  // Counters of robots already known only, so bad input cannot grow the table.
  void CountRejected(const std::string& robot_id);
  void CountDuplicate(const std::string& robot_id);

  // Forgets the robot (its next scan starts a new sequence, and it no longer counts against
  // max_robots); what it was, or nullopt if it is not known.
  std::optional<RobotStats> Retire(const std::string& robot_id);
  // Puts back a robot Retire() removed, unless it has been seen again since.
  void Unretire(const RobotStats& robot);

  std::optional<uint64_t> LastSequence(const std::string& robot_id) const;
  std::vector<RobotStats> Robots() const;  // sorted by id

 private:
  const RobotSequenceRule rule_;
  mutable std::mutex mu_;
  std::map<std::string, RobotStats> robots_;
};

}  // namespace bgkmap
