// Objects that appear or disappear at given scans of a simulated sequence (`bgkmap simulate
// --change`): boxes standing on any world. The lidar of scan k sees the world as it is at scan k.
#pragma once

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/sim/box_world.h"
#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

struct ScriptedObject {
  static constexpr int kNever = std::numeric_limits<int>::max();
  std::string name;
  double center_x = 0, center_y = 0;  // world frame, metres
  double size_x = 0, size_y = 0;      // axis-aligned footprint, metres
  double height = 0;                  // flat top this far above the base world at the centre
  int appear = 0;                     // first scan that sees it (0: from the start)
  int disappear = kNever;             // first scan without it (kNever: stays)

  bool PresentAt(int scan) const { return scan >= appear && scan < disappear; }
  // The footprint with `Box::height` the absolute height of the top over `base`.
  Box Placed(const World& base) const;
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
