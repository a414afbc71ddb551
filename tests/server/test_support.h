// Shared helpers of the server tests: the real street scans, an in-process server on a loopback
// port, the offline reference map, and raster comparison.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/server/map_server.h"

namespace bgkmap::testing {

// A scan that owns its points; `Data()` views it for the client.
struct OwnedScan {
  std::string robot_id;
  uint64_t sequence = 0;
  ScanPose pose;
  std::vector<Point3f> points;
  ScanData Data() const;
};

// The three Ouster OS1-128 street scans of ../shared/data (poses as sent over the wire).
const std::vector<OwnedScan>& StreetScans();

// Splits each street scan into `parts` interleaved sub-scans (every parts-th point), numbered
// 1.. for `robot_id`: many realistic, overlapping scans from little data.
std::vector<OwnedScan> SubScans(const std::string& robot_id, int parts, size_t max_scans = 1000);

// The pose the server builds from a wire pose (normalised quaternion).
Pose WirePose(const ScanPose& pose);

// How a scan's points reach the server: as the client sends them by default (compact, without
// the points the map drops anyway: docs/server.md "Compact scans"), or as packed float32.
enum class Wire { kClientDefault, kFloat32 };

// The points the server integrates for `scan` sent over `wire` to a map of `params`, in the
// order it integrates them.
std::vector<Point3f> PointsAsIntegrated(const OwnedScan& scan, const MapParams& params,
                                        Wire wire = Wire::kClientDefault);

// An offline map of `scans` integrated in the given order with TerrainMap::IntegrateScan, each
// scan's points as the server integrates them after `wire`.
std::unique_ptr<TerrainMap> OfflineMap(const std::vector<const OwnedScan*>& scans,
                                       const MapParams& params = MapParams{},
                                       Wire wire = Wire::kClientDefault);

// A fresh directory under the system's temporary directory, removed with everything in it.
class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "bgkmap_test");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& str() const { return path_; }
  std::string Sub(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// A config for tests: loopback, port 0, two threads each.
ServerConfig TestConfig();

// MapServer in-process plus a connected client.
class ServerFixture {
 public:
  explicit ServerFixture(const ServerConfig& config = TestConfig());
  ~ServerFixture();
  MapServer& server() { return *server_; }
  Client& client() { return *client_; }
  std::string target() const;
  std::unique_ptr<Client> NewClient() const;

 private:
  std::unique_ptr<MapServer> server_;
  std::unique_ptr<Client> client_;
};

// Metric box of every known cell of `map`, padded by one tile.
MetricBox KnownBox(const TerrainMap& map);

// The region query `box` would produce from an offline map.
Raster OfflineRegion(const TerrainMap& map, const MetricBox& box, int stride = 1);

// Same geometry and every layer's floats the same bits (NaN payloads included).
bool BitwiseEqual(const Raster& a, const Raster& b);

// Same geometry, same known pixels, values within `tolerance` (absolute, or relative for values
// above 1). Reports at most a few mismatches.
::testing::AssertionResult RastersMatch(const Raster& served, const Raster& offline,
                                        double tolerance);

// Every tile's statistics equal (exact), and the same tiles exist with any content.
::testing::AssertionResult MapsEqual(const TerrainMap& a, const TerrainMap& b);

}  // namespace bgkmap::testing
