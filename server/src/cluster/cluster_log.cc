#include "cluster/cluster_log.h"

#include <openssl/rand.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <optional>
#include <sstream>
#include <thread>

#include "bgkmap/v1/types.pb.h"

namespace bgkmap::cluster {
namespace {

constexpr const char* kRobotHeader = "Bgkmap-Robot";
constexpr const char* kSequenceHeader = "Bgkmap-Sequence";
constexpr const char* kTouchedHeader = "Bgkmap-Partitions";
constexpr const char* kChangesHeader = "Bgkmap-Cells";  // "min_x min_y max_x max_y"
// With a cluster key (cluster_trust.h): when it was signed (ns since the epoch), the payload's
// SHA-256 and the HMAC over the entry (EntryMac).
constexpr const char* kTimeHeader = "Bgkmap-Time";
constexpr const char* kDigestHeader = "Bgkmap-Digest";
constexpr const char* kMacHeader = "Bgkmap-Mac";
// A scan whose payload is stored per region (region_streams.h): where its copies are. Not in the
// HMAC: the payload's digest is, and a copy is believed only with that digest.
constexpr const char* kCopiesHeader = "Bgkmap-Copies";
constexpr const char* kMsgIdHeader = "Nats-Msg-Id";  // set by nats.c from jsPubOptions.MsgId
// Append's refusal when the log is past the expected last sequence.
constexpr const char* kLogGrew = "the log grew past the expected entry";
// How long an append or a read of the log's end waits out a stream leader's election.
constexpr int64_t kElectionMs = 10000;

}  // namespace

Status EnsureLogStream(const NatsClient& nats, const LogStreamOptions& options) {
  jsStreamConfig cfg;
  jsStreamConfig_Init(&cfg);
  cfg.Name = kLogStream;
  const char* subjects[] = {"bgkmap.log.>"};
  cfg.Subjects = subjects;
  cfg.SubjectsLen = 1;
  cfg.Storage = js_FileStorage;
  cfg.Replicas = options.replicas;
  cfg.Duplicates = static_cast<int64_t>(options.dedupe_window_s * 1e9);
  cfg.MaxMsgSize = -1;
  jsStreamInfo* info = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  natsStatus st = js_AddStream(&info, nats.jetstream(), &cfg, nullptr, &jerr);
  NatsPtr<jsStreamInfo> owned(info);
  if (st == NATS_OK) return Status::Ok();
  // Already there (another node made it): it must match.
  jsStreamInfo* existing = nullptr;
  jsErrCode jerr2 = static_cast<jsErrCode>(0);
  const natsStatus got = js_GetStreamInfo(&existing, nats.jetstream(), kLogStream, nullptr, &jerr2);
  NatsPtr<jsStreamInfo> owned_existing(existing);
  if (got != NATS_OK)
    return NatsStatus(st, "cluster: cannot create the stream " + std::string(kLogStream), jerr);
  if (existing->Config->Replicas != options.replicas) {
    return Status::FailedPrecondition("cluster.replicas: " + std::to_string(options.replicas) +
                                      " but the stream " + kLogStream + " already has " +
                                      std::to_string(existing->Config->Replicas));
  }
  return Status::Ok();
}

namespace {

// A scan's robot, for its entry's headers.
struct RobotHeaders {
  const std::string& robot_id;
  std::optional<uint64_t> sequence;  // none: a retirement
};

// A random message id: a retry through an election is stored once, and the same entry
// published again by anyone within the dedupe window too (the id is signed).
Result<std::string> RandomMessageId(const std::string& prefix) {
  unsigned char nonce[16];
  if (RAND_bytes(nonce, sizeof nonce) != 1) return Status::IoError("cluster: no random bytes");
  std::string id = prefix;
  for (unsigned char b : nonce) {
    id += "0123456789abcdef"[b >> 4];
    id += "0123456789abcdef"[b & 15];
  }
  return id;
}

// Appends `payload` on `subject` with the partitions it touches, the robot's headers when
// `robot` is set and message id `msg_id` when not empty; retried through a leader's election
// (a scan's message id stores it once). Unavailable when the log cannot be reached in time.
// The one definition of what an entry's HMAC covers: every bgkmap header (absent = ""), the
// subject and the message id, so no header can be changed or moved to another entry.
std::string EntryMac(const ClusterTrust& trust, std::string_view subject, std::string_view msg_id,
                     std::string_view time, std::string_view robot, std::string_view sequence,
                     std::string_view partitions, std::string_view cells, std::string_view digest) {
  return trust.Sign(
      {"bgkmap-log-1", subject, msg_id, time, robot, sequence, partitions, cells, digest});
}

// A payload stored per region: where its copies are (region_streams.h) and its digest.
struct StoredElsewhere {
  std::string copies;
  std::string digest;
};

// `after` (not 0): stored only as entry `after` + 1, else FailedPrecondition kLogGrew.
// `elsewhere` (not null): the entry holds no payload, only the copies' places and its digest.
Result<Appended> Append(const NatsClient& nats, const ClusterTrust& trust, const char* subject,
                        const std::string& payload, const std::vector<PartitionKey>& touched,
                        const CellBox& changes, const RobotHeaders* robot,
                        const std::string& msg_id, uint64_t after = 0,
                        const StoredElsewhere* elsewhere = nullptr) {
  natsMsg* raw = nullptr;
  const std::string_view stored = elsewhere != nullptr ? std::string_view() : payload;
  natsStatus st =
      natsMsg_Create(&raw, subject, nullptr, stored.data(), static_cast<int>(stored.size()));
  if (st != NATS_OK) return NatsStatus(st, "cluster: message");
  NatsPtr<natsMsg> msg(raw);
  std::string parts;
  for (PartitionKey p : touched) {
    if (!parts.empty()) parts += ' ';
    parts += PartitionName(p);
  }
  // (None for an entry that names no partition: a header's empty value does not survive NATS.)
  if (!parts.empty()) st = natsMsgHeader_Set(msg.get(), kTouchedHeader, parts.c_str());
  std::string cells;
  if (st == NATS_OK && !changes.empty()) {
    cells = std::to_string(changes.min.x);
    for (int v : {changes.min.y, changes.max.x, changes.max.y}) {
      cells += ' ';
      cells += std::to_string(v);
    }
    st = natsMsgHeader_Set(msg.get(), kChangesHeader, cells.c_str());
  }
  const std::string sequence =
      robot != nullptr && robot->sequence ? std::to_string(*robot->sequence) : "";
  if (robot != nullptr) {
    if (st == NATS_OK) st = natsMsgHeader_Set(msg.get(), kRobotHeader, robot->robot_id.c_str());
    if (st == NATS_OK && robot->sequence) {
      st = natsMsgHeader_Set(msg.get(), kSequenceHeader, sequence.c_str());
    }
  }
  const std::string digest = elsewhere != nullptr ? elsewhere->digest
                             : trust.keyed()      ? ClusterTrust::Digest(payload)
                                                  : std::string();
  if (elsewhere != nullptr && st == NATS_OK) {
    st = natsMsgHeader_Set(msg.get(), kCopiesHeader, elsewhere->copies.c_str());
    if (st == NATS_OK) st = natsMsgHeader_Set(msg.get(), kDigestHeader, digest.c_str());
  }
  if (trust.keyed()) {
    const std::string time = std::to_string(ClusterTrust::NowNs());
    const std::string mac =
        EntryMac(trust, subject, msg_id, time, robot != nullptr ? robot->robot_id : "", sequence,
                 parts, cells, digest);
    if (st == NATS_OK) st = natsMsgHeader_Set(msg.get(), kTimeHeader, time.c_str());
    if (st == NATS_OK && elsewhere == nullptr) {
      st = natsMsgHeader_Set(msg.get(), kDigestHeader, digest.c_str());
    }
    if (st == NATS_OK) st = natsMsgHeader_Set(msg.get(), kMacHeader, mac.c_str());
  }
  if (st != NATS_OK) return NatsStatus(st, "cluster: message headers");
  jsPubOptions po;
  jsPubOptions_Init(&po);
  if (!msg_id.empty()) po.MsgId = msg_id.c_str();
  po.ExpectStream = kLogStream;
  po.ExpectLastSeq = after;  // 0: no expectation
  jsPubAck* ack_raw = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  bool grew = false;
  st = RetryWhileElecting(
      [&] {
        jerr = static_cast<jsErrCode>(0);
        const natsStatus s = js_PublishMsg(&ack_raw, nats.jetstream(), msg.get(), &po, &jerr);
        grew = after != 0 && jerr == JSStreamWrongLastSequenceErr;
        return grew ? NATS_NOT_FOUND : s;  // an answer, not a failure to get one: no retry
      },
      kElectionMs);
  NatsPtr<jsPubAck> ack(ack_raw);
  if (grew) return Status::FailedPrecondition(kLogGrew);
  if (st != NATS_OK) {
    // Whatever the cause, the client may send it again.
    return Status::Unavailable(
        NatsStatus(st, std::string(subject) + " not stored in the cluster log", jerr).message());
  }
  return Appended{ack->Sequence, ack->Duplicate};
}

}  // namespace

Result<Appended> AppendScan(const NatsClient& nats, const ClusterTrust& trust,
                            RegionStreams& regions, const std::string& encoded,
                            const std::string& robot_id, uint64_t sequence,
                            const std::string& id_suffix, const std::vector<PartitionKey>& touched,
                            const CellBox& changes) {
  if (static_cast<int64_t>(encoded.size()) + 1024 > nats.max_payload()) {
    return Status::OutOfRange("scan: " + std::to_string(encoded.size()) +
                              " bytes exceed the NATS servers' max_payload of " +
                              std::to_string(nats.max_payload()) + " bytes");
  }
  // The robot's own id and sequence: a retry, through this node or another, is stored once.
  const RobotHeaders robot{robot_id, sequence};
  const std::string msg_id = robot_id + "/" + std::to_string(sequence) + id_suffix;
  if (!regions.enabled())
    return Append(nats, trust, kScanSubject, encoded, touched, changes, &robot, msg_id);
  // The copies first: an entry is never read before the copies it names are stored.
  StoredElsewhere elsewhere{"", ClusterTrust::Digest(encoded)};
  Result<std::string> copies = regions.Store(encoded, msg_id, elsewhere.digest, touched);
  if (!copies.ok()) return copies.status();
  elsewhere.copies = std::move(copies).value();
  return Append(nats, trust, kScanSubject, encoded, touched, changes, &robot, msg_id, 0,
                &elsewhere);
}

Result<uint64_t> AppendClear(const NatsClient& nats, const ClusterTrust& trust, const CellBox& box,
                             const std::vector<PartitionKey>& touched) {
  v1::CellBox cells;
  cells.set_min_x(box.min.x);
  cells.set_min_y(box.min.y);
  cells.set_max_x(box.max.x);
  cells.set_max_y(box.max.y);
  Result<std::string> id = RandomMessageId("clear/");
  if (!id.ok()) return id.status();
  Result<Appended> a =
      Append(nats, trust, kClearSubject, cells.SerializeAsString(), touched, box, nullptr, *id);
  if (!a.ok()) return a.status();
  return a->sequence;
}

namespace {

// An entry with no payload naming only a robot (a retirement, a refused correction), under a
// fresh message id. Every replica reads every entry's robot headers, so no partition is named.
Result<uint64_t> AppendRobotOnly(const NatsClient& nats, const ClusterTrust& trust,
                                 const char* subject, const char* id_prefix,
                                 const std::string& robot_id) {
  Result<std::string> id = RandomMessageId(id_prefix);
  if (!id.ok()) return id.status();
  const RobotHeaders robot{robot_id, std::nullopt};
  Result<Appended> a = Append(nats, trust, subject, "", {}, CellBox{}, &robot, *id);
  if (!a.ok()) return a.status();
  return a->sequence;
}

}  // namespace

Result<uint64_t> AppendRetire(const NatsClient& nats, const ClusterTrust& trust,
                              const std::string& robot_id) {
  return AppendRobotOnly(nats, trust, kRetireSubject, "retire/", robot_id);
}

Result<uint64_t> AppendImport(const NatsClient& nats, const ClusterTrust& trust,
                              const std::string& id, const std::string& manifest,
                              const std::vector<PartitionKey>& touched, const CellBox& changes) {
  // Its id as the message id: an import retried through an election is stored once.
  Result<Appended> a =
      Append(nats, trust, kImportSubject, manifest, touched, changes, nullptr, "import/" + id);
  if (!a.ok()) return a.status();
  return a->sequence;
}

Result<uint64_t> AppendExport(const NatsClient& nats, const ClusterTrust& trust) {
  Result<std::string> id = RandomMessageId("export/");
  if (!id.ok()) return id.status();
  Result<Appended> a = Append(nats, trust, kExportSubject, "", {}, CellBox{}, nullptr, *id);
  if (!a.ok()) return a.status();
  return a->sequence;
}

Result<std::optional<uint64_t>> AppendCorrection(const NatsClient& nats, const ClusterTrust& trust,
                                                 const std::string& robot_id,
                                                 const std::string& payload,
                                                 const std::vector<PartitionKey>& touched,
                                                 const CellBox& changes, uint64_t after) {
  Result<std::string> id = RandomMessageId("correct/");
  if (!id.ok()) return id.status();
  const RobotHeaders robot{robot_id, std::nullopt};
  // (A publish nats.c retries through an election after the first try was stored is answered
  // as a duplicate by its message id where JetStream checks that first, else refused for the
  // sequence: the caller then finds its own payload among the new entries.)
  Result<Appended> a =
      Append(nats, trust, kCorrectSubject, payload, touched, changes, &robot, *id, after);
  if (!a.ok() && a.status().message() == kLogGrew) return std::optional<uint64_t>();
  if (!a.ok()) return a.status();
  return std::optional<uint64_t>(a->sequence);
}

Result<uint64_t> AppendRefusal(const NatsClient& nats, const ClusterTrust& trust,
                               const std::string& robot_id) {
  return AppendRobotOnly(nats, trust, kRefusedSubject, "refused/", robot_id);
}

Result<NatsPtr<natsMsg>> GetEntry(const NatsClient& nats, const ClusterTrust& trust,
                                  uint64_t sequence) {
  natsMsg* raw = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  const natsStatus st = RetryWhileElecting(
      [&] { return js_GetMsg(&raw, nats.jetstream(), kLogStream, sequence, nullptr, &jerr); },
      kElectionMs);
  NatsPtr<natsMsg> msg(raw);
  if (st == NATS_NOT_FOUND || jerr == JSNoMessageFoundErr) {
    return Status::DataLoss("the cluster log holds no entry " + std::to_string(sequence));
  }
  if (st != NATS_OK) {
    return Status::Unavailable(
        NatsStatus(st, "read log entry " + std::to_string(sequence), jerr).message());
  }
  if (Status s = VerifyEntryStoredAt(trust, msg.get(), false, natsMsg_GetTime(msg.get()));
      !s.ok()) {
    return s;
  }
  return msg;
}

namespace {

// The next entry of the log from entry `next` on, read through `*sub` (opened again from `next`
// when it is null or has failed), with its sequence in `*sequence`; null after 100 ms without
// one, after a read failure, or when the reader cannot be opened (then `*open_failure`, after a
// 250 ms pause). A reopened reader's repeats of entries before `next` are skipped.
NatsPtr<natsMsg> NextEntry(const NatsClient& nats, bool headers_only, uint64_t next,
                           LiveSubscription* sub, Status* open_failure, uint64_t* sequence) {
  if (!*sub) {
    Result<LiveSubscription> opened = OpenLogReader(nats, next, headers_only);
    if (!opened.ok()) {
      *open_failure = opened.status();
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
      return nullptr;
    }
    *sub = std::move(opened).value();
  }
  natsMsg* raw = nullptr;
  const natsStatus st = natsSubscription_NextMsg(&raw, sub->get(), 100);
  if (st == NATS_TIMEOUT) return nullptr;
  if (st != NATS_OK) {
    sub->reset();
    return nullptr;
  }
  NatsPtr<natsMsg> msg(raw);
  const std::optional<uint64_t> entry = EntrySequence(msg.get());
  if (!entry || *entry < next) return nullptr;
  *sequence = *entry;
  return msg;
}

}  // namespace

Status ReadLogRange(const NatsClient& nats, uint64_t first, uint64_t last, bool headers_only,
                    const std::function<void(uint64_t sequence, natsMsg* msg)>& on_entry,
                    int64_t stall_ms) {
  uint64_t next = first;
  LiveSubscription sub;
  auto progress = std::chrono::steady_clock::now();
  while (next <= last) {
    if (std::chrono::steady_clock::now() - progress > std::chrono::milliseconds(stall_ms)) {
      return Status::Unavailable("the cluster log gave no entry after " + std::to_string(next - 1) +
                                 " for " + std::to_string(stall_ms) + " ms");
    }
    Status open_failure;
    uint64_t entry = 0;
    NatsPtr<natsMsg> msg = NextEntry(nats, headers_only, next, &sub, &open_failure, &entry);
    if (!msg) continue;
    if (entry > next && next == first) {
      return Status::FailedPrecondition("the cluster log no longer holds entry " +
                                        std::to_string(first) + " (it was trimmed to " +
                                        std::to_string(entry) + ")");
    }
    if (entry > last) break;
    progress = std::chrono::steady_clock::now();
    next = entry + 1;
    on_entry(entry, msg.get());
  }
  return Status::Ok();
}

Result<LiveSubscription> OpenLogReader(const NatsClient& nats, uint64_t start, bool headers_only) {
  jsSubOptions so;
  jsSubOptions_Init(&so);
  so.Ordered = true;
  so.Config.HeadersOnly = headers_only;
  so.Config.DeliverPolicy = js_DeliverByStartSequence;
  so.Config.OptStartSeq = start;
  natsSubscription* raw = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  const natsStatus st = js_SubscribeSync(&raw, nats.jetstream(), kLogSubjects, nullptr, &so, &jerr);
  LiveSubscription sub(raw, QuiescingDeleter{nats.connection()});
  if (st != NATS_OK) {
    return Status::Unavailable(
        NatsStatus(st, headers_only ? "read the log's headers" : "read the log", jerr).message());
  }
  return sub;
}

void FollowLogHeaders(const NatsClient& nats, uint64_t start, const std::atomic<bool>& stop,
                      std::string_view event,
                      const std::function<void(uint64_t sequence, natsMsg* msg)>& on_entry) {
  uint64_t next = start;
  LiveSubscription sub;
  while (!stop) {
    Status open_failure;
    uint64_t entry = 0;
    NatsPtr<natsMsg> msg = NextEntry(nats, true, next, &sub, &open_failure, &entry);
    if (!open_failure.ok()) {
      spdlog::warn("event={} reason=\"{}\"", event, open_failure.message());
    }
    if (!msg) continue;
    next = entry + 1;
    on_entry(entry, msg.get());
  }
}

std::optional<uint64_t> EntrySequence(natsMsg* msg) {
  jsMsgMetaData* raw = nullptr;
  if (natsMsg_GetMetaData(&raw, msg) != NATS_OK) return std::nullopt;
  NatsPtr<jsMsgMetaData> meta(raw);
  return meta->Sequence.Stream;
}

namespace {

struct LogBounds {
  uint64_t first = 0, last = 0;
};

Result<LogBounds> LogState(const NatsClient& nats) {
  jsStreamInfo* info = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  const natsStatus st = RetryWhileElecting(
      [&] { return js_GetStreamInfo(&info, nats.jetstream(), kLogStream, nullptr, &jerr); },
      kElectionMs);
  NatsPtr<jsStreamInfo> owned(info);
  if (st != NATS_OK) {
    return Status::Unavailable(NatsStatus(st, "cluster log", jerr).message());
  }
  return LogBounds{info->State.FirstSeq, info->State.LastSeq};
}

}  // namespace

Result<uint64_t> LastSequence(const NatsClient& nats) {
  Result<LogBounds> state = LogState(nats);
  if (!state.ok()) return state.status();
  return state->last;
}

Result<uint64_t> FirstSequence(const NatsClient& nats) {
  Result<LogBounds> state = LogState(nats);
  if (!state.ok()) return state.status();
  return state->first;
}

Status TrimLog(const NatsClient& nats, uint64_t keep_from) {
  jsOptions o;
  jsOptions_Init(&o);
  o.Stream.Purge.Sequence = keep_from;  // purges up to, not including, keep_from
  jsErrCode jerr = static_cast<jsErrCode>(0);
  const natsStatus st = js_PurgeStream(nats.jetstream(), kLogStream, &o, &jerr);
  if (st != NATS_OK) return NatsStatus(st, "cluster: trim the log", jerr);
  return Status::Ok();
}

Result<LogEntryHeader> ReadEntryHeader(natsMsg* msg) {
  const char* robot = nullptr;
  const char* sequence = nullptr;
  const char* touched = nullptr;
  LogEntryHeader h;
  const std::string_view subject(natsMsg_GetSubject(msg));
  h.kind = subject == kClearSubject     ? LogEntryHeader::Kind::kClear
           : subject == kImportSubject  ? LogEntryHeader::Kind::kImport
           : subject == kRetireSubject  ? LogEntryHeader::Kind::kRetire
           : subject == kExportSubject  ? LogEntryHeader::Kind::kExport
           : subject == kCorrectSubject ? LogEntryHeader::Kind::kCorrect
           : subject == kRefusedSubject ? LogEntryHeader::Kind::kRefused
                                        : LogEntryHeader::Kind::kScan;
  const bool scan = h.kind == LogEntryHeader::Kind::kScan;
  const bool robot_entry = scan || h.kind == LogEntryHeader::Kind::kRetire ||
                           h.kind == LogEntryHeader::Kind::kCorrect ||
                           h.kind == LogEntryHeader::Kind::kRefused;
  const bool no_partition = h.kind == LogEntryHeader::Kind::kRetire ||
                            h.kind == LogEntryHeader::Kind::kExport ||
                            h.kind == LogEntryHeader::Kind::kRefused;
  if ((natsMsgHeader_Get(msg, kTouchedHeader, &touched) != NATS_OK && !no_partition) ||
      (robot_entry && natsMsgHeader_Get(msg, kRobotHeader, &robot) != NATS_OK) ||
      (scan && natsMsgHeader_Get(msg, kSequenceHeader, &sequence) != NATS_OK)) {
    return Status::DataLoss("cluster log entry without bgkmap headers");
  }
  if (robot_entry) h.robot_id = robot;
  if (scan) {
    const std::string_view seq(sequence);
    if (auto [end, ec] = std::from_chars(seq.data(), seq.data() + seq.size(), h.robot_sequence);
        ec != std::errc() || end != seq.data() + seq.size()) {
      return Status::DataLoss("cluster log entry: bad " + std::string(kSequenceHeader));
    }
  }
  std::istringstream parts{std::string(touched != nullptr ? touched : "")};
  for (std::string name; parts >> name;) {
    std::optional<PartitionKey> p = ParsePartitionName(name);
    if (!p) return Status::DataLoss("cluster log entry: bad partition '" + name + "'");
    h.touched.push_back(*p);
  }
  std::sort(h.touched.begin(), h.touched.end());
  // Entries written before this header existed: the changes are not known.
  const char* changes = nullptr;
  if (natsMsgHeader_Get(msg, kChangesHeader, &changes) == NATS_OK) {
    std::istringstream in{std::string(changes)};
    CellBox box;
    if (!(in >> box.min.x >> box.min.y >> box.max.x >> box.max.y) || box.empty()) {
      return Status::DataLoss("cluster log entry: bad " + std::string(kChangesHeader));
    }
    h.changes = box;
  }
  return h;
}

Status VerifyEntry(const ClusterTrust& trust, natsMsg* msg, bool headers_only) {
  if (!trust.keyed()) return Status::Ok();
  jsMsgMetaData* raw = nullptr;
  if (natsMsg_GetMetaData(&raw, msg) != NATS_OK) {
    return Status::FailedPrecondition("the entry has no JetStream time");
  }
  NatsPtr<jsMsgMetaData> meta(raw);
  return VerifyEntryStoredAt(trust, msg, headers_only, meta->Timestamp);
}

Status VerifyEntryStoredAt(const ClusterTrust& trust, natsMsg* msg, bool headers_only,
                           int64_t stored_ns) {
  if (!trust.keyed()) return Status::Ok();
  auto header = [msg](const char* key) {
    const char* value = nullptr;
    return natsMsgHeader_Get(msg, key, &value) == NATS_OK && value != nullptr ? std::string(value)
                                                                              : std::string();
  };
  const std::string mac = header(kMacHeader);
  if (mac.empty()) return Status::FailedPrecondition("the entry is not signed");
  const std::string time = header(kTimeHeader), digest = header(kDigestHeader);
  if (!trust.Verify(mac, {"bgkmap-log-1", natsMsg_GetSubject(msg), header(kMsgIdHeader), time,
                          header(kRobotHeader), header(kSequenceHeader), header(kTouchedHeader),
                          header(kChangesHeader), digest})) {
    return Status::FailedPrecondition("the entry's HMAC does not verify (no cluster key)");
  }
  int64_t signed_ns = 0;
  if (auto [end, ec] = std::from_chars(time.data(), time.data() + time.size(), signed_ns);
      ec != std::errc() || end != time.data() + time.size()) {
    return Status::FailedPrecondition("bad " + std::string(kTimeHeader));
  }
  if (!ClusterTrust::StoredInTime(signed_ns, stored_ns, kMaxEntryDelay)) {
    return Status::FailedPrecondition("stored " +
                                      std::to_string((stored_ns - signed_ns) / 1000000) +
                                      " ms after it was signed: a copy published again");
  }
  // A payload stored per region is checked when it is read (EntryPayload).
  if (!headers_only && header(kCopiesHeader).empty() &&
      ClusterTrust::Digest(std::string_view(
          natsMsg_GetData(msg), static_cast<size_t>(natsMsg_GetDataLength(msg)))) != digest) {
    return Status::FailedPrecondition("the payload is not the one signed");
  }
  return Status::Ok();
}

Result<std::string> EntryPayload(const NatsClient& nats, natsMsg* entry,
                                 std::optional<RegionKey> prefer) {
  const char* copies = nullptr;
  if (natsMsgHeader_Get(entry, kCopiesHeader, &copies) != NATS_OK || copies == nullptr) {
    return std::string(natsMsg_GetData(entry), static_cast<size_t>(natsMsg_GetDataLength(entry)));
  }
  const char* msg_id = nullptr;
  const char* digest = nullptr;
  if (natsMsgHeader_Get(entry, kMsgIdHeader, &msg_id) != NATS_OK || msg_id == nullptr ||
      natsMsgHeader_Get(entry, kDigestHeader, &digest) != NATS_OK || digest == nullptr) {
    return Status::DataLoss("the entry names payload copies without their message id and digest");
  }
  return ReadCopy(nats, copies, msg_id, digest, prefer);
}

}  // namespace bgkmap::cluster
