// `bgkmap query` of a region over the server's per-query limit (issue 29): read in pieces and
// stitched into one GeoTIFF, equal bit for bit to the region read whole; a GeoTIFF over
// --max-memory-mb streamed window by window, equal pixel for pixel, with the CLI's peak resident
// set bounded. Two real servers on the street scans: one whose server.max_region_cells is tiny,
// one with the default.
#include <fcntl.h>
#include <gdal.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <vector>

#include "bgkmap/io/geotiff.h"
#include "bgkmap/io/qgis_style.h"
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

// Two servers fed the street: one answering at most 20,000 pixels a query, one without limit.
struct StreetServers {
  testing::BgkmapdProcess small{std::vector<std::string>{"--set", "server.max_region_cells=20000"}};
  testing::BgkmapdProcess whole{std::vector<std::string>{}};
  bool FeedTheStreet() {
    for (const testing::BgkmapdProcess* s : {&small, &whole}) {
      if (!s->started() ||
          testing::RunCli("insert " + kStreet + " --robot r1 --server " + s->target(),
                          "2>/dev/null")
                  .exit_code != 0) {
        return false;
      }
    }
    return true;
  }
};

TEST(QuerySplitTest, ASplitRegionEqualsTheWholeRegionBitForBit) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_query_split_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // 20,000 pixels per query: the 45 x 30 m box below is 135,000 cells at stride 1.
  StreetServers servers;
  ASSERT_TRUE(servers.FeedTheStreet());
  testing::BgkmapdProcess &small = servers.small, &whole = servers.whole;
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

bool SamePixels(const Raster& a, const Raster& b) {
  if (a.box != b.box || a.cols != b.cols || a.rows != b.rows || a.x0 != b.x0 || a.y1 != b.y1 ||
      a.layers != b.layers) {
    return false;
  }
  for (size_t l = 0; l < a.layers.size(); ++l) {
    if (a.data[l].size() != b.data[l].size() ||
        std::memcmp(a.data[l].data(), b.data[l].data(), a.data[l].size() * sizeof(float)) != 0) {
      return false;
    }
  }
  return true;
}

struct Measured {
  int exit_code = -1;
  long peak_rss_kb = 0;  // the process's VmHWM (ru_maxrss)
};

// `bgkmap <args>` (split at spaces), its output discarded, with its own peak resident set
// (wait4's rusage is the child's alone: the servers and earlier commands do not count).
Measured RunCliMeasured(const std::string& args) {
  std::vector<std::string> words{BGKMAP_CLI};
  std::istringstream in(args);
  for (std::string w; in >> w;) words.push_back(w);
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(w.data());
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 1);
    ::dup2(null, 2);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  Measured m;
  int status = 0;
  rusage usage{};
  if (pid > 0 && ::wait4(pid, &status, 0, &usage) == pid) {
    m.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    m.peak_rss_kb = usage.ru_maxrss;
  }
  return m;
}

// A region whose stitched raster (800 x 600 pixels x 7 layers x 4 bytes = 13.4 MB) is over a
// 1 MB bound: written in twelve windows of 256 pixels (one block), each window read in pieces of
// at most 20,000 pixels from the small server, equal pixel for pixel to one whole query's file,
// as a GeoTIFF and as a COG. An output that needs the whole raster is refused over the bound.
TEST(QuerySplitTest, AGeoTiffOverTheMemoryBoundIsWrittenInWindowsPixelForPixel) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_query_windows_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  StreetServers servers;
  ASSERT_TRUE(servers.FeedTheStreet());
  testing::BgkmapdProcess &small = servers.small, &whole = servers.whole;
  const std::string args = "query --bbox -40,-30,40,30";
  for (const std::string cog : {"", " --cog"}) {
    const std::string kind = cog.empty() ? "plain" : "cog";
    const std::string windows = (dir / ("windows_" + kind + ".tif")).string();
    const std::string one = (dir / ("whole_" + kind + ".tif")).string();
    testing::CliRun run = testing::RunCli(
        args + cog + " --max-memory-mb 1 --out " + windows + " --server " + small.target(), "2>&1");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("800 x 600 pixels"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find(" in 12 windows)"), std::string::npos) << run.output;
    run = testing::RunCli(args + cog + " --out " + one + " --server " + whole.target(), "2>&1");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(run.output.find(" windows)"), std::string::npos) << run.output;
    Result<Raster> a = io::ReadGeoTiff(windows), b = io::ReadGeoTiff(one);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->cols, 800);
    EXPECT_TRUE(SamePixels(*a, *b)) << kind;
    EXPECT_TRUE(fs::exists(io::QgisStylePath(windows))) << "the QGIS style beside it";
  }
  const testing::CliRun png = testing::RunCli(
      args + " --max-memory-mb 1 --out " + (dir / "x.png").string() + " --server " + small.target(),
      "2>&1");
  EXPECT_EQ(png.exit_code, 2) << png.output;
  EXPECT_NE(png.output.find("over --max-memory-mb 1"), std::string::npos) << png.output;
  EXPECT_FALSE(fs::exists(dir / "x.png"));
  fs::remove_all(dir);
}

// The CLI's peak resident set stays bounded whatever the region: 300 x 300 m at 0.1 m is
// 9 M pixels, 252 MB stitched; streamed within --max-memory-mb 16 it peaks near the process's
// own base (~66 MB here: gRPC, GDAL, PROJ), far below the stitched raster (which alone, and
// again as its pieces, the in-memory path held).
TEST(QuerySplitTest, ALargeGeoTiffIsWrittenWithBoundedMemory) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_query_rss_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  testing::BgkmapdProcess server(std::vector<std::string>{});
  ASSERT_TRUE(server.started());
  ASSERT_EQ(testing::RunCli("insert " + kStreet + " --robot r1 --server " + server.target(),
                            "2>/dev/null")
                .exit_code,
            0);
  const std::string out = (dir / "large.tif").string();
  const Measured m = RunCliMeasured("query --bbox -150,-150,150,150 --max-memory-mb 16 --out " +
                                    out + " --server " + server.target());
  ASSERT_EQ(m.exit_code, 0);
  std::printf("peak resident set of bgkmap query: %ld kB (the stitched raster: 252 MB)\n",
              m.peak_rss_kb);
  EXPECT_LT(m.peak_rss_kb, 160 * 1024);
  GDALAllRegister();  // this test may run alone: nothing else registered GDAL's drivers
  GDALDatasetH ds = GDALOpen(out.c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  EXPECT_EQ(GDALGetRasterXSize(ds), 3000);
  EXPECT_EQ(GDALGetRasterYSize(ds), 3000);
  EXPECT_EQ(GDALGetRasterCount(ds), 7);
  GDALClose(ds);
  // A COG: its copy with overviews runs with GDAL's block cache set from the bound (measured
  // 130 MB; 463 MB with GDAL's default cache of 5% of the RAM).
  const std::string cog = (dir / "large_cog.tif").string();
  const Measured c =
      RunCliMeasured("query --bbox -150,-150,150,150 --cog --max-memory-mb 16 --out " + cog +
                     " --server " + server.target());
  ASSERT_EQ(c.exit_code, 0);
  std::printf("peak resident set of bgkmap query --cog: %ld kB\n", c.peak_rss_kb);
  EXPECT_LT(c.peak_rss_kb, 220 * 1024);
  EXPECT_FALSE(fs::exists(cog + ".staging.tif"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
