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

#include "bgkmap/server/latency_histogram.h"
#include "bgkmap/server/robot_stats.h"
#include "serving/map_port.h"

namespace bgkmap {

// What the server around the map adds to a scrape (the RPC side's open streams).
struct ServiceCounts {
  uint64_t ingest_streams = 0;
  uint64_t watchers = 0;
  const RequestLatencies* latencies = nullptr;  // the handlers' timings; null: none exported
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
  std::vector<RobotStats> robots;       // sorted by id
  std::optional<StorageState> store;    // with storage.data_dir
  std::optional<ResidencyStats> tiles;  // a single server's map
  uint64_t memory_limit_bytes = 0;      // storage.max_memory_mb in bytes; 0 = unbounded
  std::optional<uint64_t> process_resident_bytes;
  CorrectionStats corrections;
  // A shard of a cluster: records from NATS refused since start, by kind (ShardState::refused).
  std::optional<std::vector<std::pair<std::string, uint64_t>>> cluster_refused;
  std::optional<std::pair<uint64_t, uint64_t>> nats_received;       // bytes, messages (a shard)
  std::vector<std::pair<RequestPhase, LatencySnapshot>> latencies;  // in kRequestPhases order
};

// Reads every value from the map (MapPort::State) and `service`. Locks nothing map-wide (the
// summary is kept incrementally) and never waits on a remote; safe on any thread while the
// server runs.
ServerMetrics CollectMetrics(MapPort& map, const ServiceCounts& service,
                             uint64_t memory_limit_bytes);

// The whole exposition: HELP and TYPE for every family, counters named *_total.
std::string FormatMetrics(const ServerMetrics& metrics);

// VmRSS of /proc/self/status in bytes; nullopt where it cannot be read.
std::optional<uint64_t> ProcessResidentBytes();

// Writes metric families in the Prometheus text format 0.0.4.
class ExpositionWriter {
 public:
  enum class Type { kCounter, kGauge, kHistogram };
  using Labels = std::vector<std::pair<std::string_view, std::string_view>>;

  // Starts a family: its "# HELP" and "# TYPE" lines. Samples that follow belong to it.
  void Family(std::string_view name, Type type, std::string_view help);
  // A sample of the current family; label values are escaped here.
  void Sample(uint64_t value, const Labels& labels = {});
  // A family with a single unlabelled sample.
  void Counter(std::string_view name, std::string_view help, uint64_t value);
  void Gauge(std::string_view name, std::string_view help, uint64_t value);
  // The samples of one histogram of the current family (a kHistogram): its cumulative buckets
  // (`le` appended to `labels`), _sum and _count.
  void Histogram(const LatencySnapshot& snapshot, const Labels& labels);

  const std::string& text() const { return out_; }

 private:
  void Line(std::string_view suffix, const Labels& labels, std::string_view value);

  std::string out_;
  std::string family_;
};

// A label value as the format quotes it: backslash, double quote and line feed escaped.
std::string EscapeLabelValue(std::string_view value);

}  // namespace bgkmap
