// The habits every `bgkmap` subcommand shares (README, "Exit codes"): --version, $BGKMAP_SERVER
// as the default server, and exit codes 0 success, 1 failure, 2 usage error; check-path 0 safe,
// 1 unsafe, 2 error, like grep and diff.
#include <gtest/gtest.h>
#include <signal.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bgkmapd_process.h"
#include "cli_runner.h"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
const std::string kStreet = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";
constexpr const char* kNowhere = " --server unix:/nonexistent/bgkmapd.sock";

class CliHabitsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    unsetenv("BGKMAP_SERVER");
    dir_ = fs::temp_directory_path() / ("bgkmap_cli_habits_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    server_ = new testing::BgkmapdProcess(std::vector<std::string>{});
    ASSERT_TRUE(server_->started());
    ASSERT_EQ(testing::RunCli("insert " + kStreet + " --robot r1" + S()).exit_code, 0);
  }
  static void TearDownTestSuite() {
    server_->Signal(SIGTERM);
    EXPECT_EQ(server_->Wait(), 0);
    delete server_;
    fs::remove_all(dir_);
  }
  void TearDown() override { unsetenv("BGKMAP_SERVER"); }
  static std::string S() { return " --server " + server_->target(); }
  static std::string Path(const std::string& n) { return (dir_ / n).string(); }
  // Exit code and stderr.
  static testing::CliRun Err(const std::string& args) {
    return testing::RunCli(args, "2>&1 >/dev/null");
  }
  static inline fs::path dir_;
  static inline testing::BgkmapdProcess* server_ = nullptr;
};

TEST_F(CliHabitsTest, VersionAndHelpExitZero) {
  testing::CliRun run = testing::RunCli("--version", "2>/dev/null");
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_EQ(run.output, std::string("bgkmap ") + BGKMAP_VERSION + "\n");
  EXPECT_EQ(testing::RunCli("--help", "2>/dev/null").exit_code, 0);
  run = testing::RunCli("info --help", "2>/dev/null");
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_NE(run.output.find("BGKMAP_SERVER"), std::string::npos) << run.output;
}

TEST_F(CliHabitsTest, BadCommandLinesExitTwo) {
  for (const std::string& args : {
           std::string(""),                                    // no subcommand
           std::string("frobnicate"),                          // unknown subcommand
           "query --out x.tif --bogus" + S(),                  // unknown option
           "query --bbox 1,1,0,0 --out x.tif" + S(),           // inverted box
           "query --out x.tif --layers slope" + S(),           // unknown layer
           "query --out x.tif --stride 0" + S(),               // stride
           "points 1" + S(),                                   // not x,y pairs
           "points 1,2 --layers slope" + S(),                  // unknown layer
           "watch --bbox 1,1,0,0" + S(),                       // inverted box
           "clear --bbox 9,-1,11,1" + S(),                     // needs --yes
           "export --bbox 1,1,0,0 " + Path("x.bgkmap") + S(),  // inverted box
           "insert " + kStreet + " --rate -1" + S(),           // negative rate
           std::string("build ") + kStreet + " --out x.tif --method fancy",
           std::string("import"),  // missing input
       }) {
    const testing::CliRun run = Err(args);
    EXPECT_EQ(run.exit_code, 2) << args << "\n" << run.output;
    EXPECT_FALSE(run.output.empty()) << args;
  }
  // Usage errors are found before any server is asked: the same with no server at all.
  EXPECT_EQ(Err(std::string("query --out x.tif --stride 0") + kNowhere).exit_code, 2);
}

TEST_F(CliHabitsTest, FailuresExitOne) {
  for (const std::string& args : {
           std::string("info") + kNowhere,  // unreachable
           std::string("points 1,2") + kNowhere,
           "query --bbox -1e6,-1e6,1e6,1e6 --out " + Path("huge.tif") + S(),  // server refuses
           "import " + Path("missing.bgkmap") + S(),                          // no such file
           "insert " + Path("no-such-dir") + S(),
       }) {
    const testing::CliRun run = Err(args);
    EXPECT_EQ(run.exit_code, 1) << args << "\n" << run.output;
    EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << args << run.output;
  }
}

