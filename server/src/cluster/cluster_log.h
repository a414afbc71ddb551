// The cluster's log: one JetStream stream whose order is the map's order. Every shard reads it
// in the same order, so every replica of a partition integrates the same scans in the same order
// and holds the bitwise same tiles. A robot's (robot id, sequence) is the message id, so a retry
// within the stream's de-duplication window is stored once whatever node it reaches.
//
// Each entry carries headers a shard reads without decoding the scan: the robot, its sequence
// number, the partitions the scan can change (PartitionLayout::Touched) and the box of cells it
// can change (what a Watch on any node learns from a headers-only reader of the log).
//
// With a cluster key (cluster_trust.h) an entry also carries the time it was signed, the SHA-256
// of its payload and an HMAC over its subject, message id, time and every header above: a
// reader believes an entry only if VerifyEntry accepts it. The message id is signed and
// JetStream stores an id once within cluster.dedupe_window_s, and an entry stored longer after
// its signature than kMaxEntryDelay (plus the clock skew) is refused, so a copy of a real entry
// published again is never applied. A scan stored per region (region_streams.h) keeps its
// payload's digest in the entry and its bytes in the regions' streams: EntryPayload believes a
// copy only with that digest.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/status.h"
#include "bgkmap/v1/ingest.pb.h"
#include "cluster/cluster_trust.h"
#include "cluster/nats_client.h"
#include "cluster/partition_layout.h"
#include "cluster/region_streams.h"

