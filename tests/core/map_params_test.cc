#include "bgkmap/core/map_params.h"

#include <gtest/gtest.h>

#include "bgkmap/config/map_params_yaml.h"

namespace bgkmap {
namespace {

Result<MapParams> FromYaml(const std::string& text) { return MapParamsFromYaml(YAML::Load(text)); }

TEST(MapParamsTest, DefaultsAreValidAndMatchThePaperWhereItGivesValues) {
  const MapParams p;
  EXPECT_TRUE(p.Validate().ok()) << p.Validate().ToString();
  EXPECT_EQ(p.lambda, 0.0);
  EXPECT_EQ(p.alpha0, 0.001);
  EXPECT_EQ(p.beta0, 0.001);
  EXPECT_EQ(p.robot_radius, 0.3);
  EXPECT_EQ(p.method, Method::kBgkPlus);
}

TEST(MapParamsTest, EmptyYamlGivesDefaults) {
  Result<MapParams> p = FromYaml("");
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->resolution, MapParams{}.resolution);
}

TEST(MapParamsTest, ReadsEveryKey) {
  Result<MapParams> p = FromYaml(R"(
resolution: 0.2
kernel_length: 1.0
lambda: 0.1
prior_mean: -2
sigma2: 0.02
alpha0: 0.01
beta0: 0.02
robot_radius: 0.5
step_crit: 0.2
slope_crit_deg: 25
roughness_crit: 0.08
weights: [0.5, 0.3, 0.2]
trav_threshold: 0.4
variance_threshold: 0.1
min_range: 0.5
max_range: 80
max_height_above_sensor: 1.0
observation: mean
tile_size: 32
method: one-step
)");
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_EQ(p->resolution, 0.2);
  EXPECT_EQ(p->kernel_length, 1.0);
  EXPECT_EQ(p->prior_mean, -2.0);
  EXPECT_EQ(p->weights[1], 0.3);
  EXPECT_EQ(p->observation, Observation::kMean);
  EXPECT_EQ(p->tile_size, 32);
  EXPECT_EQ(p->method, Method::kOneStep);
  // And back: the emitted YAML parses to the same parameters.
  Result<MapParams> again = MapParamsFromYaml(MapParamsToYaml(*p));
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  std::string why;
  EXPECT_TRUE(again->StatisticsCompatibleWith(*p, &why)) << why;
  EXPECT_EQ(again->trav_threshold, 0.4);
}

struct BadCase {
  const char* yaml;
  const char* must_mention;
};

void PrintTo(const BadCase& c, std::ostream* os) { *os << c.yaml; }

class BadConfigTest : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadConfigTest, IsRejectedWithOneLineNamingTheKey) {
  Result<MapParams> p = FromYaml(GetParam().yaml);
  ASSERT_FALSE(p.ok()) << GetParam().yaml;
  const std::string msg = p.status().message();
  EXPECT_NE(msg.find(GetParam().must_mention), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadConfigTest,
    ::testing::Values(
        BadCase{"resolution: -0.1", "resolution"}, BadCase{"resolution: 0", "resolution"},
        BadCase{"resolution: .nan", "resolution"}, BadCase{"resolution: abc", "resolution"},
        BadCase{"kernel_length: 0.05", "kernel_length"},
        BadCase{"kernel_length: 100", "kernel_length"}, BadCase{"lambda: -1", "lambda"},
        BadCase{"sigma2: 0", "sigma2"}, BadCase{"alpha0: 0", "alpha0"},
        BadCase{"robot_radius: 0.01", "robot_radius"},
        BadCase{"weights: [0.5, 0.5, 0.5]", "sum to 1"}, BadCase{"weights: [1, 0]", "weights"},
        BadCase{"weights: [1.2, -0.2, 0]", "weights"},
        BadCase{"trav_threshold: 1.5", "trav_threshold"},
        BadCase{"variance_threshold: -1", "variance_threshold"},
        BadCase{"min_range: 5\nmax_range: 2", "max_range"}, BadCase{"tile_size: 3", "tile_size"},
        BadCase{"tile_size: 64.5", "tile_size"}, BadCase{"observation: median", "observation"},
        BadCase{"method: bgk", "method"}, BadCase{"slope_crit_deg: 120", "slope_crit_deg"},
        BadCase{"resoluton: 0.1", "unknown key 'resoluton'"}, BadCase{"[1, 2]", "top level"}),
    [](const ::testing::TestParamInfo<BadCase>& param_info) {
      std::string name;
      for (const char* c = param_info.param.yaml; *c && *c != ':' && *c != ' '; ++c) {
        name += std::isalnum(static_cast<unsigned char>(*c)) ? *c : '_';
      }
      return name + "_" + std::to_string(param_info.index);
    });

TEST(MapParamsTest, OtherSectionsAreLeftToTheirOwners) {
  Result<MapParams> p =
      MapParamsFromYaml(YAML::Load("resolution: 0.2\nserver: {port: 1}"), {"server"});
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  EXPECT_FALSE(FromYaml("resolution: 0.2\nserver: {port: 1}").ok());
}

TEST(MapParamsTest, CompatibilityNamesTheDifference) {
  MapParams a, b;
  b.kernel_length = 0.5;
  std::string why;
  EXPECT_FALSE(a.StatisticsCompatibleWith(b, &why));
  EXPECT_NE(why.find("kernel_length"), std::string::npos);
  b = a;
  b.trav_threshold = 0.3;  // only affects derived layers
  EXPECT_TRUE(a.StatisticsCompatibleWith(b, &why));
}

TEST(MapParamsTest, MissingFileIsAnError) {
  Result<MapParams> p = LoadMapParamsFile("/nonexistent/bgkmap.yaml");
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.status().message().find("/nonexistent/bgkmap.yaml"), std::string::npos);
}

}  // namespace
}  // namespace bgkmap

namespace bgkmap {
namespace {

TEST(MapParamsTest, ShippedDefaultConfigEqualsTheBuiltInDefaults) {
  Result<MapParams> p = LoadMapParamsFile(std::string(BGKMAP_SOURCE_DIR) + "/config/default.yaml");
  ASSERT_TRUE(p.ok()) << p.status().ToString();
  const YAML::Node shipped = MapParamsToYaml(*p), builtin = MapParamsToYaml(MapParams{});
  EXPECT_EQ(YAML::Dump(shipped), YAML::Dump(builtin));
}

}  // namespace
}  // namespace bgkmap

namespace bgkmap {
namespace {

TEST(MapParamsTest, EmitsShortestRoundTripNumbers) {
  MapParams p;
  p.prior_mean = 1.0 / 3.0;
  const std::string text = YAML::Dump(MapParamsToYaml(p));
  EXPECT_NE(text.find("resolution: 0.1\n"), std::string::npos) << text;
  Result<MapParams> back = MapParamsFromYaml(YAML::Load(text));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->prior_mean, p.prior_mean);  // exact, not merely close
}

}  // namespace
}  // namespace bgkmap

namespace bgkmap {
namespace {

TEST(MapParamsTest, NoConfigPathMeansDefaultsAndABadPathIsAnError) {
  Result<MapParams> none = LoadMapParamsFileOrDefaults("");
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(YAML::Dump(MapParamsToYaml(*none)), YAML::Dump(MapParamsToYaml(MapParams{})));
  EXPECT_FALSE(LoadMapParamsFileOrDefaults("/nonexistent/bgkmap.yaml").ok());
}

}  // namespace
}  // namespace bgkmap
