#include "bgkmap/sim/scripted_objects.h"

#include <algorithm>
#include <cmath>

namespace bgkmap::sim {

Box ScriptedObject::Placed(const World& base, int scan) const {
  const double cx = CenterXAt(scan), cy = CenterYAt(scan);
  double ground = base.SurfaceHeight(cx, cy);
  if (std::isnan(ground)) ground = 0.0;
  return {cx - 0.5 * size_x, cy - 0.5 * size_y, cx + 0.5 * size_x, cy + 0.5 * size_y,
          ground + height};
}

ObjectsWorld::ObjectsWorld(std::shared_ptr<const World> base, std::vector<Box> boxes)
    : base_(std::move(base)), boxes_(std::move(boxes)), max_height_(base_->MaxHeight()) {
  for (const Box& b : boxes_) max_height_ = std::max(max_height_, b.height);
}

double ObjectsWorld::SurfaceHeight(double x, double y) const {
  double z = base_->SurfaceHeight(x, y);
  for (const Box& b : boxes_) {
    if (b.Contains(x, y)) z = std::isnan(z) ? b.height : std::max(z, b.height);
  }
  return z;
}

double ObjectsWorld::MaxHeightIn(double x0, double y0, double x1, double y1) const {
  double z = base_->MaxHeightIn(x0, y0, x1, y1);
  for (const Box& b : boxes_) {
    if (b.xmin <= x1 && b.xmax >= x0 && b.ymin <= y1 && b.ymax >= y0) z = std::max(z, b.height);
  }
  return z;
}

std::shared_ptr<const World> WorldAtScan(const std::shared_ptr<const World>& base,
                                         const std::vector<ScriptedObject>& objects, int scan) {
  if (objects.empty()) return base;
  std::vector<Box> boxes;
  for (const ScriptedObject& o : objects) {
    if (o.PresentAt(scan)) boxes.push_back(o.Placed(*base, scan));
  }
  return std::make_shared<ObjectsWorld>(base, std::move(boxes));
}

}  // namespace bgkmap::sim
