// Scans to clear and to show a changed object, bgkmap against OctoMap on the same scans (issue:
// dynamics). A simulated VLP-16 1.5 m above flat ground watches the place of a 2 x 2 x 1 m box
// 4-6 m ahead: the box is seen N times and removed, or the ground is seen N times and the box
// placed. Reported per scan after the change:
//   bgkmap: the cells a scan sees there ("its place") that are ground (|z| <= 0.05 m, traversable)
//           after removal, or non-traversable after placement; and the known cells still raised;
//   OctoMap: insertPointCloud (resolution 0.1 m, default sensor model and clamping), the occupied
//           voxels left above 0.2 m inside the box after removal, or the box's seen cells with an
//           occupied voxel above 0.5 m after placement.
// Also the time of one update. Run: build/bench/changing_world [history=1000]
#include <octomap/OcTree.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/sim/beam_model.h"
#include "bgkmap/sim/box_world.h"
#include "bgkmap/sim/ray_caster.h"

namespace bgkmap {
namespace {

using Clock = std::chrono::steady_clock;
const sim::Box kBox{4.0, -1.0, 6.0, 1.0, 1.0};

Pose SensorPose() {
  Pose p;
  p.translation = {0.0, 0.0, 1.5};
  return p;
}

struct Scene {
  std::vector<Point3f> bare, boxed;
  std::vector<CellIndex> seen_bare, seen_box;  // cells of the box's place each scan observes
};

std::vector<CellIndex> Seen(const std::vector<Point3f>& scan, bool on_box) {
  const MapParams p;
  std::vector<CellIndex> out;
  const Result<PreparedScan> prepared = PrepareScan(p, scan, SensorPose());
  for (const ObservedCell& oc : prepared->cells) {
    const double x = (oc.cell.x + 0.5) * p.resolution, y = (oc.cell.y + 0.5) * p.resolution;
    if (kBox.Contains(x, y) && (!on_box || oc.y > 0.5)) out.push_back(oc.cell);
  }
  return out;
}

struct BgkmapRun {
  std::unique_ptr<TerrainMap> map;
  double ms = 0;
  int updates = 0;
  explicit BgkmapRun(Dynamics d) {
    MapParams p;
    p.dynamics = d;
    map = std::move(TerrainMap::Create(p)).value();
  }
  void Insert(const std::vector<Point3f>& scan) {
    const auto t0 = Clock::now();
    (void)map->IntegrateScan(scan, SensorPose());
    ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ++updates;
  }
  // Fraction of `cells` that are ground (want_ground) or non-traversable.
  double Fraction(const std::vector<CellIndex>& cells, bool want_ground) const {
    int hits = 0;
    for (const CellIndex& c : cells) {
      const CellEstimate e = map->Estimate(c);
      hits += want_ground ? (e.state == CellState::kTraversable && std::abs(e.elevation) <= 0.05f)
                          : e.state == CellState::kNonTraversable;
    }
    return cells.empty() ? 0 : static_cast<double>(hits) / static_cast<double>(cells.size());
  }
};

struct OctomapRun {
  octomap::OcTree tree{0.1};
  double ms = 0;
  int updates = 0;
  void Insert(const std::vector<Point3f>& scan) {
    octomap::Pointcloud cloud;
    const Pose pose = SensorPose();
    for (const Point3f& q : scan) {
      const Eigen::Vector3d m = pose.rotation * Eigen::Vector3d(q.x, q.y, q.z) + pose.translation;
      cloud.push_back(static_cast<float>(m.x()), static_cast<float>(m.y()),
                      static_cast<float>(m.z()));
    }
    const octomap::point3d origin(0.0f, 0.0f, 1.5f);
    const auto t0 = Clock::now();
    tree.insertPointCloud(cloud, origin, 100.0);
    ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ++updates;
  }
  // Occupied voxels above `z` in the column of a cell.
  bool OccupiedAbove(const CellIndex& c, double z) const {
    for (double h = z + 0.05; h < 1.5; h += 0.1) {
      const octomap::OcTreeNode* n = tree.search((c.x + 0.5) * 0.1, (c.y + 0.5) * 0.1, h);
      if (n != nullptr && tree.isNodeOccupied(n)) return true;
    }
    return false;
  }
  double Fraction(const std::vector<CellIndex>& cells, bool want_clear) const {
    int hits = 0;
    for (const CellIndex& c : cells) {
      hits += want_clear ? !OccupiedAbove(c, 0.2) : OccupiedAbove(c, 0.5);
    }
    return cells.empty() ? 0 : static_cast<double>(hits) / static_cast<double>(cells.size());
  }
};

// The box's footprint cells that any run saw while it stood (for "cleared everywhere").
std::vector<CellIndex> FootprintCells() {
  std::vector<CellIndex> out;
  for (int y = -10; y < 10; ++y) {
    for (int x = 40; x < 60; ++x) out.push_back({x, y});
  }
  return out;
}

int Main(int history) {
  Scene s;
  s.bare = sim::SimulateScan(sim::BoxWorld{}, sim::Vlp16(), SensorPose());
  s.boxed = sim::SimulateScan(sim::BoxWorld({kBox}), sim::Vlp16(), SensorPose());
  s.seen_bare = Seen(s.bare, false);
  s.seen_box = Seen(s.boxed, true);
  std::printf(
      "VLP-16 1.5 m up, 2x2x1 m box 4-6 m ahead; history %d scans; %zu cells of its place "
      "seen without it, %zu seen on it\n",
      history, s.seen_bare.size(), s.seen_box.size());

  for (const bool removal : {true, false}) {
    std::printf("\n%s after %d scans %s:\n", removal ? "box removed" : "box placed", history,
                removal ? "of it" : "of bare ground");
    std::printf("scan | bgkmap on | bgkmap off (paper) | octomap\n");
    BgkmapRun on(Dynamics::kOn), off(Dynamics::kOff);
    OctomapRun octo;
    const std::vector<Point3f>& first = removal ? s.boxed : s.bare;
    const std::vector<Point3f>& then = removal ? s.bare : s.boxed;
    for (int i = 0; i < history; ++i) {
      on.Insert(first);
      off.Insert(first);
      octo.Insert(first);
    }
    const std::vector<CellIndex>& cells = removal ? s.seen_bare : s.seen_box;
    for (int k = 1; k <= 10; ++k) {
      on.Insert(then);
      off.Insert(then);
      octo.Insert(then);
      std::printf("%4d | %8.0f %% | %8.0f %% | %6.0f %%\n", k, 100 * on.Fraction(cells, removal),
                  100 * off.Fraction(cells, removal), 100 * octo.Fraction(cells, removal));
    }
    std::printf("mean update: bgkmap on %.2f ms, off %.2f ms, octomap %.1f ms\n",
                on.ms / on.updates, off.ms / off.updates, octo.ms / octo.updates);
    if (removal) {
      int raised = 0;
      for (const CellIndex& c : FootprintCells()) {
        const CellEstimate e = on.map->Estimate(c);
        raised += e.state != CellState::kUnknown && std::abs(e.elevation) > 0.05f;
      }
      std::printf("bgkmap on: known footprint cells still raised after 10 scans: %d\n", raised);
    }
  }
  return 0;
}

}  // namespace
}  // namespace bgkmap

int main(int argc, char** argv) { return bgkmap::Main(argc > 1 ? std::atoi(argv[1]) : 1000); }
