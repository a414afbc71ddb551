#include "bgkmap/core/map_param_table.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "bgkmap/config/map_params_yaml.h"
#include "support/non_default_params.h"

namespace bgkmap {
namespace {

using testing_support::DifferingKeys;
using testing_support::KeysAtDefault;
using testing_support::NonDefaultParams;

TEST(MapParamTableTest, ListsEveryKeyOnceInMapParamKeysOrder) {
  const auto table = MapParamTable();
  ASSERT_EQ(table.size(), MapParamKeys().size());
  std::set<std::string_view> seen;
  for (size_t i = 0; i < table.size(); ++i) {
    EXPECT_EQ(table[i].key, MapParamKeys()[i]);
    EXPECT_TRUE(seen.insert(table[i].key).second) << table[i].key << " is listed twice";
    EXPECT_EQ(FindMapParam(table[i].key), &table[i]);
    EXPECT_FALSE(table[i].doc.empty()) << table[i].key;
  }
  EXPECT_EQ(FindMapParam("resoluton"), nullptr);
}

TEST(MapParamTableTest, EachEntryHasTheFieldOfItsKindOnly) {
  for (const MapParamInfo& info : MapParamTable()) {
    const int fields = (info.real != nullptr) + (info.integer != nullptr) +
                       (info.triple != nullptr) + (info.enum_name != nullptr);
    EXPECT_EQ(fields, 1) << info.key;
    switch (info.kind) {
      case MapParamKind::kDouble:
        EXPECT_NE(info.real, nullptr) << info.key;
        break;
      case MapParamKind::kInt:
        EXPECT_NE(info.integer, nullptr) << info.key;
        break;
      case MapParamKind::kDouble3:
        EXPECT_NE(info.triple, nullptr) << info.key;
        break;
      case MapParamKind::kEnum:
        EXPECT_NE(info.enum_name, nullptr) << info.key;
        EXPECT_NE(info.enum_parse, nullptr) << info.key;
        break;
    }
  }
}

TEST(MapParamTableTest, TheSampleIsValidAndSetsEveryKey) {
  const MapParams p = NonDefaultParams();
  EXPECT_TRUE(p.Validate().ok()) << p.Validate().ToString();
  EXPECT_EQ(KeysAtDefault(p), "");
}

TEST(MapParamTableTest, YamlRoundTripsEveryKey) {
  const MapParams p = NonDefaultParams();
  const std::string text = YAML::Dump(MapParamsToYaml(p));
  Result<MapParams> back = MapParamsFromYaml(YAML::Load(text));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(DifferingKeys(*back, p), "") << text;
  for (const MapParamInfo& info : MapParamTable()) {
    EXPECT_NE(text.find(std::string(info.key) + ": "), std::string::npos) << info.key;
  }
}

TEST(MapParamTableTest, EveryRuleRejectsNaNNamingItsKey) {
  for (const MapParamInfo& info : MapParamTable()) {
    if (info.check == nullptr || info.kind == MapParamKind::kInt ||
        info.kind == MapParamKind::kEnum) {
      continue;
    }
    MapParams p;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    if (info.kind == MapParamKind::kDouble) p.*info.real = nan;
    if (info.kind == MapParamKind::kDouble3) (p.*info.triple)[1] = nan;
    const Status s = p.Validate();
    EXPECT_FALSE(s.ok()) << info.key;
    EXPECT_EQ(s.message().rfind(std::string(info.key) + " = ", 0), 0u) << s.message();
  }
}

TEST(MapParamTableTest, CompatibilityComparesExactlyTheStatisticsShapingKeys) {
  const MapParams sample = NonDefaultParams();
  for (const MapParamInfo& info : MapParamTable()) {
    MapParams other = sample;
    // Copy the default of this one key over the sample.
    const MapParams defaults;
    switch (info.kind) {
      case MapParamKind::kDouble:
        other.*info.real = defaults.*info.real;
        break;
      case MapParamKind::kInt:
        other.*info.integer = defaults.*info.integer;
        break;
      case MapParamKind::kDouble3:
        other.*info.triple = defaults.*info.triple;
        break;
      case MapParamKind::kEnum:
        ASSERT_TRUE(info.enum_parse(info.enum_name(defaults), other).ok()) << info.key;
        break;
    }
    ASSERT_EQ(DifferingKeys(other, sample), info.key);
    std::string why;
    EXPECT_EQ(sample.StatisticsCompatibleWith(other, &why), !info.shapes_statistics) << info.key;
    if (info.shapes_statistics) {
      EXPECT_EQ(why.rfind(std::string(info.key), 0), 0u) << why;
    }
  }
}

}  // namespace
}  // namespace bgkmap
