// The map as the handlers (rpc/, http/) see it: one port, two implementations, the way LevelDB's
// DB hides DBImpl.
//   - ServedMap (serving/served_map.h): the single server's map, in memory or on a store;
//   - cluster::ClusterNode (cluster/cluster_node.h): a shard of a cluster, whose changes go to
//     the cluster's log and whose reads gather tiles from the partitions' owners.
// A handler calls the port and never asks which one it has: what one of them cannot do yet
// answers Unimplemented (MapWrites::Offers), and what only one of them has (a store, a shard's
// partitions) is an optional part of MapState. The wiring (map_server.cc) builds one of them.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/georeference.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/server/robot_stats.h"
#include "serving/correction_stats.h"
#include "serving/map_reads.h"
#include "serving/map_summary.h"
#include "serving/map_writes.h"
#include "serving/residency_stats.h"

namespace bgkmap {

// A map on a store: its state for Info and /metrics.
struct StorageState {
  std::string directory;
  std::string durability;  // "sync" | "periodic"
  uint64_t checkpoint_version = 0;
  uint64_t corrupt_tiles = 0;  // listed as failing their checksum now
  uint64_t dirty_tiles = 0;    // changed since the last checkpoint was captured
  bool write_failed = false;
  // Writes are refused for lack of space: below storage.min_free_space_mb, or opened read-only
  // on a full disk (then `read_only` too). Reads are served; writes resume when there is room.
  bool writes_paused_for_space = false;
  bool read_only = false;
  uint64_t free_bytes = 0;     // on the data dir's file system, as last probed
  uint64_t reserve_bytes = 0;  // storage.min_free_space_mb
  std::string paused_reason;   // why writes are paused ("" when they are not)
  struct Counters {            // since the store was opened
    uint64_t tiles_loaded = 0;
    uint64_t tiles_written = 0;
    uint64_t tiles_deleted = 0;
    uint64_t checkpoints = 0;
    uint64_t corrupt_tiles = 0;        // distinct tiles found corrupt
    uint64_t corrupt_log_records = 0;  // log records found corrupt
    uint64_t log_records_appended = 0;
    uint64_t log_bytes_appended = 0;
    uint64_t write_errors = 0;              // failed appends and checkpoints
    uint64_t writes_refused_for_space = 0;  // refused before they were tried
  } counters;
  struct DiskUsage {             // only when asked for: it lists the store's directory
    uint64_t tile_bytes = 0;     // SST files of the tiles column family
    uint64_t log_bytes = 0;      // SST files of the log column family
    uint64_t sources_bytes = 0;  // SST files of the retained raw scans
    uint64_t history_bytes = 0;  // SST files of the retained tile history
    uint64_t wal_bytes = 0;      // write-ahead log files
    uint64_t total_bytes = 0;    // every file in the store's directory (WAL included)
  } usage;
  ResidencyStats residency;
};

// A shard of a cluster: its place in the cluster for Info (docs/scale-out.md).
struct ShardState {
  std::string node;
  std::vector<std::string> live_nodes;
  uint64_t partitions_known = 0;
  uint32_t partition_tiles = 0;
  struct Partition {  // one this node serves or is catching up
    std::string name;
    uint64_t log_sequence = 0;
    uint64_t scans_integrated = 0;
    uint64_t tiles = 0;
    bool serving = false;
    uint64_t restored_from = 0;
  };
  std::vector<Partition> owned;
  // Records read from NATS and refused since start (no valid cluster-key HMAC), by kind
  // ("log_entry", "tile_reply", "membership", "checkpoint"): docs/scale-out.md, "Trust".
  std::vector<std::pair<std::string, uint64_t>> refused;
  uint32_t region_partitions = 0;  // cluster.region_partitions (0: payloads in the log)
  // What this shard's NATS connection received since start: the log (and, with regions, its
  // regions' payloads), tile fetches and replies, membership.
  uint64_t nats_received_bytes = 0;
  uint64_t nats_received_messages = 0;
};

// What Info and /metrics report. Read field by field, not at one map version.
struct MapState {
  uint64_t version = 0;  // known_version()
  uint64_t scans_applied = 0;
  MapSummary summary;              // (a cluster node: the cluster's, as of its last ReadVersion)
  std::vector<RobotStats> robots;  // sorted by id
  CorrectionStats corrections;
  Georeference georeference;            // where the map frame sits (empty: a local frame)
  std::optional<StorageState> storage;  // a map on a store
  std::optional<ResidencyStats> tiles;  // a single server's map (in memory or on a store)
  std::optional<ShardState> shard;      // a shard of a cluster
};

class MapPort : public MapReads, public MapWrites {
 public:
  virtual const MapParams& params() const = 0;
  virtual const GridGeometry& geometry() const = 0;

  // The newest version this server knows without asking anyone: a single server's applied
  // version; a cluster node's log sequence as of its last question to the log.
  virtual uint64_t known_version() const = 0;
  // The robots known (sorted by id): cheap, no map-wide work.
  virtual std::vector<RobotStats> Robots() const = 0;
  // Counts, robots, the store and the shard; never waits on a remote (the summary recounts the
  // tiles changed since the last read). `with_disk_usage` lists the store's directory.
  virtual MapState State(bool with_disk_usage = false) = 0;
  // Calls `done` with applied_version(): at once on this thread when it is at hand, or on a
  // worker when it must be asked for (a cluster's log), so a caller never waits on a remote.
  virtual void ReadVersion(std::function<void(uint64_t)> done) = 0;

 protected:
  ~MapPort() = default;
};

}  // namespace bgkmap
