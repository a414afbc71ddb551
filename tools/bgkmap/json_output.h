// JSON helpers for the CLI's machine-readable output.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>

namespace bgkmap::cli {

// NaN (unknown) becomes null: JSON has no NaN.
inline nlohmann::json JsonNumber(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace bgkmap::cli
