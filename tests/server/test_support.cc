#include "test_support.h"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "bgkmap/core/point_filter.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/proto/compact_points.h"

namespace bgkmap::testing {

ScanData OwnedScan::Data() const {
  ScanData d;
  d.robot_id = robot_id;
  d.sequence = sequence;
  d.pose = pose;
  d.points = points;
  return d;
}

const std::vector<OwnedScan>& StreetScans() {
  static const std::vector<OwnedScan> scans = [] {
    std::vector<OwnedScan> out;
    const std::string dir = std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";
    Result<io::KittiSequence> seq = io::KittiSequence::Open(dir);
    if (!seq.ok()) {
      ADD_FAILURE() << "cannot open " << dir << ": " << seq.status().ToString();
      return out;
    }
    for (size_t k = 0; k < seq->size(); ++k) {
      Result<io::Scan> scan = seq->Read(k);
      if (!scan.ok()) {
        ADD_FAILURE() << scan.status().ToString();
        return out;
      }
      OwnedScan s;
      s.robot_id = "street";
      s.sequence = k + 1;
      s.pose = ScanPose::FromPose(scan->pose);
      s.points = std::move(scan->points);
      out.push_back(std::move(s));
    }
    return out;
  }();
  return scans;
}

std::vector<OwnedScan> SubScans(const std::string& robot_id, int parts, size_t max_scans) {
  std::vector<OwnedScan> out;
  for (const OwnedScan& full : StreetScans()) {
    for (int p = 0; p < parts && out.size() < max_scans; ++p) {
      OwnedScan s;
      s.robot_id = robot_id;
      s.sequence = out.size() + 1;
      s.pose = full.pose;
      for (size_t i = static_cast<size_t>(p); i < full.points.size();
           i += static_cast<size_t>(parts)) {
        s.points.push_back(full.points[i]);
      }
      out.push_back(std::move(s));
    }
  }
  return out;
}

Pose WirePose(const ScanPose& p) {
  const double n = std::sqrt(p.qw * p.qw + p.qx * p.qx + p.qy * p.qy + p.qz * p.qz);
  return Pose::FromQuaternion(p.qw / n, p.qx / n, p.qy / n, p.qz / n, p.tx, p.ty, p.tz);
}

std::vector<Point3f> PointsAsIntegrated(const OwnedScan& scan, const MapParams& params, Wire wire) {
  if (wire == Wire::kFloat32) return scan.points;
  // The client's steps, written out independently: quantize, drop what the map's range filter
  // drops by the dequantized point (the height filter is left to the server), encode, and the
  // server's decode.
  const Pose pose = WirePose(scan.pose);
  std::vector<Point3f> kept;
  for (const Point3f& p : scan.points) {
    QuantizedPoint q;
    if (!QuantizePoint(p, kDefaultCompactStep, &q)) continue;
    const PointFilter fate =
        FilterSensorPoint(params, pose, DequantizePoint(q, kDefaultCompactStep));
    if (fate == PointFilter::kKept || fate == PointFilter::kHeight) {
      kept.push_back(p);
    }
  }
  Result<CompactPoints> compact = EncodeCompactPoints(kept, kDefaultCompactStep);
  EXPECT_TRUE(compact.ok());
  Result<std::vector<Point3f>> decoded = DecodeCompactPoints(*compact, kept.size());
  EXPECT_TRUE(decoded.ok());
  return decoded.ok() ? std::move(decoded).value() : std::vector<Point3f>();
}

std::unique_ptr<TerrainMap> OfflineMap(const std::vector<const OwnedScan*>& scans,
                                       const MapParams& params, Wire wire) {
  std::unique_ptr<TerrainMap> map = std::move(TerrainMap::Create(params)).value();
  for (const OwnedScan* s : scans) {
    Result<ScanReport> r =
        map->IntegrateScan(PointsAsIntegrated(*s, params, wire), WirePose(s->pose));
    EXPECT_TRUE(r.ok()) << r.status().ToString();
  }
  return map;
}

TempDir::TempDir(const std::string& prefix) {
  static std::atomic<int> counter{0};
  const std::filesystem::path p =
      std::filesystem::temp_directory_path() /
      (prefix + "_" + std::to_string(getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  path_ = p.string();
}

TempDir::~TempDir() {
  std::error_code ignored;
  std::filesystem::remove_all(path_, ignored);
}

ServerConfig TestConfig() {
  ServerConfig c;
  c.listen_address = "127.0.0.1:0";
  c.worker_threads = 2;
  c.query_threads = 2;
  c.shutdown_timeout_s = 20;
  return c;
}

ServerFixture::ServerFixture(const ServerConfig& config) {
  Result<std::unique_ptr<MapServer>> s = MapServer::Start(config);
  if (!s.ok()) {
    ADD_FAILURE() << s.status().ToString();
    return;
  }
  server_ = std::move(s).value();
  client_ = NewClient();
  EXPECT_TRUE(client_->WaitForConnected(std::chrono::seconds(10)));
}

ServerFixture::~ServerFixture() {
  client_.reset();
  if (server_) server_->Shutdown();
}

std::string ServerFixture::target() const { return "127.0.0.1:" + std::to_string(server_->port()); }

std::unique_ptr<Client> ServerFixture::NewClient() const {
  return std::make_unique<Client>(target());
}

MetricBox KnownBox(const TerrainMap& map) {
  const CellBox b = map.KnownBounds();
  const double r = map.params().resolution;
  const double pad = map.params().tile_size * r;
  return {b.min.x * r - pad, b.min.y * r - pad, (b.max.x + 1) * r + pad, (b.max.y + 1) * r + pad};
}

Raster OfflineRegion(const TerrainMap& map, const MetricBox& box, int stride) {
  // The server's region rule: cells meeting [min, max), widened to stride multiples aligned with
  // the global grid.
  const double r = map.params().resolution;
  auto lo = [&](double v) { return static_cast<int64_t>(std::floor(v / r + 1e-6)); };
  auto hi = [&](double v) { return static_cast<int64_t>(std::ceil(v / r - 1e-6)) - 1; };
  auto floor_to = [stride](int64_t a) {
    return (a >= 0 ? a / stride : -((-a + stride - 1) / stride)) * stride;
  };
  CellBox cells;
  cells.min = {static_cast<int>(floor_to(lo(box.min_x))),
               static_cast<int>(floor_to(lo(box.min_y)))};
  cells.max = {static_cast<int>(floor_to(std::max(lo(box.min_x), hi(box.max_x))) + stride - 1),
               static_cast<int>(floor_to(std::max(lo(box.min_y), hi(box.max_y))) + stride - 1)};
  std::vector<Layer> all;
  for (int i = 0; i < kLayerCount; ++i) all.push_back(static_cast<Layer>(i));
  return ExtractRaster(map, cells, all, stride);
}

bool BitwiseEqual(const Raster& a, const Raster& b) {
  if (a.cols != b.cols || a.rows != b.rows || a.data.size() != b.data.size()) return false;
  for (size_t i = 0; i < a.data.size(); ++i) {
    if (a.data[i].size() != b.data[i].size()) return false;
    if (std::memcmp(a.data[i].data(), b.data[i].data(), a.data[i].size() * sizeof(float)) != 0) {
      return false;
    }
  }
  return true;
}

::testing::AssertionResult RastersMatch(const Raster& a, const Raster& b, double tolerance) {
  if (!(a.box == b.box) || a.stride != b.stride || a.cols != b.cols || a.rows != b.rows ||
      a.layers != b.layers) {
    return ::testing::AssertionFailure()
           << "geometry differs: " << a.cols << "x" << a.rows << " vs " << b.cols << "x" << b.rows
           << " stride " << a.stride << " vs " << b.stride;
  }
  if (std::abs(a.x0 - b.x0) > 1e-9 || std::abs(a.y1 - b.y1) > 1e-9) {
    return ::testing::AssertionFailure() << "origin differs";
  }
  int reported = 0;
  size_t mismatches = 0;
  std::ostringstream out;
  for (size_t l = 0; l < a.layers.size(); ++l) {
    for (size_t i = 0; i < a.data[l].size(); ++i) {
      const float x = a.data[l][i], y = b.data[l][i];
      const bool same = (std::isnan(x) && std::isnan(y)) ||
                        (!std::isnan(x) && !std::isnan(y) &&
                         std::abs(x - y) <= tolerance * std::max(1.0f, std::abs(y)));
      if (!same) {
        ++mismatches;
        if (reported++ < 5) {
          out << "\n  layer " << LayerName(a.layers[l]) << " pixel " << i << ": " << x << " vs "
              << y;
        }
      }
    }
  }
  if (mismatches > 0) {
    return ::testing::AssertionFailure() << mismatches << " values differ" << out.str();
  }
  return ::testing::AssertionSuccess();
}

::testing::AssertionResult MapsEqual(const TerrainMap& a, const TerrainMap& b) {
  size_t differing = 0, missing = 0;
  a.ForEachTile([&](TileKey k, const Tile& t) {
    const Tile* o = b.FindTile(k);
    if (o == nullptr) {
      missing += t.Empty() ? 0 : 1;
    } else if (!(t == *o)) {
      ++differing;
    }
  });
  b.ForEachTile([&](TileKey k, const Tile& t) {
    if (a.FindTile(k) == nullptr && !t.Empty()) ++missing;
  });
  if (differing + missing == 0) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << differing << " tiles differ, " << missing << " non-empty tiles only in one map";
}

}  // namespace bgkmap::testing
