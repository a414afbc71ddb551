// What the server knows of each robot that streams to it: the one record the registry keeps,
// Info and /metrics report, and MapServer::Report() returns.
#pragma once

#include <cstdint>
#include <string>

namespace bgkmap {

// A scan's stamp as its robot sent it.
struct Stamp {
  int64_t seconds = 0;
  int32_t nanos = 0;
};

struct RobotStats {
  std::string robot_id;
  uint64_t last_sequence = 0;  // its last admitted scan's (kept across restarts with a store)
  Stamp last_stamp;
  uint64_t scans_applied = 0;    // since start
  uint64_t scans_duplicate = 0;  // acknowledged as duplicates since start
  uint64_t scans_rejected = 0;   // refused (bad input, limits, storage) since start
  uint64_t points_kept = 0;      // of its applied scans, after filtering
};

}  // namespace bgkmap
