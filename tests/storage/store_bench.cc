// Measures the store on the real street scans (docs/storage.md, "Measured"): bytes per known
// cell on disk for each tile layout and compression, log record size, and log append throughput
// with sync vs periodic durability. Not a test; run by hand:
//   store_bench [SCAN_DIR] [APPENDS] [ZSTD_LEVEL] [HALF_LIFE_S]
// With HALF_LIFE_S > 0 the map forgets, its scans stamped 1 s apart (tiles carry stamps).
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

#include "bgkmap/io/kitti_sequence.h"
#include "bgkmap/storage/recovery.h"
#include "bgkmap/storage/tile_store.h"
#include "store_test_util.h"

namespace st = bgkmap::storage;
using bgkmap::MapParams;
using bgkmap::PreparedScan;
using bgkmap::TerrainMap;
using bgkmap::Tile;
using bgkmap::TileKey;

namespace {

const char* CompressionName(st::TileCompression c) {
  switch (c) {
    case st::TileCompression::kNone:
      return "none";
    case st::TileCompression::kLz4:
      return "lz4";
    case st::TileCompression::kZstd:
      return "zstd";
  }
  return "?";
}

void MeasureTiles(const TerrainMap& map, int zstd_level) {
  const double known = static_cast<double>(map.CountKnownCells());
  std::printf("map: %zu tiles, %.0f known cells (%.1f%% fill), %.1f bytes/known cell in memory\n",
              map.tile_count(), known,
              100.0 * known / (map.tile_count() * map.params().tile_size * map.params().tile_size),
              map.TileMemoryBytes() / known);
  std::printf("%-8s %-7s %-6s %12s %12s %12s\n", "shuffle", "xor", "codec", "encoded B/c",
              "tile SST B/c", "dir B/c");
  std::vector<st::TileUpdate> updates;
  map.ForEachTile([&](TileKey k, const Tile& t) { updates.push_back({k, &t}); });
  for (auto compression :
       {st::TileCompression::kNone, st::TileCompression::kLz4, st::TileCompression::kZstd}) {
    for (bool shuffle : {false, true}) {
      for (bool xor_delta : {false, true}) {
        st::testing::TempDir dir;
        st::StoreOptions options;
        options.tile_compression = compression;
        options.tile_encoding = {shuffle, xor_delta};
        options.zstd_level = zstd_level;
        auto store = std::move(st::TileStore::Open(dir.path(), options, map.params())).value();
        if (!store->Checkpoint(map.version(), updates).ok()) std::abort();
        if (!store->Compact().ok()) std::abort();
        uint64_t encoded = 0;
        const auto listed = store->ListTiles();
        for (const auto& info : *listed) encoded += info.encoded_bytes;
        const st::DiskUsage usage = store->Usage();
        std::printf("%-8s %-7s %-6s %12.2f %12.2f %12.2f\n", shuffle ? "yes" : "no",
                    xor_delta ? "yes" : "no", CompressionName(compression), encoded / known,
                    usage.tile_bytes / known, usage.total_bytes / known);
        // The stored map must read back bitwise.
        auto back = st::testing::NewMap(map.params());
        if (!st::LoadAllTiles(*store, *back).ok()) std::abort();
        back->set_version(map.version());
        if (!st::testing::MapsIdentical(map, *back)) std::abort();
      }
    }
  }
}

void MeasureAppends(const std::vector<std::shared_ptr<const PreparedScan>>& scans,
                    const MapParams& params, int appends) {
  uint64_t cells = 0, bytes = 0;
  for (const auto& s : scans) {
    cells += s->cells.size();
    bytes += st::EncodeLogRecord(st::LogRecord::Scan(1, "robot", 1, s)).size();
  }
  std::printf("\nlog record: %.0f observed cells/scan, %.0f bytes/scan, %.2f bytes/cell\n",
              double(cells) / scans.size(), double(bytes) / scans.size(), double(bytes) / cells);
  std::printf("%-9s %-8s %10s %10s\n", "mode", "threads", "scans/s", "MB/s");
  for (auto durability : {st::Durability::kSync, st::Durability::kPeriodic}) {
    for (int threads : {1, 4, 16}) {
      st::testing::TempDir dir;
      st::StoreOptions options;
      options.durability = durability;
      auto store = std::move(st::TileStore::Open(dir.path(), options, params)).value();
      std::atomic<uint64_t> next{0};
      const auto start = std::chrono::steady_clock::now();
      std::vector<std::thread> pool;
      for (int t = 0; t < threads; ++t) {
        pool.emplace_back([&, t] {
          for (uint64_t v; (v = ++next) <= static_cast<uint64_t>(appends);) {
            const auto& scan = scans[v % scans.size()];
            if (!store->log()
                     .Append(st::LogRecord::Scan(v, "robot-" + std::to_string(t), v, scan))
                     .ok()) {
              std::abort();
            }
          }
        });
      }
      for (auto& t : pool) t.join();
      const double s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("%-9s %-8d %10.0f %10.1f\n", std::string(st::DurabilityName(durability)).c_str(),
                  threads, appends / s, store->log().bytes_appended() / s / 1e6);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir =
      argc > 1 ? argv[1] : std::string(BGKMAP_SHARED_DATA) + "/ouster_os1_128_street";
  const int appends = argc > 2 ? std::atoi(argv[2]) : 600;
  auto sequence = bgkmap::io::KittiSequence::Open(dir);
  if (!sequence.ok()) {
    std::fprintf(stderr, "%s\n", sequence.status().ToString().c_str());
    return 1;
  }
  MapParams params;  // the defaults: 0.1 m cells, 64-cell tiles, bgk+
  params.half_life_s = argc > 4 ? std::atof(argv[4]) : 0.0;
  auto map = st::testing::NewMap(params);
  std::vector<std::shared_ptr<const PreparedScan>> scans;
  for (size_t k = 0; k < sequence->size(); ++k) {
    auto scan = sequence->Read(k);
    if (!scan.ok()) return 1;
    const int64_t stamp = params.half_life_s > 0 ? static_cast<int64_t>(k + 1) * 1'000'000'000 : 0;
    if (!map->IntegrateScan(scan->points, scan->pose, false, stamp).ok()) return 1;
    scans.push_back(std::make_shared<const PreparedScan>(
        std::move(bgkmap::PrepareScan(params, scan->points, scan->pose)).value()));
  }
  std::printf("%s: %zu scans, half_life_s %g\n", dir.c_str(), sequence->size(), params.half_life_s);
  const int zstd_level = argc > 3 ? std::atoi(argv[3]) : 3;
  std::printf("zstd level %d\n", zstd_level);
  MeasureTiles(*map, zstd_level);
  MeasureAppends(scans, params, appends);
  return 0;
}
