// bgkmap::Client: the C++ client of bgkmapd (bgkmap.v1.MapService). Synchronous calls that hide
// the protocol: scans go in as points and poses, regions come back as bgkmap::Raster.
//
//   bgkmap::Client client("127.0.0.1:50051");
//   auto stream = client.OpenIngest();
//   stream->Send(scan);                      // blocks while the server's read-ahead is full
//   bgkmap::ScanAck ack; stream->ReadAck(&ack);
//   auto raster = client.QueryRegion({{-50, -50, 50, 50}, {bgkmap::Layer::kElevation}});
//
// A Client is thread-safe: any number of threads may call it at once.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/client/rpc_status.h"
#include "bgkmap/core/cell_estimate.h"
#include "bgkmap/core/georeference.h"
#include "bgkmap/core/grid.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/core/path_check.h"
#include "bgkmap/core/path_sweep.h"
#include "bgkmap/core/raster.h"
#include "bgkmap/core/scan.h"

namespace bgkmap {

struct ClientOptions {
  // Deadline of each unary call and region query (0 = none).
  std::chrono::milliseconds timeout{60'000};
  // Largest message accepted from the server.
  int max_message_bytes = 64 << 20;
  // TLS: the CA certificates (PEM text, not a path) the server's certificate must chain to;
  // "" = plaintext.
  std::string tls_ca_pem;
  // Mutual TLS: this client's certificate chain and private key (PEM text).
  std::string tls_cert_pem;
  std::string tls_key_pem;
  // The name the server certificate must carry when it is not the target's host ("" = host).
  std::string tls_server_name;
  // Sent on every call as "authorization: Bearer <token>" (server.auth.tokens_file); "" = none.
  std::string token;
  // Scans go out compact (docs/server.md "Compact scans"): quantized in the sensor frame to this
  // step (metres, in (0, 0.01]), then zstd; the map is that of the dequantized points. 0 sends
  // packed float32, 12 bytes a point.
  double compact_step = 0.002;
  // Before sending, drop the points the map drops anyway whatever the pose: non-finite ones and
  // those outside [min_range, max_range] (the map's, read once by Info; without the right to call
  // Info, only non-finite ones). Acks count them as if they had been sent.
  bool drop_filtered_points = true;
  // Also drop the points above max_height_above_sensor under the pose sent. Off by default: a
  // later pose correction re-prepares the retained points with the new pose, and may keep some
  // of these (docs/server.md "Compact scans").
  bool drop_points_above_sensor = false;
  // An ingest stream encodes its scans on this many threads of its own, while earlier scans are
  // on the wire, and writes them in the order sent (Send() copies the points and returns once the
  // scan is queued). 0: each scan is encoded in Send(), on the caller's thread, then written.
  int ingest_encode_threads = 2;
  // ... with at most this many scans queued or being written; Send() blocks while they are.
  int ingest_encode_ahead = 4;
};

// A rectangle in the map frame, metres; regions cover the cells meeting [min, max).
struct MetricBox {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;
};

// Sensor pose in the map frame: translation and unit quaternion.
struct ScanPose {
  double tx = 0, ty = 0, tz = 0;
  double qw = 1, qx = 0, qy = 0, qz = 0;
  static ScanPose FromPose(const Pose& pose);  // rotation matrix -> quaternion
};

// One scan to send; `points` (sensor frame) must stay valid during the call.
struct ScanData {
  std::string robot_id;
  uint64_t sequence = 0;
  int64_t stamp_ns = 0;  // since the Unix epoch; the scan's map time (forgetting ages by it)
  ScanPose pose;
  std::span<const Point3f> points;
};

enum class AckStatus { kApplied, kDuplicate, kRejected };

struct ScanAck {
  std::string robot_id;
  uint64_t sequence = 0;
  AckStatus status = AckStatus::kRejected;
  RpcStatus error;  // why a scan was rejected (ok otherwise)
  std::vector<TileKey> changed_tiles;
  uint64_t map_version = 0;
  ScanPointCounts counts;
};

// A robot's scan stream. Send() and ReadAck() may run on two different threads.
class IngestStream {
 public:
  virtual ~IngestStream() = default;
  // Sends one scan; blocks under flow control. False once the stream is broken (see Finish()).
  // With ClientOptions::ingest_encode_threads the scan is queued to be encoded and written
  // (`scan.points` is copied): a break is seen by a later Send(), and the queued scans get no
  // ack, like any scan the server did not answer before the stream ended.
  virtual bool Send(const ScanData& scan) = 0;
  // The next ack, in send order. False when the server ended the stream.
  virtual bool ReadAck(ScanAck* ack) = 0;
  // No more scans; acks keep coming until every sent scan is answered.
  virtual void CloseSend() = 0;
  // Closes the sending side, reads every remaining ack into `remaining` (if given) and returns
  // how the stream ended (UNAVAILABLE when the server shut down: unacked scans were not applied).
  virtual RpcStatus Finish(std::vector<ScanAck>* remaining = nullptr) = 0;
  // Aborts the stream.
  virtual void Cancel() = 0;
};

struct RegionQuery {
  MetricBox box;
  std::vector<Layer> layers;  // empty: every layer
  int stride = 1;             // map cells per pixel edge
  bool compress = false;      // gzip the answer on the wire (RegionRequest.compress)
};

// A tile's part of a region raster in a delta (docs/server.md, "Region deltas").
struct RegionPatch {
  TileKey key;
  int64_t row_start = 0, col_start = 0, rows = 0, cols = 0;  // in the region raster
  // Every pixel is now unknown (the tile was cleared, emptied or removed): no values.
  bool tombstone = false;
  std::vector<std::vector<float>> values;  // per layer, rows * cols, rows north to south
};

// The answer to QueryRegionSince.
struct RegionDelta {
  // True: `raster` is the whole region (the delta could not be exact: `resync_reason`); replace
  // the copy. False: `patches` hold what changed since, per changed tile its part of the region
  // or rectangles of its changed blocks (several may name one tile: apply each by its
  // rectangle); `raster` has the geometry only.
  bool full = false;
  std::string resync_reason;
  Raster raster;
  std::vector<RegionPatch> patches;
  uint64_t map_version = 0;  // ask the next delta since this version,
  uint64_t history_id = 0;   // with this history id
  uint64_t wire_bytes = 0;   // serialized size of the answer's messages
};

// Brings `copy` (an earlier answer of the same query, kept current) to `delta`: replaced by a
// full answer, patched by a delta. InvalidArgument, leaving `copy` unchanged, if a delta's
// geometry or layers are not the copy's.
Status ApplyDelta(const RegionDelta& delta, Raster* copy);

struct PointValues {
  std::vector<Layer> layers;
  std::vector<float> values;  // point-major: values[i * layers.size() + j]
  uint64_t map_version = 0;
  float at(size_t point, size_t layer) const { return values[point * layers.size() + layer]; }
};

struct PathQuery {
  std::vector<Pose2> poses;
  double radius = 0;                                  // disk footprint, used when polygon is empty
  std::vector<std::array<double, 2>> polygon;         // robot-frame footprint vertices
  std::optional<double> max_traversability;           // default: the map's trav_threshold
  std::optional<double> max_traversability_variance;  // default: the map's variance_threshold
  std::optional<double> max_unknown_fraction;         // default: 0
};

// The server's verdict on a path: its poses and the segments between them (docs/semantics.md,
// "Path checks").
struct PathCheck {
  std::vector<PoseCheck> poses;
  std::vector<SegmentCheck> segments;  // poses.size() - 1: segment i joins poses i and i + 1
  bool safe = false;                   // every pose and every placement between them
  // -1 when safe, else first_unsafe->where.segment: the pose where the unsafe stretch begins.
  int first_unsafe_index = -1;
  std::optional<PlacementCheck> first_unsafe;  // the first unsafe point, in path order
  uint64_t map_version = 0;
};

struct WatchQuery {
  MetricBox box;
  std::vector<Layer> layers;  // empty: every layer
  bool initial_snapshot = false;
};

struct TileUpdate {
  TileKey key;
  uint64_t tile_version = 0;
  uint64_t map_version = 0;
  Raster raster;  // the tile's cells, rows north to south
};

// A running Watch; updates arrive on a background thread.
class WatchSubscription {
 public:
  virtual ~WatchSubscription() = default;  // cancels and waits
  virtual void Cancel() = 0;
  // Blocks until the stream ends; CANCELLED after Cancel(), UNAVAILABLE on server shutdown.
  virtual RpcStatus Wait() = 0;
};

struct RobotInfo {
  std::string robot_id;
  uint64_t last_sequence = 0;
  int64_t last_stamp_ns = 0;
  uint64_t scans_applied = 0;
  uint64_t scans_duplicate = 0;
  uint64_t scans_rejected = 0;
  uint64_t points_kept = 0;
};

struct ServerLimitsInfo {
  uint64_t max_points_per_scan = 0;
  uint64_t max_region_cells = 0;
  uint64_t max_query_points = 0;
  uint64_t max_path_poses = 0;
  double max_coordinate = 0;
  uint64_t max_message_bytes = 0;
  uint32_t max_inflight_scans_per_stream = 0;
  // Map cells one region reads; 0 from an older server, whose max_region_cells counted map cells
  // (it counts output pixels now).
  uint64_t max_region_read_cells = 0;
};

// The server's map store (absent when the map lives in memory only).
struct StorageInfo {
  std::string data_dir;
  std::string durability;  // "sync" | "periodic"
  uint64_t checkpoint_version = 0;
  uint64_t corrupt_tiles = 0;  // queries touching them fail with DATA_LOSS
  // Tiles in memory (storage.max_memory_mb bounds them; the others are read on demand).
  uint64_t memory_limit_bytes = 0;  // 0: unbounded
  uint64_t resident_tiles = 0;
  uint64_t resident_bytes = 0;
  uint64_t tiles_loaded = 0;   // from the store since the server started
  uint64_t tiles_evicted = 0;  // since the server started
  // Writes refused (UNAVAILABLE) for lack of free space on the data dir; queries still answered.
  bool writes_paused_for_space = false;
  bool read_only = false;  // the server started on a full disk and opened its store read-only
  uint64_t free_bytes = 0;
  uint64_t free_space_reserve_bytes = 0;
  std::string writes_paused_reason;
};

// A cluster shard's view (docs/scale-out.md), in Info from a shard.
struct ClusterPartitionInfo {
  std::string name;  // "x.y"
  uint64_t log_sequence = 0;
  uint64_t scans_integrated = 0;
  uint64_t tiles = 0;
  bool serving = false;
  uint64_t restored_from = 0;  // the checkpoint's log sequence (0: rebuilt from the log's start)
};
struct ClusterInfo {
  std::string node;
  std::vector<std::string> live_nodes;
  uint64_t partitions = 0;  // with data, cluster-wide
  uint32_t partition_tiles = 0;
  std::vector<ClusterPartitionInfo> owned;
  uint32_t region_partitions = 0;    // 0: every scan's payload in the one log
  uint64_t nats_received_bytes = 0;  // this shard's NATS connection, since its start
};

struct MapInfo {
  MapParams params;
  std::string params_yaml;
  uint64_t tile_count = 0;
  uint64_t known_cells = 0;
  CellBox known_cells_box;  // empty when nothing is known
  MetricBox known_bounds;
  uint64_t map_version = 0;
  uint64_t scans_applied = 0;
  std::vector<RobotInfo> robots;  // sorted by id
  ServerLimitsInfo limits;
  std::string server_version;
  std::optional<StorageInfo> storage;
  // Where the map frame sits (core/georeference.h), as the map's store keeps it (the first one
  // given by the server config `georeference` or an imported archive); absent: a local frame.
  std::optional<Georeference> georeference;
  std::optional<ClusterInfo> cluster;  // present on a cluster shard
  const RobotInfo* FindRobot(const std::string& id) const;
};

struct ClearResult {
  std::vector<TileKey> changed_tiles;
  uint64_t map_version = 0;
};

struct RetiredRobot {
  uint64_t last_sequence = 0;  // the robot's last admitted sequence number
  uint64_t robots = 0;         // robots the server knows after the retirement
};

// What a pose correction or a scan removal did (CorrectionSummary in admin.proto).
struct CorrectionResult {
  uint64_t map_version = 0;  // the correction's own version
  uint64_t scans_revised = 0;
  uint64_t records_replayed = 0;
  uint64_t records_in_history = 0;
  uint64_t tiles_changed = 0;
  double seconds = 0;
};

struct ExportResult {
  uint64_t bytes = 0;        // of the archive file
  uint64_t tiles = 0;        // in the archive
  uint64_t map_version = 0;  // the archive is the map at exactly this version
};

struct ImportResult {
  uint64_t tiles_added = 0;
  uint64_t map_version = 0;          // of the import (one change)
  uint64_t known_cells = 0;          // of the whole map once the import was done
  uint64_t archive_map_version = 0;  // the version the archive was exported at
};

class Client {
 public:
  // `target`: "host:port" (any gRPC target string). Connects lazily; with options.tls_ca_pem
  // over TLS (a plaintext server, or a certificate that does not verify, fails each call with
  // UNAVAILABLE).
  explicit Client(const std::string& target, ClientOptions options = {});
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  // True once the server is reachable (waits at most `timeout`).
  bool WaitForConnected(std::chrono::milliseconds timeout);

