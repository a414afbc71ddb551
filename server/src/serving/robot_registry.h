// The robots that stream to the map: each one's last admitted sequence number and counters.
//
// Sequence numbers: a robot's scan is admitted only if its sequence number is above the robot's
// last admitted one; otherwise it is a duplicate and is not applied again. A scan admitted but
// then refused by the journal is withdrawn, so that its retry is accepted. A sequence number
// more than `max_sequence_jump` above the robot's last one (0 for a new robot) is refused: one
// scan with a huge number (a bug, or another client using the robot's id) would otherwise make
// every later scan of the robot a duplicate.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "durability/durability.h"

namespace bgkmap {

struct RobotProgress {
  std::string robot_id;
  uint64_t last_sequence = 0;
  Stamp last_stamp;
  uint64_t scans_applied = 0;
  uint64_t scans_duplicate = 0;
  uint64_t scans_rejected = 0;
  uint64_t points_kept = 0;
};

class RobotRegistry {
 public:
  // max_sequence_jump 0: no limit.
  explicit RobotRegistry(uint32_t max_robots, uint64_t max_sequence_jump = 0)
      : max_robots_(max_robots), max_sequence_jump_(max_sequence_jump) {}

  // Before anything is admitted: continue from a recovered map.
  void Restore(const std::map<std::string, uint64_t>& sequences);

  enum class Admission { kAdmitted, kDuplicate, kTooManyRobots, kSequenceJump };
  // Admits a scan with `points` kept points; `previous` receives the robot's last sequence
  // number before it (for Withdraw(); for a duplicate or a jump, what to tell the robot).
  Admission Admit(const std::string& robot_id, uint64_t sequence, Stamp stamp, uint64_t points,
                  uint64_t* previous);
  // Undoes Admit() of a scan that was not applied.
  void Withdraw(const std::string& robot_id, uint64_t sequence, uint64_t previous, uint64_t points);

  // Cheap early check (the admission decides): would this sequence number be a duplicate?
  // `last` receives the robot's last sequence number when it would.
  bool IsDuplicate(const std::string& robot_id, uint64_t sequence, uint64_t* last = nullptr) const;
  uint64_t max_sequence_jump() const { return max_sequence_jump_; }
  // Counters of robots already known only, so bad input cannot grow the table.
  void CountRejected(const std::string& robot_id);
  void CountDuplicate(const std::string& robot_id);

  // Forgets the robot (its next scan starts a new sequence, and it no longer counts against
  // max_robots); what it was, or nullopt if it is not known.
  std::optional<RobotProgress> Retire(const std::string& robot_id);
  // Puts back a robot Retire() removed, unless it has been seen again since.
  void Unretire(const RobotProgress& robot);

  std::optional<uint64_t> LastSequence(const std::string& robot_id) const;
  std::vector<RobotProgress> Robots() const;  // sorted by id

 private:
  const uint32_t max_robots_;
  const uint64_t max_sequence_jump_;
  mutable std::mutex mu_;
  std::map<std::string, RobotProgress> robots_;
};

}  // namespace bgkmap
