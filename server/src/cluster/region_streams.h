// Streams per region (cluster.region_partitions > 0; docs/scale-out.md, "Streams per region").
// A region is region_partitions x region_partitions partitions, and one shard owns all of a
// region's partitions (Membership::OwnerOf hashes the region). A scan's payload is stored once
// in the stream of every region it touches (BGKMAP_REGION_<x>_<y>, subject
// bgkmap.region.<x>_<y>); its log entry keeps the scan's place in the cluster's one order, its
// headers, the payload's SHA-256 and where the copies are, but no payload. So every shard reads
// every entry's few hundred bytes of headers and only the payloads its own partitions need, and
// the payload bytes are spread over as many streams (and stream leaders) as there are regions.
#pragma once

#include <compare>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/status.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"

namespace bgkmap::cluster {

struct RegionKey {
  int x = 0;
  int y = 0;
  friend constexpr auto operator<=>(const RegionKey&, const RegionKey&) = default;
};

// The region of partition `p`: regions of region_partitions x region_partitions partitions tile
// the plane, region (0, 0) centred on the map's origin.
RegionKey RegionOf(PartitionKey p, int region_partitions);
// "x_y" (e.g. "3_-2"): the region's name in its stream's name and subject.
std::string RegionName(RegionKey r);

struct RegionStreamOptions {
  int region_partitions = 0;      // cluster.region_partitions (0: payloads stay in the log)
  int replicas = 1;               // cluster.replicas
  double dedupe_window_s = 3600;  // cluster.dedupe_window_s
};

class RegionStreams {
 public:
  RegionStreams(const NatsClient& nats, RegionStreamOptions options);

  bool enabled() const { return options_.region_partitions > 0; }
  int region_partitions() const { return options_.region_partitions; }

  // Stores `payload` (a scan as sent, message id `msg_id` in the log) in the stream of every
  // region of `touched`, each region's stream made on first use. Returns the log entry's copies
  // header: "REGION:SEQUENCE ..." (RegionName, the copy's sequence in that region's stream). A
  // copy's message id is `msg_id` and the payload's digest, so a retry is stored once and a copy
  // published by anyone else under a guessed id is another message, never the one named.
  // Unavailable when a region's stream cannot be reached in time (the client sends it again).
  Result<std::string> Store(const std::string& payload, const std::string& msg_id,
                            const std::string& digest, const std::vector<PartitionKey>& touched);

 private:
  Status Ensure(RegionKey r);  // the region's stream, made once

  const NatsClient& nats_;
  const RegionStreamOptions options_;
  std::mutex mu_;
  std::set<RegionKey> ensured_;  // guarded by mu_
};

// The message id of a payload's copy in a region stream.
std::string CopyMessageId(std::string_view msg_id, std::string_view digest);

// Reads the copy of a payload that `copies` (an entry's copies header) names, `prefer`'s
// region first, and returns its bytes once its message id is `CopyMessageId(msg_id, digest)` and
// its SHA-256 is `digest`. DataLoss when no copy named holds it (or the header is malformed);
// Unavailable when a stream could not be read now (the caller tries again).
Result<std::string> ReadCopy(const NatsClient& nats, std::string_view copies,
                             std::string_view msg_id, std::string_view digest,
                             std::optional<RegionKey> prefer);

}  // namespace bgkmap::cluster
