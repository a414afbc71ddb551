#include "bgkmap/core/map_params.h"

#include <string>

namespace bgkmap {

std::string_view MethodName(Method m) {
  switch (m) {
    case Method::kBgkPlus:
      return "bgk+";
    case Method::kBgkTrav:
      return "bgk-trav";
    case Method::kBaseline:
      return "baseline";
    case Method::kOneStep:
      return "one-step";
    case Method::kBgkObstacle:
      return "bgk-obstacle";
    case Method::kBgkLocalLinear:
      return "bgk-ll";
  }
  return "?";
}

std::string_view ObservationName(Observation o) { return o == Observation::kMax ? "max" : "mean"; }

std::string_view DynamicsName(Dynamics d) { return d == Dynamics::kOn ? "on" : "off"; }

Result<Dynamics> ParseDynamics(std::string_view name) {
  if (name == "on") return Dynamics::kOn;
  if (name == "off") return Dynamics::kOff;
  return Status::InvalidArgument("dynamics = " + std::string(name) + ": must be one of on, off");
}

Result<Method> ParseMethod(std::string_view name) {
  for (Method m : {Method::kBgkPlus, Method::kBgkTrav, Method::kBaseline, Method::kOneStep,
                   Method::kBgkObstacle, Method::kBgkLocalLinear}) {
    if (name == MethodName(m)) return m;
  }
  return Status::InvalidArgument(
      "method = " + std::string(name) +
      ": must be one of bgk+, bgk-trav, baseline, one-step, bgk-obstacle, bgk-ll");
}

Result<Observation> ParseObservation(std::string_view name) {
  if (name == "max") return Observation::kMax;
  if (name == "mean") return Observation::kMean;
  return Status::InvalidArgument("observation = " + std::string(name) +
                                 ": must be one of max, mean");
}

bool InfersTraversability(Method m) {
  return m == Method::kBgkPlus || m == Method::kOneStep || m == Method::kBgkObstacle ||
         m == Method::kBgkLocalLinear;
}
bool InfersElevation(Method m) {
  return m == Method::kBgkPlus || m == Method::kBgkTrav || m == Method::kBgkLocalLinear;
}
bool KeepsPlaneMoments(Method m) { return m == Method::kBgkLocalLinear; }

bool KeepsTransients(const MapParams& p) {
  return p.transient_confirm_s > 0 && p.dynamics == Dynamics::kOn;
}

}  // namespace bgkmap
