// What bgkmapd exports on /metrics: a snapshot of the server's counters (CollectMetrics), written
// in the Prometheus text exposition format, version 0.0.4 (FormatMetrics). No HTTP here: the
// endpoint is metrics_http.{h,cc}.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "bgkmap/storage/tile_store.h"
#include "serving/correction_stats.h"
#include "serving/robot_registry.h"
#include "serving/tile_residency.h"

namespace bgkmap {

struct ServiceContext;

// The persistent store's side of a snapshot (present only with storage.data_dir).
struct StoreMetrics {
  uint64_t checkpoint_version = 0;
  uint64_t corrupt_tiles = 0;  // listed corrupt now (CorruptTiles())
  uint64_t dirty_tiles = 0;    // changed since the last checkpoint capture
  bool write_failed = false;
  bool writes_paused_for_space = false;  // below storage.min_free_space_mb, or read-only
  bool read_only = false;                // opened read-only on a full disk
  uint64_t free_bytes = 0;
  uint64_t reserve_bytes = 0;
  storage::StoreCounters counters;
  storage::DiskUsage usage;
  ResidencyStats residency;
  uint64_t memory_limit_bytes = 0;  // storage.max_memory_mb in bytes; 0 = unbounded
};

// One scrape's values. Taken field by field, not at one map version: each value is current
// when it is read.
struct ServerMetrics {
  std::string server_version;
  uint64_t map_version = 0;
  uint64_t scans_applied = 0;
  uint64_t tile_count = 0;
  uint64_t known_cells = 0;
  uint64_t ingest_streams = 0;
  uint64_t watchers = 0;
  std::vector<RobotProgress> robots;  // sorted by id
  std::optional<StoreMetrics> store;
  std::optional<uint64_t> process_resident_bytes;
  CorrectionStats corrections;
};

// Reads every value from the server's accessors. Locks nothing map-wide (the summary is kept
// incrementally); safe on any thread while the server runs.
ServerMetrics CollectMetrics(ServiceContext& ctx);

// The whole exposition: HELP and TYPE for every family, counters named *_total.
std::string FormatMetrics(const ServerMetrics& metrics);

// VmRSS of /proc/self/status in bytes; nullopt where it cannot be read.
std::optional<uint64_t> ProcessResidentBytes();

// Writes metric families in the Prometheus text format 0.0.4.
class ExpositionWriter {
 public:
  enum class Type { kCounter, kGauge };
  using Labels = std::vector<std::pair<std::string_view, std::string_view>>;

  // Starts a family: its "# HELP" and "# TYPE" lines. Samples that follow belong to it.
  void Family(std::string_view name, Type type, std::string_view help);
  // A sample of the current family; label values are escaped here.
  void Sample(uint64_t value, const Labels& labels = {});
  // A family with a single unlabelled sample.
  void Counter(std::string_view name, std::string_view help, uint64_t value);
  void Gauge(std::string_view name, std::string_view help, uint64_t value);

  const std::string& text() const { return out_; }

 private:
  std::string out_;
  std::string family_;
};

// A label value as the format quotes it: backslash, double quote and line feed escaped.
std::string EscapeLabelValue(std::string_view value);

}  // namespace bgkmap
