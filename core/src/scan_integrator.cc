#include "bgkmap/core/scan_integrator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>

#include "bgkmap/core/cell_shapes.h"
#include "integration_kernels.h"
#include "scan_pass.h"
#include "scan_reach.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

}  // namespace

ScanIntegrator::ScanIntegrator(const MapParams& params)
    : params_(params),
      geometry_(params.resolution, params.tile_size),
      kernel_(params.resolution, params.kernel_length),
      neighbourhood_(DiskOffsets(params.robot_radius, params.resolution)),
      neighbourhood_radius_(static_cast<int>(std::ceil(params.robot_radius / params.resolution))) {
  if (params.dynamics == Dynamics::kOn) {
    for (const CellIndex& d : neighbourhood_) {
      if (!internal::InKernelSupport(d.x, d.y, params.resolution, params.kernel_length))
        beside_kernel_.push_back(d);
    }
    const double reach = params.robot_radius + params.kernel_length;
    evidence_reach_ = DiskOffsets(reach, params.resolution);
    evidence_reach_radius_ = static_cast<int>(std::ceil(reach / params.resolution));
    evidence_reach_half_.assign(2 * evidence_reach_radius_ + 1, -1);
    for (const CellIndex& d : evidence_reach_) {
      int& h = evidence_reach_half_[d.x + evidence_reach_radius_];
      h = std::max(h, std::abs(d.y));
    }
  }
  if (params.method == Method::kBgkObstacle) {
    for (int r = 0; r < kernel_.row_count(); ++r) {
      for (int j = 0; j <= 2 * kernel_.half_width(r); ++j)
        direct_weight_ += kernel_.row_weights(r)[j];
    }
  }
  if (params.dynamics == Dynamics::kOn) {
    // A "full-kernel observation" is every cell within l observed once.
    double full_w = 0.0;
    float full_ab = 0.0f;
    for (int r = 0; r < kernel_.row_count(); ++r) {
      for (int j = 0; j <= 2 * kernel_.half_width(r); ++j) {
        full_w += kernel_.row_weights_double(r)[j];
        full_ab += kernel_.row_weights(r)[j];
      }
    }
    if (!InfersElevation(params.method)) full_w = 1.0;  // raw elevation: one per observation
    caps_.w = params.max_confidence_scans * full_w;
    caps_.forget_below = 0.1 * full_w;
    // Direct methods keep the latest v (a + b = 1): nothing accumulates.
    if (InfersTraversability(params.method)) {
      caps_.ab = static_cast<float>(params.max_confidence_scans * full_ab);
    }
    half_life_ns_ = params.half_life_s * 1e9;
  }
}

double ScanIntegrator::DecayFactor(int64_t dt_ns) const {
  if (!(half_life_ns_ > 0) || dt_ns <= 0) return 1.0;
  return std::exp2(-static_cast<double>(dt_ns) / half_life_ns_);
}

void ScanIntegrator::Advance(Tile& tile, int64_t t) const {
  if (!(half_life_ns_ > 0) || t == 0 || t <= tile.stamp_ns()) return;
  if (tile.stamp_ns() != 0) tile.Scale(DecayFactor(t - tile.stamp_ns()));
  tile.set_stamp_ns(t);
}

double ScanIntegrator::Gain(const Tile& tile, int64_t t) const {
  if (t == 0 || tile.stamp_ns() <= t) return 1.0;
  return DecayFactor(tile.stamp_ns() - t);
}

double ScanIntegrator::ReadFactor(const Tile& tile, int64_t t) const {
  if (t == 0 || tile.stamp_ns() == 0 || tile.stamp_ns() >= t) return 1.0;
  return DecayFactor(t - tile.stamp_ns());
}

void ScanIntegrator::Saturate(Tile& tile) const {
  const int n = tile.cell_count();
  if (caps_.w > 0 && tile.has_plane()) {
    internal::CapElevationPlane(tile, 0, n, caps_.w);
  } else if (caps_.w > 0) {
    internal::CapElevation(tile.w().data(), tile.s().data(), tile.q().data(), n, caps_.w);
  }
  if (caps_.ab > 0) internal::CapBeta(tile.a().data(), tile.b().data(), n, caps_.ab);
}

ScanReport ScanIntegrator::Integrate(const PreparedScan& scan, const TileWindow& window,
                                     uint64_t version) const {
  ScanReport report;
  report.counts = scan.counts;
  report.observed_cells = scan.cells.size();
  const bool forget = forgetting() && scan.stamp_ns != 0;
  const Pass pass{*this, window, params_.tile_size, scan.stamp_ns, forget};

  const auto t0 = Clock::now();
  // Forgetting: the tiles the scan writes are brought to its time first; the others it may
  // change when it does (Advance is idempotent); the ones it only reads are read as of it.
  if (forget) {
    for (const TileKey& key : scan.write_tiles) Advance(*window.at(key), scan.stamp_ns);
  }
  pass.ResolveTransients(scan);
  const Pass::FreeSpace free_space = pass.ApplyFreeSpace(scan, report);
  const std::vector<TileKey>& cleared = free_space.cleared;
  pass.AddElevation(scan);
  const auto t1 = Clock::now();
  // The features' heights, read by the training values and by the ground re-learnt after them:
  // what follows AddElevation changes the counts, not the elevations.
  const auto fill = [&pass](TileKey key, double* z) { return pass.FillFeatureHeights(key, z); };
  internal::TileSlabs heights(scan, params_.tile_size, false, fill);
  const std::vector<std::pair<CellIndex, float>> values = pass.TrainingValues(scan, heights);
  report.feature_cells = values.size();
  const auto t2 = Clock::now();
  pass.AddTraversability(values);
  pass.RelearnGroundLeft(free_space.relearn, heights);
  pass.AddFootprint(scan);
  const auto t3 = Clock::now();

  for (const TileKey& key : scan.write_tiles) window.at(key)->set_version(version);
  for (const TileKey& key : cleared) window.at(key)->set_version(version);
  if (cleared.empty()) {
    report.changed_tiles = scan.write_tiles;
  } else {
    std::merge(scan.write_tiles.begin(), scan.write_tiles.end(), cleared.begin(), cleared.end(),
               std::back_inserter(report.changed_tiles));
  }
  report.changed_blocks.reserve(report.changed_tiles.size());
  for (const TileKey& key : report.changed_tiles) {
    report.changed_blocks.push_back(window.at(key)->TakeChangedBlocks());
  }
  report.times = {Seconds(t0, t1), Seconds(t1, t2), Seconds(t2, t3)};
  return report;
}

}  // namespace bgkmap
