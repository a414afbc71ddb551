#include "bgkmap/eval/drive_score.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <set>

#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/terrain_features.h"

namespace bgkmap::eval {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kTolerance = 1e-9;  // metres: a cell centre on the footprint's edge is inside

double Heading(const Pose& pose) { return std::atan2(pose.rotation(1, 0), pose.rotation(0, 0)); }

// b - a wrapped to (-pi, pi]: the shorter turn.
double Turn(double a, double b) {
  double d = std::remainder(b - a, 2.0 * std::numbers::pi);
  return d;
}

struct Placement {
  double x, y, z, yaw;
  int scan;  // the scan whose footprint this placement belongs to
};

// The footprint placed every at most half a cell along the path, both ends included.
std::vector<Placement> Sweep(std::span<const Pose> poses, double step) {
  std::vector<Placement> out;
  for (size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Vector3d& a = poses[k].translation;
    const double yaw_a = Heading(poses[k]);
    const int scan = static_cast<int>(k);
    if (k + 1 == poses.size()) {
      out.push_back({a.x(), a.y(), a.z(), yaw_a, scan});
      break;
    }
    const Eigen::Vector3d& b = poses[k + 1].translation;
    const double turn = Turn(yaw_a, Heading(poses[k + 1]));
    const double dist = std::hypot(b.x() - a.x(), b.y() - a.y());
    const int n = std::max(1, static_cast<int>(std::ceil(dist / step)));
    for (int i = 0; i < n; ++i) {  // the segment's end is the next segment's start
      const double t = static_cast<double>(i) / n;
      const Eigen::Vector3d p = a + t * (b - a);
      out.push_back({p.x(), p.y(), p.z(), yaw_a + t * turn, i == 0 ? scan : scan + 1});
    }
  }
  return out;
}

// A bgk-ll cell's own observations' mean, else its elevation: what v is computed from.
double FeatureHeight(const MapParams& p, const Tile& tile, int i) {
  const double w = tile.w()[i];
  if (!(w > 0.0)) return kNaN;
  if (tile.has_plane()) {
    const double own_w = tile.plane(Tile::kOwnW)[i];
    return own_w > 0.0 ? tile.plane(Tile::kOwnS)[i] / own_w : kNaN;
  }
  return (p.lambda * p.prior_mean + tile.s()[i]) / (p.lambda + w);
}

double Percentile(std::vector<double>& v, double q) {
  if (v.empty()) return kNaN;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

Footprint Footprint::Disc(double radius) {
  Footprint f;
  f.shape = Shape::kDisc;
  f.radius = radius;
  return f;
}

Footprint Footprint::Box(double length, double width, double sensor_x, double sensor_y) {
  Footprint f;
  f.shape = Shape::kBox;
  f.length = length;
  f.width = width;
  f.sensor_x = sensor_x;
  f.sensor_y = sensor_y;
  return f;
}

bool Footprint::Contains(double dx, double dy) const {
  if (shape == Shape::kDisc) return std::hypot(dx, dy) <= radius + kTolerance;
  return std::abs(dx + sensor_x) <= 0.5 * length + kTolerance &&
         std::abs(dy + sensor_y) <= 0.5 * width + kTolerance;
}

double Footprint::Reach() const {
  if (shape == Shape::kDisc) return radius;
  return std::hypot(0.5 * length + std::abs(sensor_x), 0.5 * width + std::abs(sensor_y));
}

std::string Footprint::Describe() const {
  char buf[128];
  if (shape == Shape::kDisc) {
    std::snprintf(buf, sizeof buf, "disc r=%g m", radius);
  } else {
    std::snprintf(buf, sizeof buf, "box %g x %g m, sensor at (%g, %g) m from its centre", length,
                  width, sensor_x, sensor_y);
  }
  return buf;
}

std::vector<DrivenCell> DrivenCells(const GridGeometry& geometry, std::span<const Pose> poses,
                                    const Footprint& footprint, double sensor_height) {
  const double res = geometry.resolution();
  // Per cell, the squared distance to the nearest placement covering it, its ground height and
  // the first scan that covers it.
  struct Seen {
    double d2, ground;
    int first_scan;
  };
  std::map<CellIndex, Seen> cells;
  const double reach = footprint.Reach();
  for (const Placement& p : Sweep(poses, 0.5 * res)) {
    const double c = std::cos(p.yaw), s = std::sin(p.yaw);
    const CellBox box = geometry.BoxCovering(p.x - reach, p.y - reach, p.x + reach, p.y + reach);
    for (int iy = box.min.y; iy <= box.max.y; ++iy) {
      for (int ix = box.min.x; ix <= box.max.x; ++ix) {
        const double dx = geometry.CellCenterX(ix) - p.x, dy = geometry.CellCenterY(iy) - p.y;
        // The offset in the vehicle frame (x forward along the heading, y left).
        if (!footprint.Contains(c * dx + s * dy, -s * dx + c * dy)) continue;
        const double d2 = dx * dx + dy * dy;
        const double ground = sensor_height > 0 ? p.z - sensor_height : kNaN;
        auto [it, inserted] = cells.try_emplace({ix, iy}, Seen{d2, ground, p.scan});
        if (inserted) continue;
        Seen& seen = it->second;
        if (d2 < seen.d2) seen.d2 = d2, seen.ground = ground;
        seen.first_scan = std::min(seen.first_scan, p.scan);
      }
    }
  }
  std::vector<DrivenCell> out;
  out.reserve(cells.size());
  for (const auto& [cell, v] : cells) out.push_back({cell, v.ground, v.first_scan});
  return out;
}

uint8_t BlockReasons(const MapParams& p, double w, double s, double q, float a, float b,
                     const double* plane) {
  return EstimateCell(p, w, s, q, a, b, plane).block_reasons;
}

uint8_t BlockReasonsAt(const TerrainMap& map, CellIndex cell) {
  const Tile* tile = map.FindTile(map.geometry().TileOf(cell));
  if (tile == nullptr) return 0;
  const int i = map.geometry().LocalIndex(cell);
  double plane[Tile::kPlaneMoments];
  if (tile->has_plane()) tile->PlaneOf(i, plane);
  return BlockReasons(map.params(), tile->w()[i], tile->s()[i], tile->q()[i], tile->a()[i],
                      tile->b()[i], tile->has_plane() ? plane : nullptr);
}

bool SurfaceFeatures(const TerrainMap& map, CellIndex cell, TerrainFeatures* out) {
  const MapParams& p = map.params();
  const GridGeometry& g = map.geometry();
  std::vector<PatchPoint> patch;
  for (const CellIndex& o : DiskOffsets(p.robot_radius, p.resolution)) {
    const CellIndex c{cell.x + o.x, cell.y + o.y};
    const Tile* tile = map.FindTile(g.TileOf(c));
    if (tile == nullptr) continue;
    const double z = FeatureHeight(p, *tile, g.LocalIndex(c));
    if (!std::isnan(z)) patch.push_back({o.x * p.resolution, o.y * p.resolution, z});
  }
  if (patch.size() < 3) return false;
  *out = ComputeFeatures(patch);
  return true;
}

bool CheckSurface(const TerrainMap& map, CellIndex cell, SurfaceCheck* out) {
  const MapParams& p = map.params();
  TerrainFeatures f;
  if (!SurfaceFeatures(map, cell, &f)) return false;
  out->step = f.step > p.step_crit;
  out->slope = f.slope_deg > p.slope_crit_deg;
  out->roughness = f.roughness > p.roughness_crit;
  return true;
}

double DriveScore::known_share() const {
  return driven ? static_cast<double>(known) / static_cast<double>(driven) : kNaN;
}
double DriveScore::traversable_share() const {
  return known ? static_cast<double>(traversable) / static_cast<double>(known) : kNaN;
}

DriveScore& DriveScore::operator+=(const DriveScore& o) {
  const double n = static_cast<double>(ground_cells), m = static_cast<double>(o.ground_cells);
  if (o.ground_cells > 0) {
    const double sum = (n > 0 ? ground_bias * n : 0.0) + o.ground_bias * m;
    const double sum2 =
        (n > 0 ? ground_rms * ground_rms * n : 0.0) + o.ground_rms * o.ground_rms * m;
    ground_bias = sum / (n + m);
    ground_rms = std::sqrt(sum2 / (n + m));
  }
  driven += o.driven;
  known += o.known;
  traversable += o.traversable;
  blocked += o.blocked;
  no_value += o.no_value;
  high_mean += o.high_mean;
  high_variance += o.high_variance;
  disagreement += o.disagreement;
  only_mean += o.only_mean;
  only_variance += o.only_variance;
  only_disagreement += o.only_disagreement;
  mean_step += o.mean_step;
  mean_slope += o.mean_slope;
  mean_roughness += o.mean_roughness;
  mean_flat_now += o.mean_flat_now;
  ground_cells += o.ground_cells;
  return *this;
}

DriveScore ScoreDrive(const TerrainMap& map, std::span<const DrivenCell> driven) {
  DriveScore s;
  double sum = 0, sum2 = 0;
  for (const DrivenCell& d : driven) {
    ++s.driven;
    const CellEstimate e = map.Estimate(d.cell);
    if (e.state == CellState::kUnknown) continue;
    ++s.known;
    if (std::isfinite(e.elevation) && std::isfinite(d.ground_z)) {
      const double dz = static_cast<double>(e.elevation) - d.ground_z;
      sum += dz;
      sum2 += dz * dz;
      ++s.ground_cells;
    }
    if (e.state == CellState::kTraversable) {
      ++s.traversable;
      continue;
    }
    ++s.blocked;
    const uint8_t r = BlockReasonsAt(map, d.cell);
    s.no_value += (r & kNoValue) != 0;
    s.high_mean += (r & kHighMean) != 0;
    s.high_variance += (r & kHighVariance) != 0;
    s.disagreement += (r & kDisagreement) != 0;
    s.only_mean += r == kHighMean;
    s.only_variance += r == kHighVariance;
    s.only_disagreement += r == kDisagreement;
    if ((r & kHighMean) == 0) continue;
    SurfaceCheck check;
    const bool judged = CheckSurface(map, d.cell, &check);
    s.mean_step += judged && check.step;
    s.mean_slope += judged && check.slope;
    s.mean_roughness += judged && check.roughness;
    s.mean_flat_now += !judged || !(check.step || check.slope || check.roughness);
  }
  if (s.ground_cells > 0) {
    const double n = static_cast<double>(s.ground_cells);
    s.ground_bias = sum / n;
    s.ground_rms = std::sqrt(sum2 / n);
  } else {
    s.ground_bias = s.ground_rms = kNaN;
  }
  return s;
}

double MapAgreement::agreement() const {
  return common ? static_cast<double>(state_agree) / static_cast<double>(common) : kNaN;
}

MapAgreement CompareMaps(const TerrainMap& a, const TerrainMap& b,
                         std::span<const CellIndex> cells) {
  MapAgreement m;
  std::vector<double> abs_dz;
  double sum = 0, sum2 = 0;
  auto visit = [&](CellIndex c) {
    const CellEstimate ea = a.Estimate(c), eb = b.Estimate(c);
    const bool ka = ea.state != CellState::kUnknown, kb = eb.state != CellState::kUnknown;
    m.only_a += ka && !kb;
    m.only_b += kb && !ka;
    if (!ka || !kb) return;
    ++m.common;
    m.state_agree += ea.state == eb.state;
    const bool ta = ea.state == CellState::kTraversable, tb = eb.state == CellState::kTraversable;
    m.both_traversable += ta && tb;
    m.a_blocked_only += !ta && tb;
    m.b_blocked_only += ta && !tb;
    if (ta != tb) {
      const uint8_t r = BlockReasonsAt(ta ? b : a, c);
      m.split_no_value += (r & kNoValue) != 0;
      m.split_high_mean += (r & kHighMean) != 0;
      m.split_high_variance += (r & kHighVariance) != 0;
      m.split_disagreement += (r & kDisagreement) != 0;
    }
    if (std::isfinite(ea.elevation) && std::isfinite(eb.elevation)) {
      const double dz = static_cast<double>(eb.elevation) - ea.elevation;
      sum += dz;
      sum2 += dz * dz;
      abs_dz.push_back(std::abs(dz));
    }
  };
  if (!cells.empty()) {
    for (const CellIndex& c : cells) visit(c);
  } else {
    // Every cell of every tile either map holds, each tile once.
    std::set<TileKey> keys;
    a.ForEachTile([&](TileKey k, const Tile&) { keys.insert(k); });
    b.ForEachTile([&](TileKey k, const Tile&) { keys.insert(k); });
    for (const TileKey& k : keys) {
      const CellBox box = a.geometry().TileBox(k);
      for (int y = box.min.y; y <= box.max.y; ++y) {
        for (int x = box.min.x; x <= box.max.x; ++x) visit({x, y});
      }
    }
  }
  const double n = static_cast<double>(abs_dz.size());
  m.dz_mean = abs_dz.empty() ? kNaN : sum / n;
  m.dz_rms = abs_dz.empty() ? kNaN : std::sqrt(sum2 / n);
  m.dz_abs_max = abs_dz.empty() ? kNaN : *std::max_element(abs_dz.begin(), abs_dz.end());
  m.dz_abs_p95 = Percentile(abs_dz, 0.95);
  m.dz_abs_p50 = Percentile(abs_dz, 0.5);
  return m;
}

}  // namespace bgkmap::eval
