// Stored map parameters over the whole parameter table.
#include <gtest/gtest.h>

#include <algorithm>

#include "bgkmap/storage/map_metadata.h"
#include "support/non_default_params.h"

namespace bgkmap::storage {
namespace {

using testing_support::DifferingKeys;
using testing_support::KeysAtDefault;
using testing_support::NonDefaultParams;

// Existing stores and archives hold these keys: each must still be written (and so read).
TEST(MapMetadataTableTest, StoredKeysAreTheFormatContract) {
  const std::vector<std::string_view> stored = {"resolution",
                                                "kernel_length",
                                                "lambda",
                                                "prior_mean",
                                                "sigma2",
                                                "alpha0",
                                                "beta0",
                                                "robot_radius",
                                                "step_crit",
                                                "slope_crit_deg",
                                                "roughness_crit",
                                                "weights",
                                                "trav_threshold",
                                                "variance_threshold",
                                                "min_range",
                                                "max_range",
                                                "max_height_above_sensor",
                                                "observation",
                                                "tile_size",
                                                "method"};
  std::vector<std::string> written;
  for (const auto& [key, value] : ParamsToKeyValues(MapParams{})) written.push_back(key);
  for (std::string_view key : stored) {
    EXPECT_NE(std::find(written.begin(), written.end(), key), written.end()) << key;
  }
}

TEST(MapMetadataTableTest, KeyValuesRoundTripEveryKey) {
  const MapParams p = NonDefaultParams();
  ASSERT_EQ(KeysAtDefault(p), "");
  std::map<std::string, std::string, std::less<>> kv;
  const auto pairs = ParamsToKeyValues(p);
  ASSERT_EQ(pairs.size(), MapParamKeys().size());
  for (size_t i = 0; i < pairs.size(); ++i) {
    EXPECT_EQ(pairs[i].first, MapParamKeys()[i]);
    kv.emplace(pairs[i]);
  }
  Result<MapParams> back = ParamsFromKeyValues(kv);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(DifferingKeys(*back, p), "");
}

TEST(MapMetadataTableTest, EveryMissingKeyIsNamed) {
  std::map<std::string, std::string, std::less<>> kv;
  for (auto& [k, v] : ParamsToKeyValues(NonDefaultParams())) kv[k] = v;
  for (const MapParamInfo& info : MapParamTable()) {
    auto missing = kv;
    missing.erase(std::string(info.key));
    const Result<MapParams> p = ParamsFromKeyValues(missing);
    if (!info.legacy_text.empty()) {
      // A key added later: a store written before it was built with its legacy value.
      ASSERT_TRUE(p.ok()) << info.key << ": " << p.status().ToString();
      MapParams legacy = NonDefaultParams();
      ASSERT_TRUE(info.kind != MapParamKind::kEnum ||
                  info.enum_parse(info.legacy_text, legacy).ok());
      if (info.kind == MapParamKind::kDouble)
        legacy.*info.real = std::stod(std::string(info.legacy_text));
      EXPECT_TRUE(info.Equal(*p, legacy)) << info.key;
      continue;
    }
    const Status s = p.status();
    EXPECT_EQ(s.code(), Status::Code::kDataLoss) << info.key;
    EXPECT_NE(s.message().find(std::string(info.key) + " is missing"), std::string::npos)
        << s.message();
  }
}

// Stores written before dynamics existed were built with it off; the other new keys' legacy
// values are their defaults, so such a store continues with `dynamics: off` and nothing else.
TEST(MapMetadataTableTest, LegacyValuesAreOffAndTheDefaults) {
  const MapParams defaults;
  for (const MapParamInfo& info : MapParamTable()) {
    if (info.legacy_text.empty()) continue;
    MapParams p = defaults;
    if (info.kind == MapParamKind::kEnum) {
      ASSERT_TRUE(info.enum_parse(info.legacy_text, p).ok()) << info.key;
      EXPECT_EQ(info.key, "dynamics");
      EXPECT_EQ(p.dynamics, Dynamics::kOff);
    } else {
      ASSERT_EQ(info.kind, MapParamKind::kDouble) << info.key;
      EXPECT_EQ(std::stod(std::string(info.legacy_text)), defaults.*info.real) << info.key;
    }
  }
}

TEST(MapMetadataTableTest, WholeMetadataRoundTripsEveryKey) {
  MapMetadata m;
  m.params = NonDefaultParams();
  Result<MapMetadata> back = DecodeMetadata(EncodeMetadata(m));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(DifferingKeys(back->params, m.params), "");
}

}  // namespace
}  // namespace bgkmap::storage
