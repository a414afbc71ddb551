#include "bgkmap/storage/map_metadata.h"

#include <gtest/gtest.h>

namespace bgkmap::storage {
namespace {

MapParams Unusual() {
  MapParams p;
  p.resolution = 0.1 + 1e-17;  // not representable in short decimal: must survive exactly
  p.kernel_length = 0.35;
  p.lambda = 0.5;
  p.prior_mean = -3.25;
  p.weights = {0.1, 0.7, 0.2};
  p.observation = Observation::kMean;
  p.method = Method::kOneStep;
  p.tile_size = 32;
  p.max_height_above_sensor = -0.25;
  return p;
}

TEST(MapMetadataTest, ParamsRoundTripExactlyThroughKeyValues) {
  const MapParams p = Unusual();
  std::map<std::string, std::string, std::less<>> kv;
  for (auto& [k, v] : ParamsToKeyValues(p)) kv[k] = v;
  EXPECT_EQ(kv.size(), MapParamKeys().size());
  Result<MapParams> back = ParamsFromKeyValues(kv);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->resolution, p.resolution);
  EXPECT_EQ(back->weights, p.weights);
  EXPECT_EQ(back->method, p.method);
  EXPECT_EQ(back->observation, p.observation);
  EXPECT_EQ(back->tile_size, p.tile_size);
  EXPECT_EQ(back->max_height_above_sensor, p.max_height_above_sensor);
  std::string why;
  EXPECT_TRUE(back->StatisticsCompatibleWith(p, &why)) << why;
}

TEST(MapMetadataTest, MissingOrBadKeyIsNamed) {
  std::map<std::string, std::string, std::less<>> kv;
  for (auto& [k, v] : ParamsToKeyValues(MapParams{})) kv[k] = v;
  auto missing = kv;
  missing.erase("kernel_length");
  EXPECT_NE(ParamsFromKeyValues(missing).status().message().find("kernel_length"),
            std::string::npos);
  auto bad = kv;
  bad["weights"] = "0.5,0.5";
  EXPECT_NE(ParamsFromKeyValues(bad).status().message().find("weights"), std::string::npos);
}

TEST(MapMetadataTest, IncompatibleParamsAreRefusedNamingTheKey) {
  MapParams stored;
  MapParams requested = stored;
  requested.kernel_length = 0.4;
  const Status s = CheckParamsCompatible(stored, requested);
  EXPECT_EQ(s.code(), Status::Code::kFailedPrecondition);
  EXPECT_NE(s.message().find("kernel_length"), std::string::npos) << s.message();

  requested = stored;
  requested.sigma2 = 0.5;  // only enters derived layers
  requested.trav_threshold = 0.3;
  EXPECT_TRUE(CheckParamsCompatible(stored, requested).ok());
}

TEST(MapMetadataTest, WholeMetadataRoundTrips) {
  MapMetadata m;
  m.params = Unusual();
  m.checkpoint_version = 17;
  m.map_version = 21;
  m.robot_sequences = {{"a", 3}, {"robot/b", 1ull << 40}};
  Result<MapMetadata> back = DecodeMetadata(EncodeMetadata(m));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->checkpoint_version, 17u);
  EXPECT_EQ(back->map_version, 21u);
  EXPECT_EQ(back->robot_sequences, m.robot_sequences);
  EXPECT_EQ(back->params.prior_mean, m.params.prior_mean);
}

TEST(MapMetadataTest, GeoreferenceRoundTripsAndOlderBuildsSkipIt) {
  MapMetadata m;
  m.params = Unusual();
  m.georeference = {"PROJCS[\"x\", GEOGCS[\"y\"]]", {0.1 + 0.2, -4180000.25, 1e-9}};
  const std::string bytes = EncodeMetadata(m);
  Result<MapMetadata> back = DecodeMetadata(bytes);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->georeference, m.georeference);  // bit-exact origin
  // A build before georeferences reads the pairs with ParamsFromKeyValues alone, which
  // ignores keys it does not know: its archives and ours stay readable both ways.
  std::map<std::string, std::string, std::less<>> kv;
  for (const auto& [k, v] : ParamsToKeyValues(m.params)) kv.emplace(k, v);
  kv.emplace("georeference/crs", "EPSG:32610");
  kv.emplace("georeference/origin", "1,2,3");
  EXPECT_TRUE(ParamsFromKeyValues(kv).ok());
  // Without one: no georeference pairs at all, as before.
  m.georeference = {};
  EXPECT_EQ(EncodeMetadata(m).find("georeference"), std::string::npos);
  EXPECT_TRUE(DecodeMetadata(EncodeMetadata(m))->georeference.empty());
}

TEST(MapMetadataTest, MalformedGeoreferenceIsDataLossNamingTheKey) {
  Result<Georeference> g = GeoreferenceFromKeyValues({{"crs", "EPSG:4326"}, {"origin", "1,2"}});
  ASSERT_FALSE(g.ok());
  EXPECT_EQ(g.status().code(), Status::Code::kDataLoss);
  EXPECT_NE(g.status().message().find("georeference.origin"), std::string::npos);
  g = GeoreferenceFromKeyValues({{"origin", "1,2,3"}});
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.status().message().find("georeference.crs"), std::string::npos);
}

TEST(MapMetadataTest, GeoreferencesDifferOnlyWhenBothAreSet) {
  const Georeference utm{"EPSG:32610", {1, 2, 3}};
  EXPECT_TRUE(CheckGeoreferenceCompatible({}, utm).ok());
  EXPECT_TRUE(CheckGeoreferenceCompatible(utm, {}).ok());
  EXPECT_TRUE(CheckGeoreferenceCompatible(utm, utm).ok());
  Status s = CheckGeoreferenceCompatible(utm, {"EPSG:32610", {1, 2, 4}});
  EXPECT_EQ(s.code(), Status::Code::kFailedPrecondition);
  EXPECT_EQ(s.message().rfind("georeference.origin differs: [1,2,3] vs [1,2,4]", 0), 0u)
      << s.message();
}

}  // namespace
}  // namespace bgkmap::storage
