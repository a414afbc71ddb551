#include "bgkmap/core/map_param_table.h"

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace bgkmap {
namespace {

std::string Num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

Status Bad(std::string_view key, double value, std::string_view rule) {
  return Status::InvalidArgument(std::string(key) + " = " + Num(value) + ": " + std::string(rule));
}

// The rules of MapParamInfo::check.

Status Positive(std::string_view key, double v, const MapParams&) {
  if (!std::isfinite(v) || v <= 0) return Bad(key, v, "must be a finite number > 0");
  return Status::Ok();
}

Status FiniteNonNegative(std::string_view key, double v, const MapParams&) {
  if (!std::isfinite(v) || v < 0) return Bad(key, v, "must be finite and >= 0");
  return Status::Ok();
}

Status Finite(std::string_view key, double v, const MapParams&) {
  if (!std::isfinite(v)) return Bad(key, v, "must be finite");
  return Status::Ok();
}

Status NotNaN(std::string_view key, double v, const MapParams&) {
  if (std::isnan(v)) return Bad(key, v, "must be a number");
  return Status::Ok();
}

Status Resolution(std::string_view key, double v, const MapParams& p) {
  if (Status s = Positive(key, v, p); !s.ok()) return s;
  if (v < 1e-3 || v > 100) return Bad(key, v, "must lie in [0.001, 100] metres");
  return Status::Ok();
}

// A stencil radius in cells, bounded so cell arithmetic stays exact.
Status StencilRadius(std::string_view key, double v, const MapParams& p) {
  if (v / p.resolution > kMaxStencilRadiusCells) {
    return Bad(key, v, "must be <= " + std::to_string(kMaxStencilRadiusCells) + " * resolution");
  }
  return Status::Ok();
}

// A length in cells: positive, at least one cell (else `why`), and within the stencil limit.
Status CellLength(std::string_view key, double v, const MapParams& p, const std::string& why) {
  if (Status s = Positive(key, v, p); !s.ok()) return s;
  if (v < p.resolution)
    return Bad(key, v, "must be >= resolution (" + Num(p.resolution) + ")" + why);
  return StencilRadius(key, v, p);
}

Status KernelLength(std::string_view key, double v, const MapParams& p) {
  return CellLength(key, v, p, ", or no neighbour is ever inferred");
}

Status RobotRadius(std::string_view key, double v, const MapParams& p) {
  return CellLength(key, v, p, " to span the 3 cells a plane needs");
}

Status SlopeCrit(std::string_view key, double v, const MapParams& p) {
  if (Status s = Positive(key, v, p); !s.ok()) return s;
  if (v > 90) return Bad(key, v, "must be <= 90 degrees");
  return Status::Ok();
}

Status Weights(std::string_view key, double, const MapParams& p) {
  double sum = 0;
  for (double w : p.weights) {
    if (!std::isfinite(w) || w < 0) return Bad(key, w, "every weight must be finite and >= 0");
    sum += w;
  }
  if (std::abs(sum - 1.0) > 1e-6) {
    return Bad(key, sum, "[w_step, w_slope, w_rough] must sum to 1 (paper Eq. 5)");
  }
  return Status::Ok();
}

Status TravThreshold(std::string_view key, double v, const MapParams&) {
  if (!std::isfinite(v) || v <= 0 || v > 1) return Bad(key, v, "must lie in (0, 1]");
  return Status::Ok();
}

Status MaxRange(std::string_view key, double v, const MapParams& p) {
  if (!std::isfinite(v) || v <= p.min_range) {
    return Bad(key, v, "must be finite and > min_range (" + Num(p.min_range) + ")");
  }
  return Status::Ok();
}

Status UnitInterval(std::string_view key, double v, const MapParams&) {
  if (!std::isfinite(v) || v < 0 || v > 1) return Bad(key, v, "must lie in [0, 1]");
  return Status::Ok();
}

Status ConfidenceScans(std::string_view key, double v, const MapParams&) {
  if (!std::isfinite(v) || v < 1) return Bad(key, v, "must be finite and >= 1 (scans)");
  return Status::Ok();
}

// Rays are walked cell by cell: their length bounds the per-scan cost.
Status RayLength(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 50) return Bad(key, v, "must be <= 50 metres");
  return Status::Ok();
}

Status TileSize(std::string_view key, double v, const MapParams&) {
  if (v < kMinTileSize || v > kMaxTileSize) {
    return Bad(key, v,
               "must lie in [" + std::to_string(kMinTileSize) + ", " +
                   std::to_string(kMaxTileSize) + "] cells");
  }
  return Status::Ok();
}

// Entry builders, one per kind.
constexpr bool kStats = true;     // shapes the stored statistics
constexpr bool kDerived = false;  // enters derived layers only
using Check = Status (*)(std::string_view, double, const MapParams&);

// Sensor height above the footprint: 0 (off) up to 10 m.
Status SensorHeight(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 10) return Bad(key, v, "must be <= 10 metres (0: off)");
  return Status::Ok();
}

