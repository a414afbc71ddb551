// The `bgkmap` client subcommands against a real bgkmapd on a loopback port, on the real Ouster
// street scans: what a user types, what they get back.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "bgkmap/io/geotiff.h"
#include "bgkmapd_process.h"
#include "cli_runner.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";

// stdout only: the machine-readable answer.
testing::CliRun Cli(const std::string& args) { return testing::RunCli(args, "2>/dev/null"); }

class ServerCommandsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("bgkmap_cli_server_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    server_ = new testing::BgkmapdProcess(std::vector<std::string>{});
    ASSERT_TRUE(server_->started());
  }
  static void TearDownTestSuite() {
    server_->Signal(SIGTERM);
    EXPECT_EQ(server_->Wait(), 0);
    delete server_;
    fs::remove_all(dir_);
  }
  static std::string S() { return " --server " + server_->target(); }
  static std::string Path(const std::string& n) { return (dir_ / n).string(); }
  static inline fs::path dir_;
  static inline testing::BgkmapdProcess* server_ = nullptr;
};

TEST_F(ServerCommandsTest, ServedMapEqualsTheOfflineBuildAndResumesBySequence) {
  // As float32, the points `bgkmap build` reads (the default compact scans are the dequantized
  // points: CompactScanTest pins that map).
  testing::CliRun run = Cli("insert " + kStreet + " --robot r1 --float32" + S());
  ASSERT_EQ(run.exit_code, 0);
  EXPECT_NE(run.output.find("3 applied"), std::string::npos) << run.output;
  // Again: the server already has sequences 1..3 of r1, so nothing is sent.
  run = Cli("insert " + kStreet + " --robot r1" + S());
  ASSERT_EQ(run.exit_code, 0);
  EXPECT_NE(run.output.find("0 applied, 0 duplicate"), std::string::npos) << run.output;
  // Forced resend: acknowledged as duplicates, not applied twice.
  run = Cli("insert " + kStreet + " --robot r1 --restart" + S());
  ASSERT_EQ(run.exit_code, 0);
  EXPECT_NE(run.output.find("0 applied, 3 duplicate"), std::string::npos) << run.output;

  ASSERT_EQ(Cli("query --out " + Path("served.tif") + S()).exit_code, 0);
  ASSERT_EQ(Cli("build " + kStreet + " --out " + Path("offline.tif")).exit_code, 0);
  Result<Raster> served = io::ReadGeoTiff(Path("served.tif"));
  Result<Raster> offline = io::ReadGeoTiff(Path("offline.tif"));
  ASSERT_TRUE(served.ok() && offline.ok());
  ASSERT_EQ(served->box, offline->box);
  ASSERT_EQ(served->layers, offline->layers);
  for (size_t l = 0; l < served->layers.size(); ++l) {
    for (size_t i = 0; i < served->data[l].size(); ++i) {
      const float a = served->data[l][i], b = offline->data[l][i];
      ASSERT_EQ(std::isnan(a), std::isnan(b)) << "layer " << l << " pixel " << i;
      if (!std::isnan(a)) {
        ASSERT_NEAR(a, b, 1e-5) << "layer " << l << " pixel " << i;
      }
    }
  }

  const nlohmann::json info = nlohmann::json::parse(Cli("info" + S()).output);
  EXPECT_EQ(info["robots"][0]["robot_id"], "r1");
  EXPECT_EQ(info["robots"][0]["last_sequence"], 3);
  EXPECT_EQ(info["params"]["method"], "bgk+");
  EXPECT_GT(info["known_cells"].get<int64_t>(), 100000);
}

