// bgkmapd as a library: the gRPC map server, startable in-process (tests, embedding) or from
// main.cc. Serves bgkmap.v1.MapService, grpc.health.v1.Health and server reflection.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "bgkmap/server/robot_stats.h"
#include "bgkmap/server/server_config.h"

namespace bgkmap {

// The health-check service name of the map service.
inline constexpr const char* kMapServiceName = "bgkmap.v1.MapService";
// Health of the writes alone: NOT_SERVING while they are refused for lack of free space
// (storage.min_free_space_mb), when "" and kMapServiceName stay SERVING for the reads.
inline constexpr const char* kWritesHealthName = "bgkmap.v1.MapService/writes";

struct ServerReport {
  uint64_t map_version = 0;
  uint64_t scans_applied = 0;
  uint64_t tile_count = 0;
  uint64_t known_cells = 0;
  // Most scans ever integrating at the same moment: > 1 shows disjoint scans ran in parallel.
  uint32_t peak_parallel_integrations = 0;
  uint64_t banded_scans = 0;  // scans integrated in bands (server.scan_bands)
  std::vector<RobotStats> robots;  // sorted by id
};

class MapServer {
 public:
  // Creates the map and starts listening on config.listen_address (port 0: any free port), and
  // if it is set on config.metrics_address for HTTP: GET /metrics and the live web map.
  static Result<std::unique_ptr<MapServer>> Start(const ServerConfig& config);
  ~MapServer();  // Shutdown()

  int port() const;
  // The port of the HTTP endpoint (server.metrics_address: /metrics, the web map, its events,
  // /login; the chosen one for port 0), or 0 when it is off.
  int http_port() const;
  // The port of the Foxglove WebSocket endpoint (server.foxglove.address), or 0 when it is off.
  int foxglove_port() const;

  // Reads server.auth.tokens_file again (bgkmapd: on SIGHUP). A file that does not load keeps
  // the tokens in use; the error says why (also logged).
  Status ReloadTokens();

  // Graceful stop: refuses new calls, lets every ingest stream ack the scans it has read (then
  // ends it with UNAVAILABLE), ends watches, waits for admitted scans, closes the metrics
  // endpoint, stops the workers.
  // Idempotent and thread-safe; returns when the server has stopped.
  void Shutdown();

  // Counts and per-robot progress (valid during and after Shutdown()).
  ServerReport Report() const;
  // A copy of the served map (for tests and offline export).
  std::unique_ptr<TerrainMap> SnapshotMap() const;

 private:
  struct Impl;
  explicit MapServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace bgkmap