  // One scan (unary IngestScan); a rejected scan is an error status.
  RpcResult<ScanAck> Insert(const ScanData& scan);
  // A long-lived scan stream.
  std::unique_ptr<IngestStream> OpenIngest();
  // Sends `scans` on one stream with acks read concurrently; `on_ack` sees each ack in order.
  RpcResult<std::vector<ScanAck>> IngestAll(std::span<const ScanData> scans,
                                            const std::function<void(const ScanAck&)>& on_ack = {});

  // A region raster, assembled from the streamed chunks; its map version and the server's
  // history id (what QueryRegionSince asks from).
  RpcResult<Raster> QueryRegion(const RegionQuery& query, uint64_t* map_version = nullptr,
                                uint64_t* history_id = nullptr);
  // What changed in the region after `since_version` of the answer with `since_history_id`
  // (0: not checked): the changed tiles' (or blocks') patches, or the whole region when the server
  // cannot answer the delta exactly (docs/server.md, "Region deltas"). ApplyDelta() keeps a copy.
  RpcResult<RegionDelta> QueryRegionSince(const RegionQuery& query, uint64_t since_version,
                                          uint64_t since_history_id = 0);
  RpcResult<PointValues> QueryPoints(std::span<const std::array<double, 2>> points,
                                     const std::vector<Layer>& layers = {});
  RpcResult<PathCheck> CheckPath(const PathQuery& query);
  // Streams updates of changed tiles to `on_update` (on a background thread) until cancelled.
  std::unique_ptr<WatchSubscription> Watch(const WatchQuery& query,
                                           std::function<void(const TileUpdate&)> on_update);
  RpcResult<MapInfo> Info();
  RpcResult<ClearResult> ClearRegion(const MetricBox& box);
  // Admin: forgets a robot (Info() lists them); its next scan starts a new sequence. NOT_FOUND
  // if the server does not know it.
  RpcResult<RetiredRobot> RetireRobot(const std::string& robot_id);
  // The robot itself (or admin): re-integrates its scans `sequence -> pose` with corrected poses
  // (T_map_sensor); answers once the corrected map is in place (docs/semantics.md, "Pose
  // corrections"). FAILED_PRECONDITION if a scan is no longer retained.
  RpcResult<CorrectionResult> CorrectPoses(const std::string& robot_id,
                                           const std::vector<std::pair<uint64_t, ScanPose>>& poses);
  // The robot itself (or admin): removes its scans first..last (inclusive) from the map.
  RpcResult<CorrectionResult> RemoveScans(const std::string& robot_id, uint64_t first,
                                          uint64_t last);

  // Admin: the whole map, or the cells meeting `box`, as one map archive at `path` (a
  // consistent snapshot at one map version). Written to path + ".partial", synced, then renamed:
  // `path` is either the complete archive or untouched; the partial file is removed on failure.
  RpcResult<ExportResult> ExportMap(const std::optional<MetricBox>& box, const std::string& path);
  // Admin: adds the archive at `path` into the served map: statistics are summed, so importing
  // two robots' archives gives exactly their sum. Nothing changes unless the whole archive
  // verifies (see ImportMap in map_service.proto for the status codes).
  RpcResult<ImportResult> ImportMap(const std::string& path);

  // The last sequence number the server admitted for `robot_id` (nullopt: none yet), to resume
  // a stream after a restart.
  RpcResult<std::optional<uint64_t>> LastSequence(const std::string& robot_id);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bgkmap
