// Writes the seed corpora of the fuzz targets (fuzz/corpus/<target>/) from the real code paths:
// tiles and log records the storage encoders made from a real street scan, a map archive
// ExportMap wrote, a scan request as a robot sends it, a slice of the ALS LAS tile, PCD clouds
// of street points, an OctoMap scan graph octomap itself wrote. Run by scripts/fuzz.sh --seeds:
//   make_fuzz_seeds <corpus dir> <shared data dir>
#include <octomap/ScanGraph.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/proto/compact_points.h"
#include "bgkmap/proto/scan_codec.h"
#include "bgkmap/storage/log_record.h"
#include "bgkmap/storage/map_archive.h"
#include "bgkmap/storage/tile_codec.h"
#include "bgkmap/v1/ingest.pb.h"
#include "bgkmap/v1/query.pb.h"

namespace {

namespace fs = std::filesystem;
using namespace bgkmap;

std::string corpus;

void Put(const std::string& target, const std::string& name, const std::string& bytes) {
  fs::create_directories(corpus + "/" + target);
  std::ofstream(corpus + "/" + target + "/" + name, std::ios::binary) << bytes;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

template <typename T>
T Must(Result<T> r) {
  if (!r.ok()) {
    std::cerr << "make_fuzz_seeds: " << r.status().message() << "\n";
    std::exit(1);
  }
  return std::move(r).value();
}

// Every `step`-th point of the scan.
std::vector<Point3f> Every(const std::vector<Point3f>& points, size_t step) {
  std::vector<Point3f> out;
  for (size_t i = 0; i < points.size(); i += step) out.push_back(points[i]);
  return out;
}

// Small tiles (8 cells of 0.1 m) keep the encodings, and so the seeds, small.
MapParams SmallTileParams() {
  MapParams p;
  p.tile_size = 8;
  return p;
}

// The compact point target's layout: step, count, order, the zstd frame.
void CompactPointSeeds(const io::Scan& scan) {
  const std::vector<Point3f> points = Every(scan.points, 200);
  const std::pair<PointOrder, const char*> orders[] = {
      {PointOrder::kScanOrder, "street_scan_order"},
      {PointOrder::kSpatialSort, "street_sorted"},
      {PointOrder::kScanRay, "street_scan_ray"}};
  for (const auto& [order, name] : orders) {
    const CompactPoints c = Must(EncodeCompactPoints(points, kDefaultCompactStep, nullptr, order));
    std::string bytes(13, '\0');
    std::memcpy(bytes.data(), &c.step, 8);
    std::memcpy(bytes.data() + 8, &c.count, 4);
    bytes[12] = static_cast<char>(c.order);
    Put("compact_points", name, bytes + c.data);
  }
}

void ScanRequestSeeds(const io::Scan& scan) {
  v1::Scan msg;
  msg.set_robot_id("alpha");
  msg.set_sequence(1);
  const Eigen::Quaterniond q(scan.pose.rotation);
  auto* pose = msg.mutable_pose();
  pose->mutable_translation()->set_x(scan.pose.translation.x());
  pose->mutable_translation()->set_y(scan.pose.translation.y());
  pose->mutable_translation()->set_z(scan.pose.translation.z());
  pose->mutable_rotation()->set_w(q.w());
  pose->mutable_rotation()->set_x(q.x());
  pose->mutable_rotation()->set_y(q.y());
  pose->mutable_rotation()->set_z(q.z());
  const std::vector<Point3f> points = Every(scan.points, 400);
  msg.set_points(
      std::string(reinterpret_cast<const char*>(points.data()), points.size() * sizeof(Point3f)));
  Put("scan_request", "street_scan", std::string(1, '\0') + msg.SerializeAsString());
  msg.clear_points();
  Put("scan_request", "no_points", std::string(1, '\0') + msg.SerializeAsString());
  ToProto(Must(EncodeCompactPoints(points, kDefaultCompactStep)), msg.mutable_compact_points());
  Put("scan_request", "street_scan_compact", std::string(1, '\0') + msg.SerializeAsString());

  v1::RegionRequest region;
  region.mutable_box()->set_min_x(-10);
  region.mutable_box()->set_min_y(-10.05);
  region.mutable_box()->set_max_x(20);
  region.mutable_box()->set_max_y(5);
  region.set_stride(4);
  region.add_layers(v1::LAYER_ELEVATION);
  region.add_layers(v1::LAYER_TRAVERSABILITY);
  Put("scan_request", "region", std::string(1, '\1') + region.SerializeAsString());
}

void StorageSeeds(const io::Scan& scan) {
  const MapParams params = SmallTileParams();
  auto map = Must(TerrainMap::Create(params));
  const std::vector<Point3f> points = Every(scan.points, 200);
  Must(map->IntegrateScan(points, scan.pose));

  // Tiles: the fullest and the emptiest, in each layout.
  const Tile* full = nullptr;
  const Tile* sparse = nullptr;
  int full_n = -1, sparse_n = 1 << 30;
  map->ForEachTile([&](TileKey, const Tile& tile) {
    int n = 0;
    for (int i = 0; i < tile.cell_count(); ++i) n += tile.w()[i] != 0;
    if (n > full_n) full_n = n, full = &tile;
    if (n > 0 && n < sparse_n) sparse_n = n, sparse = &tile;
  });
  for (int flags = 0; flags < 4; ++flags) {
    const storage::TileEncodeOptions options{.shuffle = (flags & 1) != 0, .xor_delta = flags >= 2};
    // The targets' first byte: tile size 8 << 0.
    Put("tile_codec", "full_" + std::to_string(flags),
        std::string(1, '\0') + storage::EncodeTile(*full, options));
    Put("tile_codec", "sparse_" + std::to_string(flags),
        std::string(1, '\0') + storage::EncodeTile(*sparse, options));
  }

  // A bgk-ll tile (plane moments, tile format 4); first byte: tile size 8 << 0, bit 3 = planes.
  MapParams ll_params = params;
  ll_params.method = Method::kBgkLocalLinear;
  auto ll_map = Must(TerrainMap::Create(ll_params));
  Must(ll_map->IntegrateScan(points, scan.pose));
  const Tile* ll_full = nullptr;
  int ll_n = -1;
  ll_map->ForEachTile([&](TileKey, const Tile& tile) {
    int n = 0;
    for (int i = 0; i < tile.cell_count(); ++i) n += tile.w()[i] != 0;
    if (n > ll_n) ll_n = n, ll_full = &tile;
  });
  Put("tile_codec", "plane_full", std::string(1, '\x08') + storage::EncodeTile(*ll_full));

  // Log records: a scan as the server logs it, and a clear.
  const std::vector<Point3f> few = Every(scan.points, 1000);
  auto prepared = std::make_shared<const PreparedScan>(Must(PrepareScan(params, few, scan.pose)));
  Put("log_record", "scan",
      storage::EncodeLogRecord(storage::LogRecord::Scan(7, "alpha", 3, prepared, 123456789)));
  storage::LogRecord retained = storage::LogRecord::Scan(9, "alpha", 4, prepared, 123456790);
  retained.cells_in_source = true;  // as logged beside its raw scan (format 4)
  retained.cells_crc = storage::LoggedCellsCrc(*prepared);
  Put("log_record", "scan_cells_in_source", storage::EncodeLogRecord(retained));
  Put("log_record", "clear",
      storage::EncodeLogRecord(storage::LogRecord::Clear(8, CellBox{{-5, -6}, {40, 2}})));

  // Archives: a map of the few points above (a few kB) and an empty one.
  auto small = Must(TerrainMap::Create(params));
  Must(small->IntegrateScan(Every(few, 8), scan.pose));
  storage::MapMetadata meta;
  meta.params = params;
  meta.map_version = meta.checkpoint_version = small->version();
  meta.robot_sequences = {{"alpha", 1}};
  const std::string tmp = fs::temp_directory_path() / "bgkmap-seed.bgkmap";
  if (!storage::ExportMap(*small, meta, tmp).ok()) std::exit(1);
  Put("map_archive", "street_map", ReadFile(tmp));
  auto empty = Must(TerrainMap::Create(params));
  if (!storage::ExportMap(*empty, storage::MapMetadata{.params = params}, tmp).ok()) std::exit(1);
  Put("map_archive", "empty_map", ReadFile(tmp));
  fs::remove(tmp);
}

// The header and VLRs of the ALS tile and its first points, the point counts patched.
void LasSeeds(const std::string& data) {
  const std::string las = ReadFile(data + "/als_topography/topography.las");
  uint32_t offset;
  uint16_t record;
  std::memcpy(&offset, las.data() + 96, 4);
  std::memcpy(&record, las.data() + 105, 2);
  for (uint32_t points : {0u, 1u, 24u}) {
    std::string slice = las.substr(0, offset + size_t{points} * record);
    std::memcpy(slice.data() + 107, &points, 4);
    Put("las_reader", "als_" + std::to_string(points) + "_points", slice);
  }
}

void PcdSeeds(const io::Scan& scan) {
  const std::vector<Point3f> points = Every(scan.points, 2000);
  std::ostringstream head;
  head << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z intensity\n"
       << "SIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH " << points.size()
       << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << points.size() << "\n";
  std::ostringstream ascii;
  ascii << head.str() << "DATA ascii\n";
  std::string binary = head.str() + "DATA binary\n";
  for (const Point3f& p : points) {
    ascii << p.x << " " << p.y << " " << p.z << " 7\n";
    const float rec[4] = {p.x, p.y, p.z, 7.0f};
    binary.append(reinterpret_cast<const char*>(rec), sizeof(rec));
  }
  Put("pcd_reader", "street_ascii", ascii.str());
  Put("pcd_reader", "street_binary", binary);
  Put("pcd_reader", "organised_double",
      "VERSION .7\nFIELDS rgb z y x\nSIZE 4 8 8 8\nTYPE U F F F\nCOUNT 1 1 1 1\nWIDTH 2\n"
      "HEIGHT 2\nDATA ascii\n1 1 2 3\n2 nan nan nan\n3 4 5 6\n4 -1 -2 -3\n");
}

void GraphSeeds(const io::Scan& scan) {
  const std::vector<Point3f> points = Every(scan.points, 4000);
  octomap::ScanGraph graph;
  for (int k = 0; k < 2; ++k) {
    auto* cloud = new octomap::Pointcloud();  // the graph owns it
    for (const Point3f& p : points) cloud->push_back(p.x, p.y, p.z);
    graph.addNode(cloud, octomap::pose6d(k, 0.5 * k, 1.2, 0, 0, 0.3 * k));
  }
  graph.addEdge(0, 1);
  const std::string tmp = fs::temp_directory_path() / "bgkmap-seed.graph";
  if (!graph.writeBinary(tmp)) std::exit(1);
  Put("scan_graph", "two_street_scans", ReadFile(tmp));
  fs::remove(tmp);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: make_fuzz_seeds <corpus dir> <shared data dir>\n";
    return 2;
  }
  corpus = argv[1];
  const std::string data = argv[2];
  const io::KittiSequence street = Must(io::KittiSequence::Open(data + "/ouster_os1_128_street"));
  const io::Scan scan = Must(street.Read(1));
  ScanRequestSeeds(scan);
  CompactPointSeeds(scan);
  StorageSeeds(scan);
  LasSeeds(data);
  PcdSeeds(scan);
  GraphSeeds(scan);
  return 0;
}
