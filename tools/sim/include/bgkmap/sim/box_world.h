// Flat ground at z = 0 with axis-aligned boxes standing on it: the smallest world in which
// something appears or disappears (the changing-world tests; `bgkmap simulate flat` is this
// world without boxes, its objects come from a change script).
#pragma once

#include <algorithm>
#include <vector>

#include "bgkmap/sim/world.h"

namespace bgkmap::sim {

struct Box {
  double xmin, ymin, xmax, ymax, height;
  bool Contains(double x, double y) const {
    return x >= xmin && x <= xmax && y >= ymin && y <= ymax;
  }
};

class BoxWorld : public World {
 public:
  explicit BoxWorld(std::vector<Box> boxes = {}) : boxes_(std::move(boxes)) {
    for (const Box& b : boxes_) max_height_ = std::max(max_height_, b.height);
  }
  double SurfaceHeight(double x, double y) const override {
    double z = 0.0;
    for (const Box& b : boxes_) {
      if (b.Contains(x, y)) z = std::max(z, b.height);
    }
    return z;
  }
  double MaxHeight() const override { return max_height_; }

 private:
  std::vector<Box> boxes_;
  double max_height_ = 0.0;
};

}  // namespace bgkmap::sim
