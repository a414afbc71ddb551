// JSON helpers for the CLI's machine-readable output. Every JSON the CLI writes goes through
// nlohmann::json (strings escaped, no bare nan/inf); files whose key order is part of their
// look (regress.json, eval.json, scenario.json) use nlohmann::ordered_json.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bgkmap/client/client.h"

namespace bgkmap::cli {

// NaN (unknown) and +-inf become null: JSON has neither.
template <typename Json = nlohmann::json>
Json JsonNumber(double v) {
  return std::isfinite(v) ? Json(v) : Json(nullptr);
}

// Pretty-printed, newline-terminated; bytes that are not UTF-8 (e.g. in a path) are replaced
// instead of throwing.
template <typename Json>
std::string JsonText(const Json& j) {
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

// The robots of an Info answer, as `bgkmap info` and `bgkmap robots` print them.
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
