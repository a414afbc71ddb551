// The robot-sequence rule, in one place: the single server's RobotRegistry and a cluster
// shard's PartitionReplica both judge a robot's scans by it.
//
// A robot's scan is admitted only if its sequence number is above the robot's last admitted
// one; otherwise it is a duplicate and is not applied again. A sequence number more than
// `max_sequence_jump` above the robot's last one (0 for a new robot) is refused: one scan with a
// huge number (a bug, or another client using the robot's id) would otherwise make every later
// scan of the robot a duplicate. A robot not known yet is refused once `max_robots` are known.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>

namespace bgkmap {

enum class RobotAdmission { kAdmitted, kDuplicate, kTooManyRobots, kSequenceJump };

struct RobotSequenceRule {
  uint32_t max_robots = std::numeric_limits<uint32_t>::max();
  uint64_t max_sequence_jump = 0;  // 0: no limit

  // `last`: the robot's last admitted sequence number, nullopt for a robot not known;
  // `known_robots`: how many robots are known. Checked in this order: duplicate, jump, robots.
  RobotAdmission Judge(std::optional<uint64_t> last, uint64_t sequence,
                       uint64_t known_robots) const {
    if (last.has_value() && sequence <= *last) return RobotAdmission::kDuplicate;
    // sequence > last here, so the difference does not wrap.
    if (max_sequence_jump != 0 && sequence - last.value_or(0) > max_sequence_jump) {
      return RobotAdmission::kSequenceJump;
    }
    if (!last.has_value() && known_robots >= max_robots) return RobotAdmission::kTooManyRobots;
    return RobotAdmission::kAdmitted;
  }
};

}  // namespace bgkmap
