// A partition's checkpoint: its tiles (the halo's included) and each robot's last sequence, as of
// one log sequence number, kept in JetStream (stream BGKMAP_CHECKPOINTS, `replicas` copies). A
// shard taking a partition over restores the newest checkpoint and reads the log from the entry
// after it, instead of from the log's start. Written as chunks and then a manifest, so a writer
// that dies half way leaves the previous checkpoint whole; older chunks are purged afterwards.
// With a cluster key the manifest carries an HMAC over its subject (the partition) and bytes;
// the chunks it names by stream sequence are the writer's own. A manifest that fails it is
// refused (DataLoss), so nobody else's checkpoint is restored or trims the log.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/core/terrain_map.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"

namespace bgkmap::cluster {

inline constexpr const char* kCheckpointStream = "BGKMAP_CHECKPOINTS";

struct PartitionCheckpoint {
  uint64_t log_sequence = 0;
  std::map<std::string, uint64_t> robot_sequences;
  std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> tiles;
};

Status EnsureCheckpointStream(const NatsClient& nats, int replicas);
// Stores `checkpoint` of `p`; the tiles are encoded here.
Status WriteCheckpoint(const NatsClient& nats, const ClusterTrust& trust, PartitionKey p,
                       const PartitionCheckpoint& checkpoint);
// The newest checkpoint of `p` (nullopt: none), its tiles decoded for maps of `params`.
// DataLoss if a chunk fails its checksum.
Result<std::optional<PartitionCheckpoint>> ReadCheckpoint(const NatsClient& nats,
                                                          const ClusterTrust& trust, PartitionKey p,
                                                          const MapParams& params);

// The log sequence of the newest checkpoint of `p` (nullopt: none), without reading its tiles.
Result<std::optional<uint64_t>> ReadCheckpointSequence(const NatsClient& nats,
                                                       const ClusterTrust& trust, PartitionKey p);

// The robot table of the newest checkpoint of `p` (nullopt: none), as of its log sequence,
// without reading its tiles (log_sequence and robot_sequences set; no tiles).
Result<std::optional<PartitionCheckpoint>> ReadCheckpointRobots(const NatsClient& nats,
                                                                const ClusterTrust& trust,
                                                                PartitionKey p);

// An import's tiles, stored in chunks (subject bgkmap.ckpt.import.<id>) before the import's
// log entry; returns the encoded v1::CheckpointManifest naming them (the entry's payload).
Result<std::string> StoreImportTiles(const NatsClient& nats, const std::string& id,
                                     std::span<const TileKey> keys,
                                     std::span<const Tile* const> tiles);
// The tiles of the chunks an encoded manifest names. DataLoss if one fails its checksum.
Result<std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>> ReadImportTiles(
    const NatsClient& nats, const std::string& manifest, const MapParams& params);

}  // namespace bgkmap::cluster
