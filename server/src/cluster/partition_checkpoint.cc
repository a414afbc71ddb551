#include "cluster/partition_checkpoint.h"

#include <span>

#include "bgkmap/storage/tile_codec.h"
#include "bgkmap/v1/cluster.pb.h"

namespace bgkmap::cluster {
namespace {

std::string Subject(PartitionKey p, const char* what) {
  return "bgkmap.ckpt." + PartitionName(p) + "." + what;
}

constexpr const char* kMacHeader = "Bgkmap-Mac";

std::string ManifestMac(const ClusterTrust& trust, std::string_view subject,
                        std::string_view bytes) {
  return trust.Sign({"bgkmap-ckpt-1", subject, bytes});
}

// `mac` (not empty): the message's Bgkmap-Mac header.
Result<uint64_t> Publish(const NatsClient& nats, const std::string& subject,
                         const std::string& bytes, const std::string& mac = "") {
  natsMsg* raw = nullptr;
  natsStatus st =
      natsMsg_Create(&raw, subject.c_str(), nullptr, bytes.data(), static_cast<int>(bytes.size()));
  if (st != NATS_OK) return NatsStatus(st, "checkpoint: message");
  NatsPtr<natsMsg> msg(raw);
  if (!mac.empty() && (st = natsMsgHeader_Set(msg.get(), kMacHeader, mac.c_str())) != NATS_OK) {
    return NatsStatus(st, "checkpoint: message header");
  }
  jsPubAck* ack_raw = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  st = RetryWhileElecting(
      [&] { return js_PublishMsg(&ack_raw, nats.jetstream(), msg.get(), nullptr, &jerr); }, 10000);
  NatsPtr<jsPubAck> ack(ack_raw);
  if (st != NATS_OK) return NatsStatus(st, "checkpoint: publish " + subject, jerr);
  return ack->Sequence;
}

void Purge(const NatsClient& nats, const std::string& subject, uint64_t below, uint64_t keep) {
  jsOptions o;
  jsOptions_Init(&o);
  o.Stream.Purge.Subject = subject.c_str();
  o.Stream.Purge.Sequence = below;
  o.Stream.Purge.Keep = keep;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  js_PurgeStream(nats.jetstream(), kCheckpointStream, &o, &jerr);  // best effort: space only
}

}  // namespace

Status EnsureCheckpointStream(const NatsClient& nats, int replicas) {
  jsStreamConfig cfg;
  jsStreamConfig_Init(&cfg);
  cfg.Name = kCheckpointStream;
  const char* subjects[] = {"bgkmap.ckpt.>"};
  cfg.Subjects = subjects;
  cfg.SubjectsLen = 1;
  cfg.Storage = js_FileStorage;
  cfg.Replicas = replicas;
  cfg.AllowDirect = true;
  jsStreamInfo* info = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  const natsStatus st = js_AddStream(&info, nats.jetstream(), &cfg, nullptr, &jerr);
  NatsPtr<jsStreamInfo> owned(info);
  if (st == NATS_OK) return Status::Ok();
  jsStreamInfo* existing = nullptr;
  const natsStatus got =
      js_GetStreamInfo(&existing, nats.jetstream(), kCheckpointStream, nullptr, &jerr);
  NatsPtr<jsStreamInfo> owned_existing(existing);
  if (got != NATS_OK) return NatsStatus(st, std::string("cluster: stream ") + kCheckpointStream);
  return Status::Ok();
}

// Publishes `tiles` in chunks on `subject`; their sequence numbers go to `manifest`.
static Status PublishChunks(const NatsClient& nats, const std::string& subject,
                            std::span<const TileKey> keys, std::span<const Tile* const> tiles,
                            v1::CheckpointManifest& manifest) {
  const int64_t budget = nats.max_payload() - 4096;
  v1::CheckpointChunk chunk;
  int64_t bytes = 0;
  auto flush = [&]() -> Status {
    if (chunk.keys_size() == 0) return Status::Ok();
    Result<uint64_t> seq = Publish(nats, subject, chunk.SerializeAsString());
    if (!seq.ok()) return seq.status();
    manifest.add_chunk_sequences(*seq);
    chunk.Clear();
    bytes = 0;
    return Status::Ok();
  };
  for (size_t i = 0; i < keys.size(); ++i) {
    std::string encoded = storage::EncodeTile(*tiles[i]);
    if (bytes + static_cast<int64_t>(encoded.size()) + 16 > budget) {
      if (Status s = flush(); !s.ok()) return s;
    }
    bytes += static_cast<int64_t>(encoded.size()) + 16;
    v1::TileKey* k = chunk.add_keys();
    k->set_x(keys[i].x);
    k->set_y(keys[i].y);
    chunk.add_tiles(std::move(encoded));
  }
  manifest.set_tiles(manifest.tiles() + keys.size());
  return flush();
}

Status WriteCheckpoint(const NatsClient& nats, const ClusterTrust& trust, PartitionKey p,
                       const PartitionCheckpoint& checkpoint) {
  v1::CheckpointManifest manifest;
  manifest.set_log_sequence(checkpoint.log_sequence);
  for (const auto& [robot, sequence] : checkpoint.robot_sequences) {
    (*manifest.mutable_robot_sequences())[robot] = sequence;
  }
  std::vector<TileKey> keys;
  std::vector<const Tile*> tiles;
  for (const auto& [key, tile] : checkpoint.tiles) {
    keys.push_back(key);
    tiles.push_back(tile.get());
  }
  if (Status s = PublishChunks(nats, Subject(p, "chunk"), keys, tiles, manifest); !s.ok()) {
    return s;
  }
  const std::string subject = Subject(p, "manifest"), bytes = manifest.SerializeAsString();
  Result<uint64_t> written = Publish(nats, subject, bytes, ManifestMac(trust, subject, bytes));
  if (!written.ok()) return written.status();
  // The previous checkpoint's chunks and manifests are no longer needed.
  const uint64_t first =
      manifest.chunk_sequences_size() > 0 ? manifest.chunk_sequences(0) : *written;
  Purge(nats, Subject(p, "chunk"), first, 0);
  Purge(nats, Subject(p, "manifest"), 0, 1);
  return Status::Ok();
}

Result<std::string> StoreImportTiles(const NatsClient& nats, const std::string& id,
                                     std::span<const TileKey> keys,
                                     std::span<const Tile* const> tiles) {
  v1::CheckpointManifest manifest;
  if (Status s = PublishChunks(nats, "bgkmap.ckpt.import." + id, keys, tiles, manifest); !s.ok()) {
    return s;
  }
  return manifest.SerializeAsString();
}

static Result<std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>> ReadChunks(
    const NatsClient& nats, const v1::CheckpointManifest& manifest, const MapParams& params) {
  std::vector<std::pair<TileKey, std::unique_ptr<Tile>>> out;
  for (uint64_t seq : manifest.chunk_sequences()) {
    natsMsg* chunk_raw = nullptr;
    jsErrCode jerr = static_cast<jsErrCode>(0);
    const natsStatus got = RetryWhileElecting(
        [&] {
          return js_GetMsg(&chunk_raw, nats.jetstream(), kCheckpointStream, seq, nullptr, &jerr);
        },
        10000);
    NatsPtr<natsMsg> chunk_msg(chunk_raw);
    if (got != NATS_OK) return NatsStatus(got, "chunk " + std::to_string(seq), jerr);
    v1::CheckpointChunk chunk;
    if (!chunk.ParseFromArray(natsMsg_GetData(chunk_msg.get()),
                              natsMsg_GetDataLength(chunk_msg.get())) ||
        chunk.keys_size() != chunk.tiles_size()) {
      return Status::DataLoss("chunk " + std::to_string(seq) + " does not decode");
    }
    for (int i = 0; i < chunk.keys_size(); ++i) {
      Result<std::unique_ptr<Tile>> tile =
          storage::DecodeTile(chunk.tiles(i), params.tile_size, KeepsPlaneMoments(params.method));
      if (!tile.ok()) return Status::DataLoss(tile.status().message());
      out.emplace_back(TileKey{chunk.keys(i).x(), chunk.keys(i).y()}, std::move(tile).value());
    }
  }
  if (out.size() != manifest.tiles()) {
    return Status::DataLoss(std::to_string(out.size()) + " tiles of " +
                            std::to_string(manifest.tiles()));
  }
  return out;
}

// The newest manifest of `p` (nullopt: none).
static Result<std::optional<v1::CheckpointManifest>> ReadManifest(const NatsClient& nats,
                                                                  const ClusterTrust& trust,
                                                                  PartitionKey p) {
  natsMsg* raw = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  const std::string subject = Subject(p, "manifest");
  const natsStatus st = RetryWhileElecting(
      [&] {
        return js_GetLastMsg(&raw, nats.jetstream(), kCheckpointStream, subject.c_str(), nullptr,
                             &jerr);
      },
      5000);
  NatsPtr<natsMsg> last(raw);
  if (st == NATS_NOT_FOUND) return std::optional<v1::CheckpointManifest>();
  if (st != NATS_OK) return NatsStatus(st, "checkpoint: read " + subject, jerr);
  const char* mac = nullptr;
  if (trust.keyed() &&
      (natsMsgHeader_Get(last.get(), kMacHeader, &mac) != NATS_OK || mac == nullptr ||
       !trust.Verify(mac,
                     {"bgkmap-ckpt-1", subject,
                      std::string_view(natsMsg_GetData(last.get()),
                                       static_cast<size_t>(natsMsg_GetDataLength(last.get())))}))) {
    trust.Refuse(Untrusted::kCheckpoint, subject + ": the newest manifest is not signed");
    return Status::DataLoss("checkpoint of partition " + PartitionName(p) +
                            ": the newest manifest is not signed with the cluster key");
  }
  v1::CheckpointManifest manifest;
  if (!manifest.ParseFromArray(natsMsg_GetData(last.get()), natsMsg_GetDataLength(last.get()))) {
    return Status::DataLoss("checkpoint of partition " + PartitionName(p) +
                            ": the manifest does not decode");
  }
  return std::optional<v1::CheckpointManifest>(std::move(manifest));
}

Result<std::optional<uint64_t>> ReadCheckpointSequence(const NatsClient& nats,
                                                       const ClusterTrust& trust, PartitionKey p) {
  Result<std::optional<v1::CheckpointManifest>> manifest = ReadManifest(nats, trust, p);
  if (!manifest.ok()) return manifest.status();
  if (!manifest->has_value()) return std::optional<uint64_t>();
  return std::optional<uint64_t>((*manifest)->log_sequence());
}

Result<std::optional<PartitionCheckpoint>> ReadCheckpointRobots(const NatsClient& nats,
                                                                const ClusterTrust& trust,
                                                                PartitionKey p) {
  Result<std::optional<v1::CheckpointManifest>> manifest = ReadManifest(nats, trust, p);
  if (!manifest.ok()) return manifest.status();
  if (!manifest->has_value()) return std::optional<PartitionCheckpoint>();
  PartitionCheckpoint out;
  out.log_sequence = (*manifest)->log_sequence();
  for (const auto& [robot, sequence] : (*manifest)->robot_sequences()) {
    out.robot_sequences[robot] = sequence;
  }
  return std::optional<PartitionCheckpoint>(std::move(out));
}

Result<std::optional<PartitionCheckpoint>> ReadCheckpoint(const NatsClient& nats,
                                                          const ClusterTrust& trust, PartitionKey p,
                                                          const MapParams& params) {
  Result<std::optional<v1::CheckpointManifest>> read = ReadManifest(nats, trust, p);
  if (!read.ok()) return read.status();
  if (!read->has_value()) return std::optional<PartitionCheckpoint>();
  const v1::CheckpointManifest& manifest = **read;
  PartitionCheckpoint out;
  out.log_sequence = manifest.log_sequence();
  for (const auto& [robot, sequence] : manifest.robot_sequences()) {
    out.robot_sequences[robot] = sequence;
  }
  Result<std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>> tiles =
      ReadChunks(nats, manifest, params);
  if (!tiles.ok()) {
    return Status::DataLoss("checkpoint of partition " + PartitionName(p) + ": " +
                            tiles.status().message());
  }
  out.tiles = std::move(tiles).value();
  return std::optional<PartitionCheckpoint>(std::move(out));
}

Result<std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>> ReadImportTiles(
    const NatsClient& nats, const std::string& manifest, const MapParams& params) {
  v1::CheckpointManifest m;
  if (!m.ParseFromString(manifest))
    return Status::DataLoss("the import's manifest does not decode");
  return ReadChunks(nats, m, params);
}

}  // namespace bgkmap::cluster