// The footprint's weight: real returns must win, so at most one observation.
Status FootprintWeight(std::string_view key, double v, const MapParams& p) {
  if (Status s = Positive(key, v, p); !s.ok()) return s;
  if (v > 1) return Bad(key, v, "must lie in (0, 1]: a real return must outweigh the footprint");
  return Status::Ok();
}

// Full-kernel observations: 0 (off) up to the confidence cap's order.
Status ThinWeight(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 100) return Bad(key, v, "must lie in [0, 100] full-kernel observations");
  return Status::Ok();
}

// A pose's vertical error: 0 (off) up to 0.5 m (beyond that no step could be told from noise).
Status PoseSigmaZ(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 0.5) return Bad(key, v, "must lie in [0, 0.5] metres (0: off)");
  return Status::Ok();
}

// A footprint box edge: 0 or a vehicle's size, up to 20 m. The box needs both edges > 0; with
// either 0 the footprint is the disk (no cross-check: stores written before the keys existed
// name them one at a time, each with its legacy 0).
Status FootprintEdge(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 20) return Bad(key, v, "must be <= 20 metres (0: the disk of robot_radius)");
  return Status::Ok();
}

// How far the self-filter box reaches below the sensor: 0 (off) up to 20 m.
Status SelfFilterBelow(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 20) return Bad(key, v, "must lie in [0, 20] metres (0: off)");
  return Status::Ok();
}

// The self-filter box's margin about the footprint box (mirrors, racks): 0 up to 5 m.
Status SelfFilterMargin(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 5) return Bad(key, v, "must lie in [0, 5] metres");
  return Status::Ok();
}

// Transient objects keep whole cells' statistics aside, which bgk-ll's plane moments are not
// part of: refused there rather than restoring half a cell.
Status TransientConfirm(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 3600) return Bad(key, v, "must lie in [0, 3600] seconds (0: off)");
  if (v > 0 && KeepsPlaneMoments(p.method)) {
    return Bad(key, v, "must be 0 with method bgk-ll (its cells keep plane moments)");
  }
  return Status::Ok();
}

Status TransientExpire(std::string_view key, double v, const MapParams& p) {
  if (Status s = FiniteNonNegative(key, v, p); !s.ok()) return s;
  if (v > 3600) return Bad(key, v, "must lie in [0, 3600] seconds");
  return Status::Ok();
}

// The sensor's offset from the footprint box's centre, within 20 m.
Status FootprintOffset(std::string_view key, double v, const MapParams& p) {
  if (Status s = Finite(key, v, p); !s.ok()) return s;
  if (std::abs(v) > 20) return Bad(key, v, "must lie in [-20, 20] metres");
  return Status::Ok();
}