TEST_F(ServerCommandsTest, PointsPathWatchAndClearAnswerAsDocumented) {
  ASSERT_EQ(Cli("insert " + kStreet + " --robot r2" + S()).exit_code, 0);
  nlohmann::json pts = nlohmann::json::parse(Cli("points 10,0 0,500" + S()).output);
  EXPECT_EQ(pts["points"][0]["state"], 1.0);             // the road ahead of the car
  EXPECT_TRUE(pts["points"][1]["elevation"].is_null());  // far outside: unknown
  EXPECT_EQ(pts["points"][1]["state"], 0.0);

  // A path into unknown space is unsafe (exit 1), with the first unsafe pose named.
  testing::CliRun run = Cli("check-path --poses 10,0,0,0,500,0 --radius 0.3" + S());
  EXPECT_EQ(run.exit_code, 1) << run.output;
  const nlohmann::json path = nlohmann::json::parse(run.output);
  EXPECT_EQ(path["safe"], false);
  EXPECT_EQ(path["poses"][1]["unknown_fraction"], 1.0);

  run = Cli("watch --bbox -5,-5,5,5 --snapshot --count 2" + S());
  ASSERT_EQ(run.exit_code, 0);
  EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 2) << run.output;

  EXPECT_EQ(Cli("clear --bbox 9,-1,11,1" + S()).exit_code, 2);  // needs --yes: a usage error
  ASSERT_EQ(Cli("clear --bbox 9,-1,11,1 --yes" + S()).exit_code, 0);
  pts = nlohmann::json::parse(Cli("points 10,0" + S()).output);
  EXPECT_EQ(pts["points"][0]["state"], 0.0);
}

TEST_F(ServerCommandsTest, QuerySinceListsTheChangedTilesAndTombstones) {
  ASSERT_EQ(Cli("insert " + kStreet + " --robot r3" + S()).exit_code, 0);
  const uint64_t version =
      nlohmann::json::parse(Cli("info" + S()).output)["map_version"].get<uint64_t>();
  ASSERT_EQ(Cli("clear --bbox 0,0,6.4,6.4 --yes" + S()).exit_code, 0);  // tile (0, 0) whole
  testing::CliRun run =
      Cli("query --bbox -10,-10,10,10 --compress --since " + std::to_string(version) + S());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  nlohmann::json delta = nlohmann::json::parse(run.output);
  EXPECT_EQ(delta["answer"], "delta");
  EXPECT_EQ(delta["map_version"], version + 1);
  ASSERT_EQ(delta["tiles"].size(), 1u) << run.output;
  EXPECT_EQ(delta["tiles"][0]["x"], 0);
  EXPECT_EQ(delta["tiles"][0]["tombstone"], true);
  // Another history (the server restarted, or another one): the whole region, flagged.
  const uint64_t other = delta["history_id"].get<uint64_t>() + 1;
  run = Cli("query --bbox -10,-10,10,10 --since " + std::to_string(version) + " --history-id " +
            std::to_string(other) + S());
  ASSERT_EQ(run.exit_code, 0);
  delta = nlohmann::json::parse(run.output);
  EXPECT_EQ(delta["answer"], "full_resync");
  EXPECT_NE(delta["resync_reason"].get<std::string>().find("history_id"), std::string::npos);
  // A delta is not a raster: --out with --since, or neither, is a usage error.
  EXPECT_EQ(Cli("query --since 1 --out " + Path("d.tif") + S()).exit_code, 2);
  EXPECT_EQ(Cli("query --bbox -1,-1,1,1" + S()).exit_code, 2);
}

TEST_F(ServerCommandsTest, ErrorsAreOneLineAndNonZero) {
  for (const std::string& args :
       {std::string("info --server unix:/nonexistent/bgkmapd.sock"),
        "query --bbox 1,1,0,0 --out x.tif" + S(), "points 1" + S(),
        "check-path --poses 0,0,0" + S(),
        "query --bbox -1e6,-1e6,1e6,1e6 --out " + Path("huge.tif") + S()}) {
    const testing::CliRun run = testing::RunCli(args, "2>&1 >/dev/null");
    const std::string& err = run.output;
    EXPECT_NE(run.exit_code, 0) << args;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << args << "\n" << err;
  }
}

