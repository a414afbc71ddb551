#include "drive_figure.h"

#include <algorithm>

#include "bgkmap/io/category_png.h"

namespace bgkmap::cli {
namespace {

enum Class : uint8_t {
  kUnknown,
  kTraversable,
  kObstacle,   // blocked by the mean or the disagreement
  kUncertain,  // blocked by the variance alone
  kNoValue,
  kDrivenTraversable,
  kDrivenMean,
  kDrivenDisagreement,
  kDrivenVariance,
  kDrivenNoValue,
  kDrivenUnknown,
};

const std::vector<io::CategoryClass>& Legend() {
  static const std::vector<io::CategoryClass> legend = {
      {"UNKNOWN", {0, 0, 0}},
      {"TRAVERSABLE", {150, 150, 150}},
      {"BLOCKED: MEAN OR DISAGREEMENT", {120, 35, 35}},
      {"BLOCKED: VARIANCE ONLY", {40, 60, 140}},
      {"BLOCKED: NO VALUE", {100, 45, 100}},
      {"DRIVEN: TRAVERSABLE", {60, 200, 80}},
      {"DRIVEN: MEAN", {255, 40, 40}},
      {"DRIVEN: DISAGREEMENT", {255, 160, 0}},
      {"DRIVEN: VARIANCE", {70, 150, 255}},
      {"DRIVEN: NO VALUE", {240, 60, 240}},
      {"DRIVEN: UNKNOWN", {255, 255, 255}},
  };
  return legend;
}

uint8_t ClassOf(const TerrainMap& map, CellIndex c, bool driven) {
  const CellState s = map.Estimate(c).state;
  if (s == CellState::kUnknown) return driven ? kDrivenUnknown : kUnknown;
  if (s == CellState::kTraversable) return driven ? kDrivenTraversable : kTraversable;
  const uint8_t r = eval::BlockReasonsAt(map, c);
  if (r & eval::kNoValue) return driven ? kDrivenNoValue : kNoValue;
  if (r & eval::kHighMean) return driven ? kDrivenMean : kObstacle;
  if (r & eval::kDisagreement) return driven ? kDrivenDisagreement : kObstacle;
  return driven ? kDrivenVariance : kUncertain;
}

}  // namespace

Status WriteDriveFigure(const TerrainMap& map, std::span<const eval::DrivenCell> driven,
                        const std::string& path, CellBox box) {
  if (driven.empty()) return Status::InvalidArgument(path + ": no driven cells to draw");
  if (box.empty()) {
    for (const eval::DrivenCell& d : driven) box.Extend(d.cell);
    const int pad = static_cast<int>(10.0 / map.params().resolution);
    box = {{box.min.x - pad, box.min.y - pad}, {box.max.x + pad, box.max.y + pad}};
  }
  const int cols = static_cast<int>(box.width()), rows = static_cast<int>(box.height());
  std::vector<uint8_t> classes(static_cast<size_t>(cols) * rows);
  std::vector<uint8_t> is_driven(classes.size(), 0);
  auto index = [&](CellIndex c) {
    return static_cast<size_t>(box.max.y - c.y) * cols + (c.x - box.min.x);
  };
  for (const eval::DrivenCell& d : driven) {
    if (box.Contains(d.cell)) is_driven[index(d.cell)] = 1;
  }
  for (int y = box.min.y; y <= box.max.y; ++y) {
    for (int x = box.min.x; x <= box.max.x; ++x) {
      const size_t i = index({x, y});
      classes[i] = ClassOf(map, {x, y}, is_driven[i] != 0);
    }
  }
  const int scale = std::max(1, 900 / std::max(cols, 1));
  return io::WriteCategoryPng(path, cols, rows, classes, Legend(), std::min(scale, 4));
}

}  // namespace bgkmap::cli