MapParamInfo Real(std::string_view key, double MapParams::*field, bool shapes, Check check,
                  std::string_view doc) {
  MapParamInfo info{key, MapParamKind::kDouble, shapes, doc};
  info.real = field;
  info.check = check;
  return info;
}

MapParamInfo Integer(std::string_view key, int MapParams::*field, bool shapes, Check check,
                     std::string_view doc) {
  MapParamInfo info{key, MapParamKind::kInt, shapes, doc};
  info.integer = field;
  info.check = check;
  return info;
}

MapParamInfo Triple(std::string_view key, std::array<double, 3> MapParams::*field, bool shapes,
                    Check check, std::string_view doc) {
  MapParamInfo info{key, MapParamKind::kDouble3, shapes, doc};
  info.triple = field;
  info.check = check;
  return info;
}

// An enum field with its Name(value) and Parse(name) functions.
template <auto field, auto name_of, auto parse>
MapParamInfo Enum(std::string_view key, bool shapes, std::string_view doc) {
  MapParamInfo info{key, MapParamKind::kEnum, shapes, doc};
  info.enum_name = [](const MapParams& p) { return name_of(p.*field); };
  info.enum_parse = [](std::string_view text, MapParams& p) {
    auto value = parse(text);
    if (!value.ok()) return value.status();
    p.*field = *value;
    return Status::Ok();
  };
  return info;
}

MapParamInfo Legacy(MapParamInfo info, std::string_view legacy_text) {
  info.legacy_text = legacy_text;
  return info;
}

using P = MapParams;

// Beyond the paper: dynamics, the footprint, forgetting (docs/semantics.md), after the rest.
std::vector<MapParamInfo> ChangingWorldEntries();

const std::vector<MapParamInfo>& Table() {
  static const std::vector<MapParamInfo> table = [] {
    std::vector<MapParamInfo> t = {
        Real("resolution", &P::resolution, kStats, Resolution, "cell edge, metres"),
        Real("kernel_length", &P::kernel_length, kStats, KernelLength,
             "sparse kernel support l, metres"),
        // The elevation a scan's v is computed from depends on the prior too.
        Real("lambda", &P::lambda, kStats, FiniteNonNegative,
             "prior confidence in prior_mean (0 = none, as the paper)"),
        Real("prior_mean", &P::prior_mean, kStats, Finite, "prior elevation mu0, metres"),
        Real("sigma2", &P::sigma2, kDerived, Positive, "observation noise variance, m^2"),
        Real("alpha0", &P::alpha0, kDerived, Positive,
             "Beta prior pseudo-count for \"non-traversable\""),
        Real("beta0", &P::beta0, kDerived, Positive, "Beta prior pseudo-count for \"traversable\""),
        Real("robot_radius", &P::robot_radius, kStats, RobotRadius,
             "neighbourhood for step, slope and roughness, metres"),
        Real("step_crit", &P::step_crit, kStats, Positive, "critical step height, metres"),
        Real("slope_crit_deg", &P::slope_crit_deg, kStats, SlopeCrit, "critical slope, degrees"),
        Real("roughness_crit", &P::roughness_crit, kStats, Positive, "critical roughness, metres"),
        // Maps from before it discounted nothing (0).
        Legacy(Real("pose_sigma_z", &P::pose_sigma_z, kStats, PoseSigmaZ,
                    "the poses' vertical error per scan (1 sigma), metres; step and roughness "
                    "discount it; 0: off"),
               "0"),
        Triple("weights", &P::weights, kStats, Weights,
               "[w_step, w_slope, w_rough] of v (Eq. 5), summing to 1"),
        Real("trav_threshold", &P::trav_threshold, kDerived, TravThreshold, "v_th of Eq. 6"),
        Real("variance_threshold", &P::variance_threshold, kDerived, Positive,
             "sigma_th^2 of Eq. 6"),
        Legacy(Real("thin_evidence_weight", &P::thin_evidence_weight, kDerived, ThinWeight,
                    "a thin cell seen less (full-kernel observations) is unknown; 0: off"),
               "0.5"),
        Legacy(Real("thin_ground_weight", &P::thin_ground_weight, kDerived, ThinWeight,
                    "a cell blocked by the variance alone, its evidence leaning traversable, "
                    "seen less (full-kernel observations) is unknown; 100: always"),
               "100"),
        Real("min_range", &P::min_range, kStats, FiniteNonNegative,
             "drop closer points (the robot's own body), metres"),
        Real("max_range", &P::max_range, kStats, MaxRange, "drop farther points, metres"),
        Real("max_height_above_sensor", &P::max_height_above_sensor, kStats, NotNaN,
             "drop points higher above the sensor (overhangs), metres"),
        Enum<&P::observation, ObservationName, ParseObservation>(
            "observation", kStats, "max | mean of a scan's points in a cell, its training value"),
        Integer("tile_size", &P::tile_size, kStats, TileSize, "cells per tile edge"),
        Enum<&P::method, MethodName, ParseMethod>(
            "method", kStats, "bgk+ | bgk-trav | baseline | one-step | bgk-obstacle | bgk-ll"),
    };
    std::vector<MapParamInfo> more = ChangingWorldEntries();
    t.insert(t.end(), more.begin(), more.end());
    return t;
  }();
  return table;
}