// `bgkmap insert` reads scans ahead of the one it sends: a scan file that cannot be read still ends
// the insert with its own message, after the scans before it were applied, and nothing after it.
TEST_F(ServerCommandsTest, AnUnreadableScanEndsTheInsertAfterTheScansBeforeIt) {
  const fs::path seq = dir_ / "broken_street";
  fs::create_directories(seq / "velodyne");
  fs::copy_file(fs::path(kStreet) / "poses.txt", seq / "poses.txt");
  for (const char* scan : {"000000.bin", "000001.bin", "000002.bin"}) {
    fs::copy_file(fs::path(kStreet) / "velodyne" / scan, seq / "velodyne" / scan);
  }
  fs::resize_file(seq / "velodyne" / "000001.bin", 10);  // not whole x,y,z,i records
  const testing::CliRun run =
      testing::RunCli("insert " + seq.string() + " --robot broken" + S(), "2>&1 >/dev/null");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("000001.bin: size 10 bytes is not a multiple of 16"), std::string::npos)
      << run.output;
  const testing::CliRun info = Cli("info" + S());
  ASSERT_EQ(info.exit_code, 0);
  const nlohmann::json robots = nlohmann::json::parse(info.output)["robots"];
  bool found = false;
  for (const nlohmann::json& r : robots) {
    if (r["robot_id"] != "broken") continue;
    found = true;
    EXPECT_EQ(r["last_sequence"], 1) << r.dump();
    EXPECT_EQ(r["scans_applied"], 1) << r.dump();
  }
  EXPECT_TRUE(found) << info.output;
}

// A server tied to a CRS: `bgkmap query` writes its GeoTIFF in that CRS, shifted by the origin
// (heights too), while the cells and other bands are the map's own.
TEST(GeoreferencedQueryTest, QueryWritesTheServersCrsAndOrigin) {
  const fs::path dir = fs::temp_directory_path() / ("bgkmap_geo_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  testing::BgkmapdProcess server(
      std::vector<std::string>{"--set", "georeference.crs=EPSG:32610", "--set",
                               "georeference.origin=[551000, 4180000, 12.5]"});
  ASSERT_TRUE(server.started());
  const std::string s = " --server " + server.target();
  ASSERT_EQ(Cli("insert " + kStreet + " --robot r1" + s).exit_code, 0);
  const std::string geo = (dir / "geo.tif").string(), local = (dir / "local.tif").string();
  const std::string box = " --bbox -10,-10,10,10";
  ASSERT_EQ(Cli("query --cog --out " + geo + box + s).exit_code, 0);
  // --crs with --origin 0,0: the map frame's coordinates taken as the CRS's, no shift.
  ASSERT_EQ(Cli("query --crs EPSG:32610 --origin 0,0 --out " + local + box + s).exit_code, 0);
  const testing::CliRun info = testing::RunCommand("gdalinfo " + geo + " 2>&1");
  EXPECT_NE(info.output.find("ID[\"EPSG\",32610]"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("LAYOUT=COG"), std::string::npos) << info.output;
  Result<Raster> g = io::ReadGeoTiff(geo), l = io::ReadGeoTiff(local);
  ASSERT_TRUE(g.ok() && l.ok());
  EXPECT_EQ(g->box, l->box);
  EXPECT_DOUBLE_EQ(g->x0, l->x0 + 551000);
  EXPECT_DOUBLE_EQ(g->y1, l->y1 + 4180000);
  size_t known = 0;
  for (size_t b = 0; b < l->layers.size(); ++b) {
    const bool elevation = l->layers[b] == Layer::kElevation;
    for (size_t i = 0; i < l->data[b].size(); ++i) {
      const float lv = l->data[b][i], gv = g->data[b][i];
      if (std::isnan(lv)) {
        EXPECT_TRUE(std::isnan(gv));
        continue;
      }
      known += elevation;
      EXPECT_FLOAT_EQ(gv, elevation ? static_cast<float>(lv + 12.5) : lv);
    }
  }
  EXPECT_GT(known, 1000u);
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(), 0);
  fs::remove_all(dir);
}

