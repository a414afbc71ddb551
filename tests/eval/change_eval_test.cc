// A changing world end to end through the CLI: `bgkmap simulate flat --change` renders a VLP-16
// standing 1.5 m above flat ground while one 2 x 2 x 1 m box disappears and another appears at
// scan 10, and `bgkmap eval` scores the stale-obstacle and missed-new-obstacle rates per scan
// after the change, with `dynamics: on` (the default) and `off` (the paper's accumulation).
// Mutations checked once by hand: the ray caster rendering every scan against the first scan's
// world (WorldAtScan(..., 0) in simulate_command.cc) fails StaleAndMissedRatesFollowTheWorld
// (the appeared box is never seen: missed 100 %); ScoreChange counting unknown cells of an
// appeared object as shown fails it too (missed 0 % just before the change).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "../cli/cli_runner.h"

namespace bgkmap::testing {
namespace {

namespace fs = std::filesystem;

constexpr int kScans = 20;
constexpr int kChange = 10;  // first scan of the changed world
constexpr char kScript[] = R"(objects:
  - name: leaves
    center: [5.0, 0.0]
    size: [2.0, 2.0]
    height: 1.0
    disappear: 10
  - name: arrives
    center: [-5.0, 0.0]
    size: [2.0, 2.0]
    height: 1.0
    appear: 10
)";

class ChangeEvalTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("bgkmap_change_eval_" + std::to_string(::getpid())));
    fs::create_directories(*dir_);
    std::ofstream(*dir_ / "change.yaml") << kScript;
    std::ofstream(*dir_ / "off.yaml") << "dynamics: off\n";
    const CliRun sim =
        RunCli("simulate flat --scans " + std::to_string(kScans) + " --change " +
               (*dir_ / "change.yaml").string() + " --out " + (*dir_ / "seq").string());
    ASSERT_EQ(sim.exit_code, 0) << sim.output;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }

  // eval.json's change curves of bgk+ with the given config ("" = defaults: dynamics on).
  static nlohmann::json Eval(const std::string& config, const std::string& out) {
    std::string args = "eval " + (*dir_ / "seq").string() + " --methods bgk+ --no-figures " +
                       "--change-scans 10 --out " + (*dir_ / out).string();
    if (!config.empty()) args += " --config " + (*dir_ / config).string();
    const CliRun run = RunCli(args);
    EXPECT_EQ(run.exit_code, 0) << run.output;
    std::ifstream in(*dir_ / out / "eval.json");
    nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
    EXPECT_FALSE(j.is_discarded());
    return j["methods"][0]["change"];
  }

  static fs::path* dir_;
};

fs::path* ChangeEvalTest::dir_ = nullptr;

TEST_F(ChangeEvalTest, SimulateWritesTheChangeAndBothTruths) {
  EXPECT_TRUE(fs::exists(*dir_ / "seq" / "ground_truth.tif"));
  EXPECT_TRUE(fs::exists(*dir_ / "seq" / "ground_truth_before.tif"));
  std::ifstream in(*dir_ / "seq" / "scenario.json");
  const nlohmann::json s = nlohmann::json::parse(in);
  ASSERT_EQ(s["objects"].size(), 2u);
  EXPECT_EQ(s["objects"][0]["disappear"], kChange);
  EXPECT_TRUE(s["objects"][0]["appear"].is_null());
  EXPECT_EQ(s["objects"][1]["appear"], kChange);
  // The robot stands still: each scan sees the boxes of its own scan's world. Points standing
  // 0.5 m or more above the ground (the sensor is 1.5 m up) ahead (+x) and behind (-x).
  const auto raised = [&](int k) {
    char name[16];
    std::snprintf(name, sizeof name, "%06d.bin", k);
    std::ifstream f(*dir_ / "seq" / "velodyne" / name, std::ios::binary);
    std::pair<int, int> n{0, 0};
    float p[4];
    while (f.read(reinterpret_cast<char*>(p), sizeof p)) {
      if (p[2] < -1.0f) continue;
      (p[0] > 0 ? n.first : n.second) += 1;
    }
    return n;
  };
  for (int k : {0, kChange - 1}) {
    EXPECT_GT(raised(k).first, 100) << "scan " << k << " sees the box that leaves";
    EXPECT_EQ(raised(k).second, 0) << "scan " << k << " sees no box behind";
  }
  for (int k : {kChange, kScans - 1}) {
    EXPECT_EQ(raised(k).first, 0) << "scan " << k << " sees the place of the box that left";
    EXPECT_GT(raised(k).second, 100) << "scan " << k << " sees the box that arrived";
  }
}

