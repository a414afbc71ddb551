#include "http/metrics.h"

#include <cstdio>
#include <fstream>
#include <sstream>

namespace bgkmap {
namespace {

using Type = ExpositionWriter::Type;

void WriteRobots(const std::vector<RobotStats>& robots, ExpositionWriter& w) {
  struct PerRobot {
    const char* name;
    Type type;
    const char* help;
    uint64_t RobotStats::*value;
  };
  static constexpr PerRobot kPerRobot[] = {
      {"bgkmap_robot_scans_applied_total", Type::kCounter,
       "Scans of the robot integrated into the map since start.", &RobotStats::scans_applied},
      {"bgkmap_robot_scans_duplicate_total", Type::kCounter,
       "Scans of the robot acknowledged as duplicates (sequence number not above the last) since "
       "start.",
       &RobotStats::scans_duplicate},
      {"bgkmap_robot_scans_rejected_total", Type::kCounter,
       "Scans of the robot rejected (bad input, limits, storage failure) since start.",
       &RobotStats::scans_rejected},
      {"bgkmap_robot_points_kept_total", Type::kCounter,
       "Points of the robot's applied scans that were integrated (after filtering) since start.",
       &RobotStats::points_kept},
      {"bgkmap_robot_last_sequence", Type::kGauge,
       "The robot's last admitted sequence number (kept across restarts with a store).",
       &RobotStats::last_sequence},
  };
  for (const PerRobot& m : kPerRobot) {
    w.Family(m.name, m.type, m.help);
    for (const RobotStats& r : robots) w.Sample(r.*m.value, {{"robot", r.robot_id}});
  }
}

void WriteStore(const StorageState& s, uint64_t memory_limit_bytes, ExpositionWriter& w) {
  w.Gauge("bgkmap_store_checkpoint_version",
          "Map version of the last written checkpoint (every change up to it is in the stored "
          "tiles).",
          s.checkpoint_version);
  w.Gauge("bgkmap_store_corrupt_tiles",
          "Stored tiles currently listed as failing their checksum (until a checkpoint rewrites "
          "them).",
          s.corrupt_tiles);
  w.Gauge("bgkmap_store_dirty_tiles", "Tiles changed since the last checkpoint was captured.",
          s.dirty_tiles);
  w.Gauge("bgkmap_store_write_failed",
          "1 while the store refuses writes after a failed append or checkpoint, else 0.",
          s.write_failed ? 1 : 0);
  w.Gauge("bgkmap_store_writes_paused_for_space",
          "1 while writes are refused because the data dir has less free space than "
          "storage.min_free_space_mb (reads are answered; writes resume when there is room).",
          s.writes_paused_for_space ? 1 : 0);
  w.Gauge("bgkmap_store_read_only",
          "1 while the store is open read-only (it was opened on a full disk), else 0.",
          s.read_only ? 1 : 0);
  w.Gauge("bgkmap_store_free_bytes",
          "Free space on the data dir's file system, as last probed (for the reserve).",
          s.free_bytes);
  w.Gauge("bgkmap_store_free_space_reserve_bytes",
          "storage.min_free_space_mb in bytes: writes are refused below it.", s.reserve_bytes);
  const StorageState::Counters& c = s.counters;
  w.Counter("bgkmap_store_tiles_loaded_total", "Tiles read from the store since it was opened.",
            c.tiles_loaded);
  w.Counter("bgkmap_store_tiles_written_total", "Tiles written by checkpoints since open.",
            c.tiles_written);
  w.Counter("bgkmap_store_tiles_deleted_total", "Tiles deleted by checkpoints since open.",
            c.tiles_deleted);
  w.Counter("bgkmap_store_checkpoints_total", "Checkpoints written since open.", c.checkpoints);
  w.Counter("bgkmap_store_corrupt_tiles_found_total",
            "Distinct stored tiles found failing their checksum since open.", c.corrupt_tiles);
  w.Counter("bgkmap_store_corrupt_log_records_total",
            "Scan log records found failing their checksum since open.", c.corrupt_log_records);
  w.Counter("bgkmap_store_log_records_appended_total",
            "Changes (scans, clears) appended to the scan log since open.", c.log_records_appended);
  w.Counter("bgkmap_store_log_appended_bytes_total", "Bytes appended to the scan log since open.",
            c.log_bytes_appended);
  w.Counter("bgkmap_store_write_errors_total",
            "Failed scan log appends and checkpoints since open.", c.write_errors);
  w.Counter("bgkmap_store_writes_refused_for_space_total",
            "Writes refused before they were tried, for lack of free space, since the store was "
            "last opened.",
            c.writes_refused_for_space);
  w.Gauge("bgkmap_store_tile_sst_bytes", "Size of the tile column family's SST files.",
          s.usage.tile_bytes);
  w.Gauge("bgkmap_store_log_sst_bytes", "Size of the scan log column family's SST files.",
          s.usage.log_bytes);
  w.Gauge("bgkmap_store_sources_sst_bytes",
          "Size of the retained raw scans' SST files (storage.retention_mb).",
          s.usage.sources_bytes);
  w.Gauge("bgkmap_store_history_sst_bytes",
          "Size of the retained tile history's SST files (storage.retention_mb).",
          s.usage.history_bytes);
  w.Gauge("bgkmap_store_wal_bytes", "Size of the store's write-ahead log files.",
          s.usage.wal_bytes);
  w.Gauge("bgkmap_store_disk_bytes",
          "Size of every file in the store's directory (write-ahead log included).",
          s.usage.total_bytes);
  w.Gauge("bgkmap_map_resident_tiles", "Tiles held in memory.", s.residency.resident_tiles);
  w.Gauge("bgkmap_map_resident_bytes", "Memory of the tiles held in memory.",
          s.residency.resident_bytes);
  w.Counter("bgkmap_map_tiles_loaded_total",
            "Tiles loaded into memory from the store on demand since start.",
            s.residency.tiles_loaded);
  w.Counter("bgkmap_map_tiles_evicted_total",
            "Clean tiles dropped from memory under storage.max_memory_mb since start.",
            s.residency.tiles_evicted);
  w.Gauge("bgkmap_map_memory_limit_bytes",
          "storage.max_memory_mb in bytes: bound on tiles in memory plus checkpoint copies (0: "
          "unbounded).",
          memory_limit_bytes);
}

}  // namespace

ServerMetrics CollectMetrics(MapPort& map, const ServiceCounts& service,
                             uint64_t memory_limit_bytes) {
  MapState state = map.State(/*with_disk_usage=*/true);
  ServerMetrics m;
  m.server_version = BGKMAP_VERSION;
  m.map_version = state.version;
  m.scans_applied = state.scans_applied;
  m.tile_count = state.summary.tile_count;
  m.known_cells = state.summary.known_cells;
  m.ingest_streams = service.ingest_streams;
  m.watchers = service.watchers;
  m.robots = std::move(state.robots);
  m.store = std::move(state.storage);
  m.tiles = state.tiles;
  m.memory_limit_bytes = memory_limit_bytes;
  m.process_resident_bytes = ProcessResidentBytes();
  m.corrections = state.corrections;
  if (service.latencies != nullptr) {
    for (RequestPhase phase : kRequestPhases) {
      m.latencies.emplace_back(phase, service.latencies->of(phase).Snapshot());
    }
  }
  if (state.shard) {
    m.cluster_refused = state.shard->refused;
    m.nats_received =
        std::pair(state.shard->nats_received_bytes, state.shard->nats_received_messages);
  }
  return m;
}

std::string FormatMetrics(const ServerMetrics& m) {
  ExpositionWriter w;
  w.Family("bgkmap_build_info", Type::kGauge, "Always 1; the label is the bgkmapd version.");
  w.Sample(1, {{"version", m.server_version}});
  w.Gauge("bgkmap_map_version",
          "The applied map version: every change (scan, clear, import) up to it is in the map.",
          m.map_version);
  w.Counter("bgkmap_scans_applied_total", "Scans integrated into the map since start.",
            m.scans_applied);
  w.Gauge("bgkmap_map_tiles", "Tiles of the map (in memory or in the store).", m.tile_count);
  w.Gauge("bgkmap_map_known_cells", "Cells of the map with an observation.", m.known_cells);
  if (m.tiles) {
    w.Gauge("bgkmap_map_tile_memory_bytes",
            "Memory of the tiles in memory, each in its form (dense, or packed beyond "
            "storage.dense_tiles_mb).",
            m.tiles->resident_bytes);
    w.Gauge("bgkmap_map_packed_tiles", "Tiles in memory held packed (storage.dense_tiles_mb).",
            m.tiles->packed_tiles);
    w.Counter("bgkmap_map_tiles_packed_total",
              "Tiles packed under storage.dense_tiles_mb since start.", m.tiles->tiles_packed);
  }
  w.Gauge("bgkmap_ingest_streams", "Open Ingest streams.", m.ingest_streams);
  w.Gauge("bgkmap_watchers", "Open Watch streams.", m.watchers);
  w.Gauge("bgkmap_robots", "Robots the server has seen (or recovered from the store).",
          m.robots.size());
  WriteRobots(m.robots, w);
  const CorrectionStats& c = m.corrections;
  w.Gauge("bgkmap_corrections_in_progress",
          "Pose corrections and scan removals being re-integrated now.", c.in_progress);
  w.Counter("bgkmap_corrections_applied_total", "Pose corrections and removals switched in.",
            c.applied);
  w.Counter("bgkmap_corrections_failed_total", "Pose corrections and removals refused.", c.failed);
  w.Counter("bgkmap_correction_scans_revised_total", "Scans corrected or removed.",
            c.scans_revised);
  w.Counter("bgkmap_correction_records_replayed_total", "Log records re-integrated by corrections.",
            c.records_replayed);
  w.Gauge("bgkmap_correction_last_seconds", "Duration of the last correction, request to switch.",
          c.last_seconds);
  if (m.store) WriteStore(*m.store, m.memory_limit_bytes, w);
  if (m.cluster_refused) {
    w.Family("bgkmap_cluster_rejected_total", Type::kCounter,
             "Records read from NATS refused since start because their cluster-key HMAC does not "
             "verify (docs/scale-out.md, Trust), by kind.");
    for (const auto& [kind, count] : *m.cluster_refused) w.Sample(count, {{"kind", kind}});
  }
  if (m.nats_received) {
    w.Counter("bgkmap_cluster_nats_received_bytes_total",
              "Bytes this shard's NATS connection received since start: the log (with "
              "cluster.region_partitions, its own regions' payloads only), tile fetches, "
              "membership.",
              m.nats_received->first);
    w.Counter("bgkmap_cluster_nats_received_messages_total",
              "Messages this shard's NATS connection received since start.",
              m.nats_received->second);
  }
  if (!m.latencies.empty()) {
    w.Family("bgkmap_request_phase_seconds", Type::kHistogram,
             "Time of requests' phases since start, by phase: region_read (a region query's "
             "request to its raster: queue, tile locks, extraction), region_stream (its raster "
             "to the last chunk the client took), points and check_path (request to answer, "
             "without the transfer), scan (received to acknowledged).");
    for (const auto& [phase, snapshot] : m.latencies) {
      w.Histogram(snapshot, {{"phase", RequestPhaseName(phase)}});
    }
  }
  if (m.process_resident_bytes) {
    w.Gauge("process_resident_memory_bytes", "Resident memory of the bgkmapd process (VmRSS).",
            *m.process_resident_bytes);
  }
  return w.text();
}

std::optional<uint64_t> ProcessResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) != 0) continue;
    std::istringstream fields(line.substr(6));
    uint64_t kib = 0;
    std::string unit;
    if (fields >> kib >> unit && unit == "kB") return kib * 1024;
    return std::nullopt;
  }
  return std::nullopt;
}

