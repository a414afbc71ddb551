#include "bgkmap/io/esri_ascii_grid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "bgkmap/sim/dem_world.h"

namespace bgkmap {
namespace {

std::string WriteFile(const std::string& name, const std::string& text) {
  const auto path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path.string();
}

TEST(EsriAsciiGridTest, ReadsHeaderNodataAndRowsNorthToSouth) {
  const std::string path = WriteFile("bgkmap_grid_ok.asc",
                                     "ncols 3\nnrows 2\nxllcorner 100\nyllcorner 200\n"
                                     "cellsize 2\nNODATA_value -9999\n1 2 3\n4 -9999 6\n");
  Result<io::EsriAsciiGrid> g = io::ReadEsriAsciiGrid(path);
  ASSERT_TRUE(g.ok()) << g.status().message();
  EXPECT_EQ(g->cols, 3);
  EXPECT_EQ(g->rows, 2);
  EXPECT_FLOAT_EQ(g->At(101, 203), 1.0f);  // north-west cell
  EXPECT_FLOAT_EQ(g->At(105, 201), 6.0f);  // south-east cell
  EXPECT_TRUE(std::isnan(g->At(103, 201)));
  EXPECT_TRUE(std::isnan(g->At(99, 201)));
}

TEST(EsriAsciiGridTest, ShortBodyIsOneClearError) {
  const std::string path = WriteFile(
      "bgkmap_grid_short.asc", "ncols 3\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n");
  Result<io::EsriAsciiGrid> g = io::ReadEsriAsciiGrid(path);
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.status().message().find("ends after 3 of 6"), std::string::npos)
      << g.status().message();
}

TEST(EsriAsciiGridTest, TheSharedDemBecomesAWorld) {
  Result<io::EsriAsciiGrid> g =
      io::ReadEsriAsciiGrid(std::string(BGKMAP_SHARED_DATA) + "/dem/topography_ground_1m.asc");
  ASSERT_TRUE(g.ok()) << g.status().message();
  EXPECT_EQ(g->cols, 286);
  sim::HeightGrid grid{g->cols, g->rows, 0.0, 0.0, g->cellsize, g->values};
  sim::ObstacleOptions none;
  none.rocks = 0;
  none.ditches = 0;
  none.xmax = none.ymax = 10;
  const sim::DemWorld world(grid, none);
  // Bilinear interpolation returns the grid value at a cell centre.
  const float centre = g->values[143 * 286 + 143];
  ASSERT_FALSE(std::isnan(centre));
  EXPECT_NEAR(world.SurfaceHeight(143.5, 286 - 143.5), centre, 1e-4);
  EXPECT_GT(world.MaxHeight(), centre);
}

}  // namespace
}  // namespace bgkmap
