// Objects that appear or disappear at given scans of a simulated sequence (`bgkmap simulate
// --change`), or drive through it (traffic): boxes standing on any world. The lidar of scan k
// sees the world as it is at scan k; scan k is taken at k * kScanPeriodS seconds.
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/sim/box_world.h"
#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

// Simulated sequences are 10 Hz (bgkmap simulate writes times.txt so).
inline constexpr double kScanPeriodS = 0.1;

struct ScriptedObject {
  static constexpr int kNever = std::numeric_limits<int>::max();
  std::string name;
  double center_x = 0, center_y = 0;  // world frame, metres, at its first scan (appear)
  double size_x = 0, size_y = 0;      // axis-aligned footprint, metres
  double height = 0;                  // flat top this far above the base world at the centre
  int appear = 0;                     // first scan that sees it (0: from the start)
  int disappear = kNever;             // first scan without it (kNever: stays)
  // Metres per second of map time: a moving object (a vehicle) is at its centre at `appear`
  // and moves on in a straight line, kScanPeriodS per scan. 0: it stands.
  double velocity_x = 0, velocity_y = 0;

  bool PresentAt(int scan) const { return scan >= appear && scan < disappear; }
  bool Moves() const { return velocity_x != 0 || velocity_y != 0; }
  // Its centre at scan `scan`.
  double CenterXAt(int scan) const {
    return center_x + velocity_x * kScanPeriodS * (scan - appear);
  }
  double CenterYAt(int scan) const {
    return center_y + velocity_y * kScanPeriodS * (scan - appear);
  }
  // The footprint at scan `scan` (a standing object: anywhere), with `Box::height` the absolute
  // height of the top over `base` at its centre then.
  Box Placed(const World& base, int scan = 0) const;
};

// `base` plus boxes (Box::height is the absolute height of each top): inside a footprint the
// surface is the higher of the base and the top. Overhangs are the base's.
class ObjectsWorld : public World {
 public:
  ObjectsWorld(std::shared_ptr<const World> base, std::vector<Box> boxes);
  double SurfaceHeight(double x, double y) const override;
  bool InOverhang(double x, double y, double z) const override {
    return base_->InOverhang(x, y, z);
  }
  double MaxHeight() const override { return max_height_; }
  double MaxHeightIn(double x0, double y0, double x1, double y1) const override;

 private:
  std::shared_ptr<const World> base_;
  std::vector<Box> boxes_;
  double max_height_;
};

// The world of scan `scan`: `base` with the objects present at that scan. `base` itself when the
// script is empty, so a sequence without a script is simulated exactly as before.
std::shared_ptr<const World> WorldAtScan(const std::shared_ptr<const World>& base,
                                         const std::vector<ScriptedObject>& objects, int scan);

}  // namespace bgkmap::sim