void ExpositionWriter::Family(std::string_view name, Type type, std::string_view help) {
  family_ = name;
  out_ += "# HELP ";
  out_ += name;
  out_ += ' ';
  for (char c : help) {  // HELP escapes backslash and line feed
    if (c == '\\') {
      out_ += "\\\\";
    } else if (c == '\n') {
      out_ += "\\n";
    } else {
      out_ += c;
    }
  }
  out_ += "\n# TYPE ";
  out_ += name;
  out_ += type == Type::kCounter ? " counter\n"
          : type == Type::kGauge ? " gauge\n"
                                 : " histogram\n";
}

void ExpositionWriter::Sample(uint64_t value, const Labels& labels) {
  Line("", labels, std::to_string(value));
}

void ExpositionWriter::Histogram(const LatencySnapshot& snapshot, const Labels& labels) {
  Labels with_le = labels;
  with_le.emplace_back("le", "");
  for (size_t i = 0; i < snapshot.cumulative.size(); ++i) {
    // The bounds in %g (six significant digits: exact for 0.0005 ... 10); +Inf last.
    char bound[32] = "+Inf";
    if (i < kLatencyBucketBounds.size()) {
      std::snprintf(bound, sizeof bound, "%g", kLatencyBucketBounds[i]);
    }
    with_le.back().second = bound;
    Line("_bucket", with_le, std::to_string(snapshot.cumulative[i]));
  }
  char sum[32];
  std::snprintf(sum, sizeof sum, "%.9f", snapshot.sum_seconds);
  Line("_sum", labels, sum);
  Line("_count", labels, std::to_string(snapshot.count));
}

void ExpositionWriter::Line(std::string_view suffix, const Labels& labels, std::string_view value) {
  out_ += family_;
  out_ += suffix;
  if (!labels.empty()) {
    out_ += '{';
    for (size_t i = 0; i < labels.size(); ++i) {
      if (i > 0) out_ += ',';
      out_ += labels[i].first;
      out_ += "=\"";
      out_ += EscapeLabelValue(labels[i].second);
      out_ += '"';
    }
    out_ += '}';
  }
  out_ += ' ';
  out_ += value;
  out_ += '\n';
}

void ExpositionWriter::Counter(std::string_view name, std::string_view help, uint64_t value) {
  Family(name, Type::kCounter, help);
  Sample(value);
}

void ExpositionWriter::Gauge(std::string_view name, std::string_view help, uint64_t value) {
  Family(name, Type::kGauge, help);
  Sample(value);
}

std::string EscapeLabelValue(std::string_view value) {
  std::string out;
  out.reserve(value.size());
  for (char c : value) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace bgkmap
