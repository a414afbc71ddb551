// The robots that stream to the map: each one's last admitted sequence number and counters.
//
// Sequence numbers: a robot's scan is admitted only if its sequence number is above the robot's
// last admitted one; otherwise it is a duplicate and is not applied again. A scan admitted but
// then refused by the journal is withdrawn, so that its retry is accepted.
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
  explicit RobotRegistry(uint32_t max_robots) : max_robots_(max_robots) {}

  // Before anything is admitted: continue from a recovered map.
  void Restore(const std::map<std::string, uint64_t>& sequences);

  enum class Admission { kAdmitted, kDuplicate, kTooManyRobots };
  // Admits a scan with `points` kept points; `previous` receives the robot's last sequence
  // number before it (for Withdraw()).
  Admission Admit(const std::string& robot_id, uint64_t sequence, Stamp stamp, uint64_t points,
                  uint64_t* previous);
  // Undoes Admit() of a scan that was not applied.
  void Withdraw(const std::string& robot_id, uint64_t sequence, uint64_t previous, uint64_t points);

  // Cheap early check (the admission decides): would this sequence number be a duplicate?
  bool IsDuplicate(const std::string& robot_id, uint64_t sequence) const;
  // Counters of robots already known only, so bad input cannot grow the table.
  void CountRejected(const std::string& robot_id);
  void CountDuplicate(const std::string& robot_id);

  std::optional<uint64_t> LastSequence(const std::string& robot_id) const;
  std::vector<RobotProgress> Robots() const;  // sorted by id

 private:
  const uint32_t max_robots_;
  mutable std::mutex mu_;
  std::map<std::string, RobotProgress> robots_;
};

}  // namespace bgkmap
