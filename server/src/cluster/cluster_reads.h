// Queries on any node of a cluster: the reads gather the statistics of the tiles a query needs
// from the owners of their partitions (NATS request bgkmap.tiles.<partition>), as of at least
// the log's last entry when the query began, put them in a map of their own and answer from it
// with the engine's own estimates, so the answer is bitwise a single server's. With a cluster
// key a reply is believed only if its HMAC verifies for this very request (TileReplyMac); other
// replies (anyone on NATS can answer) are refused and the read waits for the owner's.
#pragma once

#include <atomic>
#include <memory>

#include "bgkmap/core/terrain_map.h"
#include "bgkmap/v1/cluster.pb.h"
#include "cluster/cluster_trust.h"
#include "cluster/membership.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"
#include "serving/map_reads.h"
#include "serving/map_summary.h"

namespace bgkmap::cluster {

class ClusterReads final : public MapReads {
 public:
  // `fetch_timeout_ms`: how long a partition may have no shard serving it (a takeover) before
  // the read is Unavailable.
  ClusterReads(const NatsClient& nats, const ClusterTrust& trust, const PartitionLayout& layout,
               const Membership& members, const MapParams& params, int64_t fetch_timeout_ms);
  ~ClusterReads();  // stops the replies' subscription (waits for its handler's last return)

  // The log's last sequence, asked of the log (a round trip).
  uint64_t applied_version() const override;
  // The log's last sequence as of the last time it was asked.
  uint64_t known_version() const { return last_sequence_.load(); }
  Result<Raster> ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                            int stride) override;
  Result<std::vector<CellEstimate>> ReadCells(std::span<const CellIndex> cells) override;
  Result<TileContent> ReadTile(TileKey key, const std::vector<Layer>& layers) override;
  Result<std::vector<TileKey>> ListKnownTiles(TileKey min, TileKey max) override;
  // A cluster keeps no per-tile versions (a tile is read at a log sequence, not at its last
  // change): every since_version is answered with the whole region.
  uint64_t history_id() const override { return 0; }
  Result<std::vector<ChangedTile>> TilesChangedSince(TileKey, TileKey, uint64_t) override {
    return Status::FailedPrecondition(
        "a cluster keeps no per-tile change versions: region deltas are not answered");
  }

  // Info's counts of the whole cluster (tiles with a known cell, known cells, their bounds) as of
  // at least log entry `sequence`: each partition's owner counts its own tiles.
  Result<MapSummary> Summarize(uint64_t sequence) const;
  // The tiles of `partitions` exactly as of log entry `at`, an export's snapshot point (each
  // owner's copy taken when it applied the entry). Unavailable naming a partition whose owner
  // has no such copy (it was taken over after the entry) once the fetch timeout passes.
  Result<std::unique_ptr<TerrainMap>> GatherAt(const std::vector<PartitionKey>& partitions,
                                               uint64_t at) const;
  // The tiles with min <= key <= max as of at least log entry `sequence`, in a map of their own.
  Result<std::unique_ptr<TerrainMap>> Gather(TileKey min, TileKey max, uint64_t sequence) const;

 private:
  struct Replies;
  // Sends `request` on `subject` and waits up to 3 s for the first reply whose HMAC verifies
  // (TileReplyMac); replies that do not are refused and skipped. NATS_NO_RESPONDERS when the
  // server says nobody subscribes to `subject`.
  natsStatus RequestTrusted(const std::string& subject, const std::string& request,
                            NatsPtr<natsMsg>* reply) const;
  // The partition's tiles in [min, max] into `into`, or only their keys into `keys` if set, or
  // only their counts into `summary` if set.
  Status FetchPartition(PartitionKey p, TileKey min, TileKey max, uint64_t sequence,
                        TerrainMap& into, std::vector<TileKey>* keys = nullptr,
                        v1::PartitionSummary* summary = nullptr, uint64_t at = 0) const;

  const NatsClient& nats_;
  const ClusterTrust& trust_;
  const PartitionLayout& layout_;
  const Membership& members_;
  const MapParams params_;
  const int64_t fetch_timeout_ms_;
  mutable std::atomic<uint64_t> last_sequence_{0};
  std::unique_ptr<Replies> replies_;
};

}  // namespace bgkmap::cluster
