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
  for (std::string_view key : MapParamKeys()) {
    auto missing = kv;
    missing.erase(std::string(key));
    const Status s = ParamsFromKeyValues(missing).status();
    EXPECT_EQ(s.code(), Status::Code::kDataLoss) << key;
    EXPECT_NE(s.message().find(std::string(key) + " is missing"), std::string::npos) << s.message();
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
