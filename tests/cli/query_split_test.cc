// `bgkmap query` of a region over the server's per-query limit (issue 29): read in pieces and
// stitched into one GeoTIFF, equal bit for bit to the region read whole. Two real servers on the
// street scans: one whose server.max_region_cells is tiny, one with the default.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "bgkmap/io/geotiff.h"
#include "bgkmapd_process.h"
#include "cli_runner.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

std::string Bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(QuerySplitTest, ASplitRegionEqualsTheWholeRegionBitForBit) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_query_split_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // 20,000 pixels per query: the 45 x 30 m box below is 135,000 cells at stride 1.
  testing::BgkmapdProcess small(std::vector<std::string>{"--set", "server.max_region_cells=20000"});
  testing::BgkmapdProcess whole(std::vector<std::string>{});
  ASSERT_TRUE(small.started() && whole.started());
  for (const testing::BgkmapdProcess* s : {&small, &whole}) {
    ASSERT_EQ(
        testing::RunCli("insert " + kStreet + " --robot r1 --server " + s->target(), "2>/dev/null")
            .exit_code,
        0);
  }
  for (int stride : {1, 3}) {
    const std::string args = "query --bbox -20.03,-15,25,15.07 --stride " + std::to_string(stride);
    const std::string split = (dir / ("split" + std::to_string(stride) + ".tif")).string();
    const std::string one = (dir / ("whole" + std::to_string(stride) + ".tif")).string();
    testing::CliRun run =
        testing::RunCli(args + " --out " + split + " --server " + small.target(), "2>&1");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    if (stride == 1) {
      EXPECT_NE(run.output.find(" pieces)"), std::string::npos) << run.output;
    }
    run = testing::RunCli(args + " --out " + one + " --server " + whole.target(), "2>&1");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(run.output.find("pieces"), std::string::npos) << run.output;

    Result<Raster> a = io::ReadGeoTiff(split), b = io::ReadGeoTiff(one);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->box, b->box);
    EXPECT_EQ(a->cols, b->cols);
    EXPECT_EQ(a->rows, b->rows);
    EXPECT_EQ(a->x0, b->x0);
    EXPECT_EQ(a->y1, b->y1);
    ASSERT_EQ(a->layers, b->layers);
    for (size_t l = 0; l < a->layers.size(); ++l) {
      ASSERT_EQ(a->data[l].size(), b->data[l].size());
      EXPECT_EQ(
          0, std::memcmp(a->data[l].data(), b->data[l].data(), a->data[l].size() * sizeof(float)))
          << "stride " << stride << " layer " << l;
    }
    EXPECT_TRUE(Bytes(split) == Bytes(one)) << "stride " << stride << ": the files differ";
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
