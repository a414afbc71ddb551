// The robots of an Info answer as JSON, as `bgkmap info` and `bgkmap robots` print them.
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

#include "bgkmap/client/client.h"

namespace bgkmap::cli {

inline nlohmann::json RobotsJson(const std::vector<RobotInfo>& robots) {
  nlohmann::json out = nlohmann::json::array();
  for (const RobotInfo& ri : robots) {
    out.push_back({{"robot_id", ri.robot_id},
                   {"last_sequence", ri.last_sequence},
                   {"scans_applied", ri.scans_applied},
                   {"scans_duplicate", ri.scans_duplicate},
                   {"scans_rejected", ri.scans_rejected},
                   {"points_kept", ri.points_kept}});
  }
  return out;
}

}  // namespace bgkmap::cli
