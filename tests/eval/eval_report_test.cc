// eval.json (tools/bgkmap/eval_report.cc) is JSON for any dataset name and any score: strings
// escaped (a control character too), NaN and inf null, the keys and their order unchanged.
// Checked against the hand-written writer this replaced (afffdea): its quoting escaped only " and
// \, so a name with a newline or a tab made the file unparsable.
#include "eval_report.h"

#include <gtest/gtest.h>

#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace bgkmap::cli {
namespace {

std::vector<std::string> Keys(const nlohmann::ordered_json& j) {
  std::vector<std::string> keys;
  for (const auto& [k, v] : j.items()) keys.push_back(k);
  return keys;
}

TEST(EvalReportTest, JsonEscapesStringsAndWritesNonFiniteAsNull) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EvalReport r;
  r.name = "City \"A\"\\B\n\tC";
  r.sequence = "/data/seq \"1\"";
  MethodResult m;
  m.method = Method::kBgkPlus;
  m.scans = 12;
  m.skipped = 3;
  m.prepare_s = 0.25;
  m.max_scan_s = inf;
  m.realtime.truth_cells = 100;
  m.realtime.known_cells = 0;
  m.realtime.coverage = 0;
  m.realtime.mse_all = nan;
  m.realtime.roc.auc = nan;
  m.offline.mse_ground = -inf;
  m.offline.state_accuracy = 0.5;
  r.methods.push_back(m);

  const std::string text = ToJson(r);
  nlohmann::ordered_json j;
  ASSERT_NO_THROW(j = nlohmann::ordered_json::parse(text)) << text;
  EXPECT_EQ(j["dataset"], r.name);
  EXPECT_EQ(j["sequence"], r.sequence);
  EXPECT_EQ(Keys(j), (std::vector<std::string>{"dataset", "sequence", "rate_hz", "resolution",
                                               "kernel_length", "methods"}));
  ASSERT_EQ(j["methods"].size(), 1u);
  const auto& jm = j["methods"][0];
  EXPECT_EQ(Keys(jm),
            (std::vector<std::string>{
                "method", "scans", "skipped", "mean_prepare_s", "mean_elevation_s",
                "mean_features_s", "mean_traversability_s", "max_scan_s", "realtime", "offline"}));
  EXPECT_EQ(jm["method"], std::string(MethodName(Method::kBgkPlus)));
  EXPECT_EQ(jm["scans"], 12);
  EXPECT_EQ(jm["skipped"], 3);
  EXPECT_EQ(jm["mean_prepare_s"], 0.25);
  EXPECT_TRUE(jm["max_scan_s"].is_null());
  const std::vector<std::string> score_keys = {
      "truth_cells",      "known_cells",         "coverage",
      "mse_all_m2",       "mse_ground_m2",       "auc",
      "roc_positives",    "roc_negatives",       "state_accuracy",
      "dangerous_misses", "dangerous_miss_rate", "false_alarms",
      "false_alarm_rate"};
  EXPECT_EQ(Keys(jm["realtime"]), score_keys);
  EXPECT_EQ(Keys(jm["offline"]), score_keys);
  EXPECT_EQ(jm["realtime"]["truth_cells"], 100);
  EXPECT_TRUE(jm["realtime"]["mse_all_m2"].is_null());
  EXPECT_TRUE(jm["realtime"]["auc"].is_null());
  EXPECT_TRUE(jm["offline"]["mse_ground_m2"].is_null());
  EXPECT_EQ(jm["offline"]["state_accuracy"], 0.5);
}

}  // namespace
}  // namespace bgkmap::cli
