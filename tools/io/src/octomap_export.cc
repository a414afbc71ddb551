#include "bgkmap/io/octomap_export.h"

#include <octomap/ColorOcTree.h>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace bgkmap::io {
namespace {

// Green (0) -> yellow (0.5) -> red (1), as in the PNG preview.
octomap::ColorOcTreeNode::Color TraversabilityColor(float v) {
  if (std::isnan(v)) return {128, 128, 128};
  const float t = std::clamp(v, 0.0f, 1.0f);
  const auto r = static_cast<uint8_t>(255.0f * std::min(1.0f, 2.0f * t));
  const auto g = static_cast<uint8_t>(255.0f * std::min(1.0f, 2.0f * (1.0f - t)));
  return {r, g, 0};
}

}  // namespace

Result<OctreeExportResult> WriteColorOcTree(const Raster& raster, const std::string& path,
                                            const OctreeExportOptions& options) {
  const std::vector<float>* elevation = raster.Find(Layer::kElevation);
  if (elevation == nullptr) {
    return Status::InvalidArgument(path + ": an octree export needs the elevation layer");
  }
  if (!(options.column_depth > 0) || !std::isfinite(options.column_depth)) {
    return Status::InvalidArgument("column_depth must be a finite number > 0");
  }
  const double res = raster.resolution;
  // 16-bit keys: 32768 voxels each way from the tree's centre.
  const double half_extent = 32000.0 * res;
  if (raster.cols * res > half_extent || raster.rows * res > half_extent) {
    return Status::OutOfRange(
        path + ": region of " + std::to_string(raster.cols) + " x " + std::to_string(raster.rows) +
        " pixels exceeds OctoMap's key range at " + std::to_string(res) + " m");
  }
  const std::vector<float>* trav = raster.Find(Layer::kTraversability);
  OctreeExportResult result;
  result.origin = {raster.x0, raster.y1 - static_cast<double>(raster.rows) * res, 0.0};

  octomap::ColorOcTree tree(res);
  const int depth_voxels = std::max(1, static_cast<int>(std::lround(options.column_depth / res)));
  for (int64_t row = 0; row < raster.rows; ++row) {
    for (int64_t col = 0; col < raster.cols; ++col) {
      const size_t i = static_cast<size_t>(row * raster.cols + col);
      const float z = (*elevation)[i];
      if (std::isnan(z)) continue;
      if (std::abs(z) > half_extent) {
        return Status::OutOfRange(path + ": elevation " + std::to_string(z) +
                                  " m is beyond OctoMap's key range");
      }
      const auto color = TraversabilityColor(trav ? (*trav)[i] : std::nanf(""));
      const double x = raster.x0 + (static_cast<double>(col) + 0.5) * res - result.origin.x();
      const double y = raster.y1 - (static_cast<double>(row) + 0.5) * res - result.origin.y();
      for (int k = 0; k < depth_voxels; ++k) {
        const octomap::point3d p(static_cast<float>(x), static_cast<float>(y),
                                 static_cast<float>(z - (k + 0.5) * res));
        tree.updateNode(p, true, /*lazy_eval=*/true);
        tree.setNodeColor(p.x(), p.y(), p.z(), color.r, color.g, color.b);
        ++result.voxels;
      }
      ++result.columns;
    }
  }
  tree.updateInnerOccupancy();
  // Our own stream: octomap's write(path) prints its own error to stderr on failure.
  std::ofstream out(path, std::ios::binary);
  if (!out || !tree.write(out) || !out.flush()) {
    return Status::IoError(path + ": cannot write the octree");
  }
  return result;
}

}  // namespace bgkmap::io
