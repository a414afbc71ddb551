// What the server knows of each robot that streams to it: the one record the registry keeps,
// Info and /metrics report, and MapServer::Report() returns.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace bgkmap {

// A scan's stamp as its robot sent it.
struct Stamp {
  int64_t seconds = 0;
  int32_t nanos = 0;
};

// Where a robot's sensor was for one of its scans, in the map frame: x, y in metres and the
// heading (yaw, radians from +x, counter-clockwise) of its sensor's x axis.
struct RobotPose {
  uint64_t sequence = 0;
  double x = 0, y = 0, yaw = 0;
};

struct RobotStats {
  std::string robot_id;
  uint64_t last_sequence = 0;  // its last admitted scan's (kept across restarts with a store)
  Stamp last_stamp;
  uint64_t scans_applied = 0;    // since start
  uint64_t scans_duplicate = 0;  // acknowledged as duplicates since start
  uint64_t scans_rejected = 0;   // refused (bad input, limits, storage) since start
  uint64_t points_kept = 0;      // of its applied scans, after filtering
  // Its admitted scans' poses since start, oldest first, at most kRecentPoses (the web map's
  // trajectory; the latest is where it is). Not kept across restarts.
  static constexpr size_t kRecentPoses = 256;
  std::vector<RobotPose> recent_poses;
};

}  // namespace bgkmap
