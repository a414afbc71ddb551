// JSON helpers for the CLI's machine-readable output. Every JSON the CLI writes goes through
// nlohmann::json (strings escaped, no bare nan/inf); files whose key order is part of their
// look (regress.json, eval.json, scenario.json) use nlohmann::ordered_json.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

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

}  // namespace bgkmap::cli