TEST_F(CliHabitsTest, CheckPathExitsZeroSafeOneUnsafeTwoOnError) {
  // On the road ahead of the car, with thresholds no known footprint can fail: safe.
  testing::CliRun run = testing::RunCli(
      "check-path --poses 10,0,0 --radius 0.3 --max-traversability 1.5 --max-variance 1e9 "
      "--max-unknown 0.99" +
          S(),
      "2>/dev/null");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(nlohmann::json::parse(run.output)["safe"], true);
  // Into unknown space: unsafe, 1, still with the JSON answer. The trouble begins on the
  // segment after pose 0, before the far pose.
  run = testing::RunCli("check-path --poses 10,0,0,0,500,0 --radius 0.3" + S(), "2>/dev/null");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  nlohmann::json answer = nlohmann::json::parse(run.output);
  EXPECT_EQ(answer["first_unsafe_index"], 0);
  EXPECT_EQ(answer["first_unsafe_point"]["segment"], 0);
  EXPECT_GT(answer["first_unsafe_point"]["t"].get<double>(), 0.0);
  EXPECT_EQ(answer["first_unsafe_point"]["safe"], false);
  EXPECT_EQ(answer["poses"][1]["safe"], false);
  // Issue 29: two poses each safe on the street, joined over the unknown ground under the
  // sensor: unsafe between them, with the point where it starts.
  run = testing::RunCli("check-path --poses -8,-2,0,8,2,0 --radius 0.3" + S(), "2>/dev/null");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  answer = nlohmann::json::parse(run.output);
  EXPECT_EQ(answer["poses"][0]["safe"], true) << run.output;
  EXPECT_EQ(answer["poses"][1]["safe"], true) << run.output;
  EXPECT_EQ(answer["segments"][0]["safe"], false);
  EXPECT_EQ(answer["segments"][0]["placements"], 164);
  const double x = answer["first_unsafe_point"]["x"].get<double>();
  EXPECT_GT(x, -8.0);
  EXPECT_LT(x, 8.0);
  EXPECT_NEAR(answer["first_unsafe_point"]["y"].get<double>(), x / 4, 1e-9);
  // Every error is 2: usage, parse, server.
  for (const std::string& args :
       {"check-path --poses 0,0,0" + S(),           // no footprint
        "check-path --poses 0,0 --radius 1" + S(),  // not triples
        "check-path --radius 1" + S(),              // --poses missing
        std::string("check-path --poses 0,0,0 --radius 1") + kNowhere,
        "check-path --poses 0,0,0 --polygon 0,0,1,1" + S()}) {  // 2 vertices
    run = Err(args);
    EXPECT_EQ(run.exit_code, 2) << args << "\n" << run.output;
    EXPECT_FALSE(run.output.empty()) << args;
  }
}

TEST_F(CliHabitsTest, ServerDefaultsToTheEnvironmentAndTheFlagWins) {
  ASSERT_EQ(setenv("BGKMAP_SERVER", server_->target().c_str(), 1), 0);
  testing::CliRun run = testing::RunCli("info", "2>/dev/null");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(nlohmann::json::parse(run.output)["robots"][0]["robot_id"], "r1");
  EXPECT_EQ(testing::RunCli("points 10,0", "2>/dev/null").exit_code, 0);
  // --server overrides the environment.
  EXPECT_EQ(testing::RunCli(std::string("info") + kNowhere).exit_code, 1);
  // And the environment overrides the built-in default: nothing listens here.
  ASSERT_EQ(setenv("BGKMAP_SERVER", "unix:/nonexistent/bgkmapd.sock", 1), 0);
  run = Err("info");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.output.find("UNAVAILABLE"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace bgkmap