std::vector<MapParamInfo> ChangingWorldEntries() {
  return {
      // Dynamics (docs/semantics.md); stores and archives from before them were built "off".
      Legacy(Enum<&P::dynamics, DynamicsName, ParseDynamics>(
                 "dynamics", kStats, "on | off: follow a changing world, or accumulate (paper)"),
             "off"),
      Legacy(Real("max_confidence_scans", &P::max_confidence_scans, kStats, ConfidenceScans,
                  "confidence cap: statistics saturate at this many full-kernel observations"),
             "20"),
      Legacy(Real("clear_margin", &P::clear_margin, kStats, Positive,
                  "a ray this far below a cell's elevation, or a return this far above, "
                  "contradicts it, metres"),
             "0.2"),
      Legacy(Real("clear_decay", &P::clear_decay, kStats, UnitInterval,
                  "fraction of a contradicted cell's statistics kept"),
             "0.05"),
      Legacy(Real("clear_ray_length", &P::clear_ray_length, kStats, RayLength,
                  "free-space rays are walked over this many metres before their return"),
             "2"),
      // The robot's footprint; maps from before it were built without (0).
      Legacy(Real("sensor_height", &P::sensor_height, kStats, SensorHeight,
                  "sensor above the ground under the robot, metres; > 0: the footprint is "
                  "traversable-ground evidence (dynamics on), 0: off"),
             "0"),
      Legacy(Real("footprint_weight", &P::footprint_weight, kStats, FootprintWeight,
                  "weight of the footprint evidence per scan, in observations at a cell"),
             "0.1"),
      Legacy(Real("footprint_length", &P::footprint_length, kStats, FootprintEdge,
                  "the vehicle's length, metres; > 0 with the width: the footprint is its box"),
             "0"),
      Legacy(Real("footprint_width", &P::footprint_width, kStats, FootprintEdge,
                  "the vehicle's width, metres; 0: the footprint is the disk of robot_radius"),
             "0"),
      Legacy(Real("footprint_sensor_x", &P::footprint_sensor_x, kStats, FootprintOffset,
                  "the sensor's position ahead of the footprint box's centre, metres"),
             "0"),
      Legacy(Real("footprint_sensor_y", &P::footprint_sensor_y, kStats, FootprintOffset,
                  "the sensor's position left of the footprint box's centre, metres"),
             "0"),
      // The self-filter; maps from before it dropped no return for it (0).
      Legacy(Real("self_filter_below", &P::self_filter_below, kStats, SelfFilterBelow,
                  "> 0: returns inside the footprint box (grown by self_filter_margin) higher "
                  "than this many metres under the sensor are the robot's body, dropped; 0: off"),
             "0"),
      Legacy(Real("self_filter_margin", &P::self_filter_margin, kStats, SelfFilterMargin,
                  "metres the self-filter box reaches beyond the footprint box on each side"),
             "0"),
      // Forgetting; maps from before it were built without (0).
      Legacy(Real("half_life_s", &P::half_life_s, kStats, FiniteNonNegative,
                  "seconds of map time (scan stamps) in which a statistic's weight halves "
                  "(dynamics on); 0: no forgetting"),
             "0"),
      // Transient objects; maps from before them kept no ground aside (0).
      Legacy(Real("transient_confirm_s", &P::transient_confirm_s, kStats, TransientConfirm,
                  "seconds something that appeared on traversable ground must still be seen "
                  "after it appeared to stay when it is no longer seen (stamped scans, "
                  "dynamics on); 0: off, everything seen stays"),
             "0"),
      Legacy(Real("transient_expire_s", &P::transient_expire_s, kStats, TransientExpire,
                  "seconds an unconfirmed appearance may go unseen before the ground it "
                  "covered comes back"),
             "1"),
  };
}

}  // namespace

