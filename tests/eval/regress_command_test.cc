// `bgkmap regress` end to end on a small synthetic cloud: the cross-validated parameters depend on
// the training half only (changing every test point leaves them and the training set unchanged),
// and on a smooth surface the test RMSE is finite and small.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

namespace {

namespace fs = std::filesystem;
using Xyz = std::tuple<double, double, double>;

double Surface(double x, double y) { return 2.0 * std::sin(x / 15.0) + std::cos(y / 20.0); }

// 1,500 points on 60 x 60 m, coordinates in centimetres so the training CSV prints them exactly.
std::vector<Xyz> Cloud() {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> cm(0, 6000);
  std::vector<Xyz> pts;
  for (int i = 0; i < 1500; ++i) {
    const double x = cm(rng) / 100.0, y = cm(rng) / 100.0;
    pts.emplace_back(x, y, std::round(Surface(x, y) * 1e4) / 1e4);
  }
  return pts;
}

void WritePcd(const fs::path& path, const std::vector<Xyz>& pts) {
  std::ofstream out(path);
  out << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH "
      << pts.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << pts.size()
      << "\nDATA ascii\n";
  for (const auto& [x, y, z] : pts) out << x << ' ' << y << ' ' << z << '\n';
}

// The (x, y) of every training point, from the CSV the command hands to gdal_grid.
std::set<std::pair<long, long>> TrainingCells(const fs::path& csv) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  std::set<std::pair<long, long>> xy;
  double x, y, z;
  char c1, c2;
  while (in >> x >> c1 >> y >> c2 >> z) xy.insert({std::lround(x * 100), std::lround(y * 100)});
  return xy;
}

nlohmann::json Regress(const fs::path& cloud, const fs::path& out) {
  const std::string cmd = std::string(BGKMAP_CLI) + " regress " + cloud.string() + " --out " +
                          out.string() +
                          " --seed 3 --folds 3 --resolutions 1,2 --kernel-lengths 2,4,8"
                          " --peers linear > " +
                          (out.string() + ".log") + " 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(out / "regress.json");
  return nlohmann::json::parse(in);
}

TEST(RegressCommandTest, ParametersComeFromTheTrainingHalfAndTheSmoothSurfaceIsFit) {
  const fs::path dir = fs::temp_directory_path() / ("bgkmap_regress_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::vector<Xyz> pts = Cloud();
  WritePcd(dir / "a.pcd", pts);
  const nlohmann::json a = Regress(dir / "a.pcd", dir / "a");
  ASSERT_EQ(a["train"].get<int>() + a["test"].get<int>(), 1500);

  // The same cloud with every test point 50 m off: the split (by seed and count) is the same.
  const auto train = TrainingCells(dir / "a" / "train.csv");
  ASSERT_EQ(train.size(), a["train"].get<size_t>());
  std::vector<Xyz> moved = pts;
  int changed = 0;
  for (auto& [x, y, z] : moved) {
    if (!train.contains({std::lround(x * 100), std::lround(y * 100)})) z += 50.0, ++changed;
  }
  ASSERT_EQ(changed, a["test"].get<int>());
  WritePcd(dir / "b.pcd", moved);
  const nlohmann::json b = Regress(dir / "b.pcd", dir / "b");

  EXPECT_EQ(a["chosen"], b["chosen"]);
  EXPECT_EQ(a["cv"], b["cv"]);  // every candidate's CV score, not only the winner
  EXPECT_EQ(TrainingCells(dir / "b" / "train.csv"), train);
  EXPECT_GT(b["results"][0]["rmse"].get<double>(), 40.0);  // the test half did change

  const double l = a["chosen"]["kernel_length"], res = a["chosen"]["resolution"];
  EXPECT_TRUE(l == 2 || l == 4 || l == 8) << l;
  EXPECT_TRUE(res == 1 || res == 2) << res;
  ASSERT_EQ(a["results"].size(), 3u);  // bgk, bgk-ll and gdal linear
  EXPECT_EQ(a["results"][0]["method"], "bgk");
  EXPECT_EQ(a["results"][1]["method"], "bgk-ll");
  for (int k : {0, 1}) {
    const double rmse = a["results"][k]["rmse"];
    EXPECT_TRUE(std::isfinite(rmse));
    EXPECT_LT(rmse, 0.15);
    EXPECT_GT(a["results"][k]["coverage"].get<double>(), 0.99);
  }
  // Each BGK method chose its own parameters by its own cross-validation, on the training half.
  ASSERT_EQ(a["methods"].size(), 2u);
  EXPECT_EQ(a["methods"][0]["chosen"], a["chosen"]);
  EXPECT_EQ(a["methods"][1]["method"], "bgk-ll");
  EXPECT_EQ(a["methods"][1]["chosen"], b["methods"][1]["chosen"]);
  EXPECT_EQ(a["methods"][1]["cv"], b["methods"][1]["cv"]);
  fs::remove_all(dir);
}

// regress.json is JSON whatever the input: a path with a quote and a backslash is escaped, and a
// non-finite metric (the CV score of a candidate whose parameters do not validate: kernel length
// 1000 m at 2 m cells is more than 64 cells) is null. The hand-written JSON this replaced printed
// the path raw and the score as `inf`, so parsing failed (checked on afffdea).
TEST(RegressCommandTest, OutputIsJsonForAnyPathAndNonFiniteScores) {
  const fs::path dir =
      fs::temp_directory_path() / ("bgkmap_regress_json_" + std::to_string(getpid()));
  fs::remove_all(dir);
  const fs::path sub = dir / "quote\"back\\slash";
  fs::create_directories(sub);
  WritePcd(sub / "c.pcd", Cloud());
  const fs::path out = dir / "out";
  // Single quotes: the shell passes the path's " and \ through unchanged.
  const std::string cmd = std::string(BGKMAP_CLI) + " regress '" + (sub / "c.pcd").string() +
                          "' --out " + out.string() +
                          " --seed 3 --folds 2 --resolutions 2 --kernel-lengths 4,1000"
                          " --peers none > " +
                          (out.string() + ".log") + " 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(out / "regress.json");
  std::stringstream text;
  text << in.rdbuf();
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(text.str())) << text.str();
  EXPECT_EQ(j["input"], (sub / "c.pcd").string());
  ASSERT_EQ(j["cv"].size(), 2u);
  EXPECT_EQ(j["cv"][1]["kernel_length"], 1000.0);
  EXPECT_TRUE(j["cv"][1]["rmse"].is_null()) << j["cv"][1];
  EXPECT_EQ(j["cv"][1]["coverage"], 0.0);
  EXPECT_EQ(j["chosen"]["kernel_length"], 4.0);
  ASSERT_EQ(j["results"].size(), 2u);  // bgk and bgk-ll only (--peers none)
  EXPECT_TRUE(j["results"][0]["rmse"].is_number());
  // Same keys, in the order the hand-written file had (scripts and docs/results/ show them so).
  const nlohmann::ordered_json ordered = nlohmann::ordered_json::parse(text.str());
  std::vector<std::string> keys;
  for (const auto& [k, v] : ordered.items()) keys.push_back(k);
  EXPECT_EQ(keys, (std::vector<std::string>{"input", "points", "chosen", "train", "test", "seed",
                                            "folds", "cv_seconds", "cv", "results", "methods"}));
  fs::remove_all(dir);
}

}  // namespace
