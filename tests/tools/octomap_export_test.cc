#include "bgkmap/io/octomap_export.h"

#include <gtest/gtest.h>
#include <octomap/ColorOcTree.h>

#include <cmath>
#include <filesystem>
#include <memory>

namespace bgkmap::io {
namespace {

Raster TwoByTwo() {
  Raster r;
  r.cols = 2;
  r.rows = 2;
  r.resolution = 0.1;
  r.x0 = 500000.0;  // UTM-sized: the export must re-centre
  r.y1 = 4000000.2;
  r.box = {{5000000, 39999999}, {5000001, 40000000}};
  r.layers = {Layer::kElevation, Layer::kTraversability};
  const float nan = std::nanf("");
  r.data = {{1.0f, 1.5f, nan, 2.0f}, {0.0f, 1.0f, nan, nan}};
  return r;
}

TEST(OctomapExportTest, WritesColouredColumnsThatOctomapReadsBack) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("bgkmap_export_" + std::to_string(::getpid()) + ".ot"))
                               .string();
  Result<OctreeExportResult> r = WriteColorOcTree(TwoByTwo(), path, {0.3});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->columns, 3u);
  EXPECT_EQ(r->voxels, 9u);
  EXPECT_DOUBLE_EQ(r->origin.x(), 500000.0);
  EXPECT_DOUBLE_EQ(r->origin.y(), 4000000.0);

  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read(path));
  ASSERT_NE(read, nullptr);
  ASSERT_EQ(read->getTreeType(), "ColorOcTree");
  auto* tree = dynamic_cast<octomap::ColorOcTree*>(read.get());
  EXPECT_EQ(tree->getResolution(), 0.1);
  // North-west pixel (col 0, row 0): centre (0.05, 0.15) local, top voxel just under z = 1.
  octomap::ColorOcTreeNode* top = tree->search(0.05, 0.15, 0.95);
  ASSERT_NE(top, nullptr);
  EXPECT_TRUE(tree->isNodeOccupied(top));
  EXPECT_EQ(top->getColor(), octomap::ColorOcTreeNode::Color(0, 255, 0));  // traversability 0
  EXPECT_EQ(tree->search(0.05, 0.15, 1.05), nullptr);                      // nothing above
  // North-east pixel: traversability 1 -> red.
  EXPECT_EQ(tree->search(0.15, 0.15, 1.45)->getColor(), octomap::ColorOcTreeNode::Color(255, 0, 0));
  // South-east pixel: elevation without traversability -> grey.
  EXPECT_EQ(tree->search(0.15, 0.05, 1.95)->getColor(),
            octomap::ColorOcTreeNode::Color(128, 128, 128));
  std::filesystem::remove(path);
}

TEST(OctomapExportTest, RefusesRastersWithoutElevationOrBeyondTheKeyRange) {
  Raster r = TwoByTwo();
  r.layers = {Layer::kState, Layer::kTraversability};
  EXPECT_FALSE(WriteColorOcTree(r, "/tmp/x.ot").ok());
  r = TwoByTwo();
  r.data[0][0] = 1e6f;
  Result<OctreeExportResult> far = WriteColorOcTree(r, "/tmp/x.ot");
  ASSERT_FALSE(far.ok());
  EXPECT_NE(far.status().message().find("key range"), std::string::npos);
  EXPECT_FALSE(WriteColorOcTree(TwoByTwo(), "/nonexistent/dir/x.ot").ok());
}

}  // namespace
}  // namespace bgkmap::io