// `bgkmap correct` and `bgkmap remove-scans` against a server with a store: line i of a KITTI
// poses file is sequence i, as `bgkmap insert` numbered the scans; a bad file is a usage error
// naming the line, a file with more lines than scans a server error naming the sequence.
TEST(CorrectCommandTest, CorrectsByLineNumberAndRefusesBadFilesWithOneLine) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_cli_correct_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  testing::BgkmapdProcess server({"--data-dir", (dir / "map").string()});
  ASSERT_TRUE(server.started());
  const std::string s = " --server " + server.target();
  ASSERT_EQ(Cli("insert " + kStreet + " --robot r1" + s).exit_code, 0);

  testing::CliRun run = Cli("correct --robot r1 --poses " + kStreet + "/poses.txt" + s);
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_NE(run.output.find("3 scans re-integrated"), std::string::npos) << run.output;

  auto write = [&](const std::string& name, const std::string& text) {
    std::FILE* f = std::fopen((dir / name).c_str(), "w");
    std::fputs(text.c_str(), f);
    std::fclose(f);
    return (dir / name).string();
  };
  run = testing::RunCli(
      "correct --robot r1 --poses " + write("short.txt", "1 0 0 0 0 1 0 0 0 0 1\n") + s,
      "2>&1 >/dev/null");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("short.txt:1: 11 numbers"), std::string::npos) << run.output;
  const std::string identity = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  run = testing::RunCli("correct --robot r1 --poses " +
                            write("long.txt", identity + identity + identity + identity) + s,
                        "2>&1 >/dev/null");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.output.find("sequence 4"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("never ingested"), std::string::npos) << run.output;

  run = Cli("remove-scans --robot r1 --from 2 --to 3" + s);
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_NE(run.output.find("2 scans re-integrated"), std::string::npos) << run.output;
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(), 0);
  fs::remove_all(dir);
}

// The georeference is the stored map's: a server restarted on the store with none configured
// still writes its GeoTIFFs in the CRS, and GDAL reads the CRS and the shifted origin back.
TEST(GeoreferencedQueryTest, TheStoredGeoreferenceOutlivesTheConfiguration) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_geo_store_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string store = (dir / "store").string();
  {
    testing::BgkmapdProcess server(
        std::vector<std::string>{"--data-dir", store, "--set", "georeference.crs=EPSG:32610",
                                 "--set", "georeference.origin=[551000, 4180000, 12.5]"});
    ASSERT_TRUE(server.started());
    ASSERT_EQ(Cli("insert " + kStreet + " --robot r1 --server " + server.target()).exit_code, 0);
    server.Signal(SIGTERM);
    ASSERT_EQ(server.Wait(), 0);
  }
  testing::BgkmapdProcess server(std::vector<std::string>{"--data-dir", store});
  ASSERT_TRUE(server.started());
  const std::string tif = (dir / "stored.tif").string();
  ASSERT_EQ(
      Cli("query --bbox -10,-10,10,10 --out " + tif + " --server " + server.target()).exit_code, 0);
  const testing::CliRun info = testing::RunCommand("gdalinfo " + tif + " 2>&1");
  EXPECT_NE(info.output.find("ID[\"EPSG\",32610]"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("Origin = (550990.000000000000000,4180010.000000000000000)"),
            std::string::npos)
      << info.output;
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(), 0);

  // Restarting it with another CRS is refused, naming the key: the cells would be misplaced.
  const auto [code, out] = testing::RunBgkmapd(
      {"--listen", "127.0.0.1:0", "--data-dir", store, "--set", "georeference.crs=EPSG:2949"});
  EXPECT_NE(code, 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