TEST_F(ChangeEvalTest, StaleAndMissedRatesFollowTheWorld) {
  const nlohmann::json on = Eval("", "on");
  const nlohmann::json off = Eval("off.yaml", "off");
  ASSERT_EQ(on["removed"].size(), 11u);  // 0 (just before) .. 10 scans after
  ASSERT_EQ(on["appeared"].size(), 11u);
  for (const nlohmann::json* c : {&on, &off}) {
    std::string curve;
    for (int j = 0; j <= 10; ++j) {
      char buf[64];
      std::snprintf(buf, sizeof buf, " %d:%.3f/%.3f", j,
                    (*c)["removed"][j]["stale_rate"].get<double>(),
                    (*c)["appeared"][j]["missed_rate"].get<double>());
      curve += buf;
    }
    std::printf("%s stale/missed per scan after the change:%s\n", c == &on ? "on " : "off",
                curve.c_str());
    // Enough cells judged, and the map had seen the box that left: just before the change
    // nearly every judged cell shows it, and none of the box that is not there yet.
    EXPECT_GT((*c)["removed"][0]["judged_cells"].get<int>(), 40);
    EXPECT_GT((*c)["appeared"][0]["judged_cells"].get<int>(), 40);
    EXPECT_GT((*c)["removed"][0]["stale_rate"].get<double>(), 0.9);
    EXPECT_EQ((*c)["appeared"][0]["missed_rate"].get<double>(), 1.0);
  }
  // dynamics on: the removed box is gone within a few scans, the new one shown after one.
  for (int j = 3; j <= 10; ++j) EXPECT_LT(on["removed"][j]["stale_rate"].get<double>(), 0.05);
  // (Measured: 5 % of the cells after 1 scan, then 0-3 %: a cell or two at the box's foot
  // flicker with the range noise of a robot standing still.)
  EXPECT_LE(on["appeared"][1]["missed_rate"].get<double>(), 0.10);
  for (int j = 2; j <= 10; ++j) EXPECT_LE(on["appeared"][j]["missed_rate"].get<double>(), 0.05);
  // dynamics off: the old box stays in the map, the new one shows slowly.
  for (int j = 1; j <= 10; ++j) EXPECT_GT(off["removed"][j]["stale_rate"].get<double>(), 0.8);
  for (int j = 1; j <= 10; ++j) EXPECT_GT(off["appeared"][j]["missed_rate"].get<double>(), 0.1);
}

// A script with a mistake is refused with one line naming the object and the fault, exit 1, and
// nothing is written.
TEST_F(ChangeEvalTest, BadScriptsAreRefusedWithOneLine) {
  const struct {
    const char* script;
    const char* says;
  } cases[] = {
      {"objects: [{center: [1, 2], size: [1, 1], heigth: 1}]", "object 1 (line 1): unknown key"},
      {"objects: [{center: [1, 2], size: [1, 1], height: 1, disappear: 20}]",
       "object 1.disappear (line 1): scan 20 is outside 1..19"},
      {"objects:\n  - {center: [1, 2], size: [1, 1], height: 1}\n  - {center: [1], size: [1, 1], "
       "height: 1}",
       "object 2.center (line 3): expected [x, y]"},
      {"objects: [{center: [1, 2], size: [0, 1], height: 1}]", "both sizes must be > 0"},
      {"objects: [{center: [1, 2], size: [1, 1], height: 1, appear: 3, disappear: 5}]",
       "give appear or disappear, not both"},
      {"objects: [{center: [1, 2], size: [1, 1], height: 1, velocity: [1, 0], appear: 5, "
       "disappear: 5}]",
       "disappear must come after appear"},
      {"objects: [{center: [1, 2], size: [1, 1], height: 1, velocity: 3}]",
       "object 1.velocity (line 1): expected [x, y]"},
      {"objects: [", "end of sequence flow not found"},
      {"boxes: []", "expected a map with an 'objects' list"},
  };
  for (const auto& c : cases) {
    const fs::path script = *dir_ / "bad.yaml";
    std::ofstream(script) << c.script;
    const fs::path out = *dir_ / "bad_seq";
    const CliRun run =
        RunCli("simulate flat --scans 20 --change " + script.string() + " --out " + out.string());
    EXPECT_EQ(run.exit_code, 1) << c.script;
    EXPECT_NE(run.output.find(c.says), std::string::npos) << run.output;
    EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;
    EXPECT_FALSE(fs::exists(out));
  }
}

}  // namespace
}  // namespace bgkmap::testing