namespace bgkmap::cluster {

inline constexpr const char* kLogStream = "BGKMAP_LOG";
inline constexpr const char* kLogSubjects = "bgkmap.log.>";
inline constexpr const char* kScanSubject = "bgkmap.log.scan";
inline constexpr const char* kClearSubject = "bgkmap.log.clear";  // a v1::CellBox of cells
// An import: a v1::CheckpointManifest naming the chunks of tiles (v1::CheckpointChunk) stored
// beforehand in the checkpoint stream, so the log entry itself stays small and the import is one
// entry (atomic in the log's order, as a single server's import is one change).
inline constexpr const char* kImportSubject = "bgkmap.log.import";
// A robot's retirement (RetireRobot): no payload; the robot is in the entry's robot header.
inline constexpr const char* kRetireSubject = "bgkmap.log.retire";
// An export's snapshot point (ExportMap): no payload; every replica keeps a copy of its own tiles
// as of this entry for the exporting shard to gather.
inline constexpr const char* kExportSubject = "bgkmap.log.export";
// A pose correction or a removal (CorrectPoses, RemoveScans): a v1::LogCorrection naming the
// revised scans by their log sequences; the robot in its headers, the partitions whose halos
// the scans meet before or after the revision (cluster_corrections.cc).
inline constexpr const char* kCorrectSubject = "bgkmap.log.correct";
// A pose correction or a removal a shard refused (the call answered with an error): no payload,
// the robot in its headers; it changes nothing, and every node's robot ledger counts it, as a
// single server counts the corrections it refuses (Info's corrections.failed).
inline constexpr const char* kRefusedSubject = "bgkmap.log.refused";

struct LogStreamOptions {
  int replicas = 1;               // cluster.replicas: JetStream copies of the log (3 in production)
  double dedupe_window_s = 3600;  // cluster.dedupe_window_s: retries inside it are stored once
};

// Creates the stream, or checks that the existing one has `options.replicas` copies.
Status EnsureLogStream(const NatsClient& nats, const LogStreamOptions& options);

struct Appended {
  uint64_t sequence = 0;   // the entry's position in the log (the map version in the cluster)
  bool duplicate = false;  // already in the log: not stored again
};

// Appends robot `robot_id`'s scan `sequence`, `encoded` as it was sent (a bgkmap.v1.Scan), once
// JetStream has stored it on a majority of its replicas (the durability point of a cluster
// ack). Its message id, which the log stores once, is "robot/sequence" + `id_suffix` (what tells
// a new scan from a retry: after a retirement the robot's sequence starts again, and a scan whose
// entry the robot-sequence rule refused may be sent again and judged again). OutOfRange when it
// exceeds the servers' max_payload; Unavailable when the log cannot be reached in time. With
// `regions` enabled the payload is stored in the streams of the regions `touched` meets first,
// and the entry names those copies and holds the payload's digest, not the payload
// (region_streams.h; read it back with EntryPayload).
Result<Appended> AppendScan(const NatsClient& nats, const ClusterTrust& trust,
                            RegionStreams& regions, const std::string& encoded,
                            const std::string& robot_id, uint64_t sequence,
                            const std::string& id_suffix, const std::vector<PartitionKey>& touched,
                            const CellBox& changes);

// Appends a clear of `box` (map cells), ordered with the scans like a single server's clear.
Result<uint64_t> AppendClear(const NatsClient& nats, const ClusterTrust& trust, const CellBox& box,
                             const std::vector<PartitionKey>& touched);

// Appends an import whose tiles are in the checkpoint stream's chunks `manifest` names.
Result<uint64_t> AppendImport(const NatsClient& nats, const ClusterTrust& trust,
                              const std::string& id, const std::string& manifest,
                              const std::vector<PartitionKey>& touched, const CellBox& changes);

// Appends the retirement of robot `robot_id`: every replica and every ledger forgets the robot's
// sequence state when it reads the entry (robot_ledger.h).
Result<uint64_t> AppendRetire(const NatsClient& nats, const ClusterTrust& trust,
                              const std::string& robot_id);

// Appends an export's snapshot point (kExportSubject).
Result<uint64_t> AppendExport(const NatsClient& nats, const ClusterTrust& trust);

// Appends a correction of `robot_id`'s scans (kCorrectSubject; `payload` a v1::LogCorrection)
// as entry `after` + 1 only (JetStream's expected last sequence): its payload was computed from
// the entries up to `after`. nullopt, nothing stored, when the log has grown past `after`
// meanwhile (the caller reads the new entries and tries again).
Result<std::optional<uint64_t>> AppendCorrection(const NatsClient& nats, const ClusterTrust& trust,
                                                 const std::string& robot_id,
                                                 const std::string& payload,
                                                 const std::vector<PartitionKey>& touched,
                                                 const CellBox& changes, uint64_t after);

// Appends the refusal of a correction of `robot_id`'s scans (kRefusedSubject).
Result<uint64_t> AppendRefusal(const NatsClient& nats, const ClusterTrust& trust,
                               const std::string& robot_id);

// The payload of `entry` (whole, as a log reader or GetEntry gave it): its own bytes, or, for a
// scan stored per region, the copy ReadCopy finds (`prefer`'s region first), checked against
// the entry's digest and message id. DataLoss when no copy holds it; Unavailable when the
// region streams cannot be read now (try again: the entry must not be passed without it).
Result<std::string> EntryPayload(const NatsClient& nats, natsMsg* entry,
                                 std::optional<RegionKey> prefer = std::nullopt);

// Entry `sequence` of the log, whole, read by its sequence (not through a reader), verified as
// VerifyEntry verifies: FailedPrecondition if it was not appended by a shard with the key,
// DataLoss if the log does not hold it, Unavailable if the log cannot be read.
Result<NatsPtr<natsMsg>> GetEntry(const NatsClient& nats, const ClusterTrust& trust,
                                  uint64_t sequence);

// Reads the log's entries first..last in order (whole, or their headers only), calling
// `on_entry(sequence, msg)` once per entry; a reader that fails is opened again from the entry
// after the last one given. Unavailable when no entry came for `stall_ms`; FailedPrecondition
// when the log no longer holds entry `first` (trimmed).
Status ReadLogRange(const NatsClient& nats, uint64_t first, uint64_t last, bool headers_only,
                    const std::function<void(uint64_t sequence, natsMsg* msg)>& on_entry,
                    int64_t stall_ms = 30000);

// An ordered reader of the log from entry `start` (whole entries, or their headers only),
// recreated by nats.c after a failure. Unavailable if the log cannot be read.
Result<LiveSubscription> OpenLogReader(const NatsClient& nats, uint64_t start, bool headers_only);
// The log sequence of an entry an OpenLogReader delivered (nullopt: no JetStream metadata).
std::optional<uint64_t> EntrySequence(natsMsg* msg);

// Reads the log's entry headers from `start` until `stop` is set, calling `on_entry(sequence,
// msg)` once per entry in log order. A reader that fails is opened again from the entry after
// the last one given, so none is skipped or repeated; each failure to open is logged as
// `event=<event>` and retried after 250 ms. Blocks: run it on the reader's own thread.
void FollowLogHeaders(const NatsClient& nats, uint64_t start, const std::atomic<bool>& stop,
                      std::string_view event,
                      const std::function<void(uint64_t sequence, natsMsg* msg)>& on_entry);

// The sequence number of the log's last entry (0: empty).
Result<uint64_t> LastSequence(const NatsClient& nats);
// The sequence number of the log's first entry kept (1 until the log is trimmed).
Result<uint64_t> FirstSequence(const NatsClient& nats);
// Deletes the entries before `keep_from` (the log's trimming).
Status TrimLog(const NatsClient& nats, uint64_t keep_from);

struct LogEntryHeader {
  enum class Kind { kScan, kClear, kImport, kRetire, kExport, kCorrect, kRefused };
  // Clears and imports have no robot; a retirement, a correction and a refusal no
  // robot_sequence.
  Kind kind = Kind::kScan;
  std::string robot_id;
  uint64_t robot_sequence = 0;
  std::vector<PartitionKey> touched;  // sorted
  CellBox changes;                    // the cells the entry can change (empty if unknown)
};
// DataLoss if the headers are missing or malformed (an entry not written by AppendScan).
Result<LogEntryHeader> ReadEntryHeader(natsMsg* msg);

// How long after its signature an append may be stored: its retries through a stream leader's
// election (10 s) with room to spare. Must stay below cluster.dedupe_window_s.
inline constexpr std::chrono::seconds kMaxEntryDelay{60};

// Whether entry `msg` (as a log reader delivered it) was appended by a shard holding the
// cluster key: its HMAC verifies, it was stored in time (kMaxEntryDelay) and, unless
// `headers_only`, its payload is the one signed. FailedPrecondition saying what failed; OK
// without a key.
Status VerifyEntry(const ClusterTrust& trust, natsMsg* msg, bool headers_only);
// The same for an entry read by its sequence (GetEntry), stored at `stored_ns` (ns since the
// epoch: natsMsg_GetTime).
Status VerifyEntryStoredAt(const ClusterTrust& trust, natsMsg* msg, bool headers_only,
                           int64_t stored_ns);

}  // namespace bgkmap::cluster
