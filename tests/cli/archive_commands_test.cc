// `bgkmap export` and `bgkmap import` against two real bgkmapd processes on the real Ouster
// street scans: the imported map answers queries exactly as the exported one; failures are one
// line and a non-zero exit.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "bgkmap/io/geotiff.h"
#include "bgkmapd_process.h"
#include "cli_runner.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

testing::CliRun Cli(const std::string& args) { return testing::RunCli(args, "2>/dev/null"); }

TEST(ArchiveCommandsTest, ExportImportRoundTripAndOneLineErrors) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_cli_archive_" + std::to_string(getpid()));
  fs::create_directories(dir);
  auto path = [&](const std::string& n) { return (dir / n).string(); };
  testing::BgkmapdProcess source(std::vector<std::string>{});
  testing::BgkmapdProcess target(std::vector<std::string>{"--data-dir", path("target-store")});
  ASSERT_TRUE(source.started() && target.started());
  const std::string from = " --server " + source.target(), to = " --server " + target.target();

  ASSERT_EQ(Cli("insert " + kStreet + " --robot r1" + from).exit_code, 0);
  testing::CliRun run = Cli("export " + path("street.bgkmap") + from);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("163 tiles"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("map version 3"), std::string::npos) << run.output;
  EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;

  run = Cli("import " + path("street.bgkmap") + to);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("163 tiles added"), std::string::npos) << run.output;
  EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;

  // The same region of both servers, bit for bit.
  ASSERT_EQ(Cli("query --bbox -40,-40,40,40 --out " + path("a.tif") + from).exit_code, 0);
  ASSERT_EQ(Cli("query --bbox -40,-40,40,40 --out " + path("b.tif") + to).exit_code, 0);
  Result<Raster> a = io::ReadGeoTiff(path("a.tif"));
  Result<Raster> b = io::ReadGeoTiff(path("b.tif"));
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->data.size(), b->data.size());
  for (size_t l = 0; l < a->data.size(); ++l) {
    ASSERT_EQ(a->data[l].size(), b->data[l].size());
    EXPECT_EQ(std::memcmp(a->data[l].data(), b->data[l].data(), a->data[l].size() * 4), 0)
        << "layer " << l;
  }

  // A region export (--box is --bbox) holds fewer tiles.
  run = Cli("export --box 0,0,10,10 " + path("region.bgkmap") + from);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_LT(fs::file_size(path("region.bgkmap")), fs::file_size(path("street.bgkmap")));

  // Failures: one line on stderr, exit 1 (2 for a bad command line), nothing half-written.
  std::ofstream(path("junk.bgkmap")) << "not a map\n";
  for (const std::string& args :
       {"import " + path("junk.bgkmap") + to, "import " + path("missing.bgkmap") + to,
        "export --bbox 5,5,1,1 " + path("bad.bgkmap") + from,
        "export " + path("no/such/dir/x.bgkmap") + from}) {
    const testing::CliRun failed = testing::RunCli(args, "2>&1 >/dev/null");
    EXPECT_EQ(failed.exit_code, args.find("--bbox") != std::string::npos ? 2 : 1) << args;
    EXPECT_EQ(std::count(failed.output.begin(), failed.output.end(), '\n'), 1) << args << "\n"
                                                                               << failed.output;
  }
  EXPECT_NE(
      testing::RunCli("import " + path("junk.bgkmap") + to, "2>&1").output.find("INVALID_ARGUMENT"),
      std::string::npos);
  EXPECT_FALSE(fs::exists(path("bad.bgkmap")));

  source.Signal(SIGTERM);
  target.Signal(SIGTERM);
  EXPECT_EQ(source.Wait(), 0);
  EXPECT_EQ(target.Wait(), 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