bool MapParamInfo::Equal(const MapParams& a, const MapParams& b) const {
  switch (kind) {
    case MapParamKind::kDouble:
      return a.*real == b.*real;
    case MapParamKind::kInt:
      return a.*integer == b.*integer;
    case MapParamKind::kDouble3:
      return a.*triple == b.*triple;
    case MapParamKind::kEnum:
      return enum_name(a) == enum_name(b);
  }
  return false;
}

std::span<const MapParamInfo> MapParamTable() { return Table(); }

const MapParamInfo* FindMapParam(std::string_view key) {
  for (const MapParamInfo& info : Table()) {
    if (info.key == key) return &info;
  }
  return nullptr;
}

const std::vector<std::string_view>& MapParamKeys() {
  static const std::vector<std::string_view> keys = [] {
    std::vector<std::string_view> k;
    for (const MapParamInfo& info : Table()) k.push_back(info.key);
    return k;
  }();
  return keys;
}

Status MapParams::Validate() const {
  for (const MapParamInfo& info : Table()) {
    if (info.check == nullptr) continue;
    double value = 0;
    if (info.kind == MapParamKind::kDouble) value = this->*info.real;
    if (info.kind == MapParamKind::kInt) value = this->*info.integer;
    if (Status s = info.check(info.key, value, *this); !s.ok()) return s;
  }
  return Status::Ok();
}

bool MapParams::StatisticsCompatibleWith(const MapParams& o, std::string* why) const {
  for (const MapParamInfo& info : Table()) {
    if (!info.shapes_statistics || info.Equal(*this, o)) continue;
    if (why == nullptr) return false;
    const auto differ = [&](std::string_view key, const std::string& a, const std::string& b) {
      *why = std::string(key) + " differs (" + a + " vs " + b + ")";
    };
    switch (info.kind) {
      case MapParamKind::kDouble:
        differ(info.key, Num(this->*info.real), Num(o.*info.real));
        break;
      case MapParamKind::kInt:
        differ(info.key, Num(this->*info.integer), Num(o.*info.integer));
        break;
      case MapParamKind::kDouble3:
        for (size_t i = 0; i < 3; ++i) {
          if ((this->*info.triple)[i] == (o.*info.triple)[i]) continue;
          differ(std::string(info.key) + "[" + std::to_string(i) + "]",
                 Num((this->*info.triple)[i]), Num((o.*info.triple)[i]));
          break;
        }
        break;
      case MapParamKind::kEnum:
        differ(info.key, std::string(info.enum_name(*this)), std::string(info.enum_name(o)));
        break;
    }
    return false;
  }
  return true;
}

}  // namespace bgkmap
