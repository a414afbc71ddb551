#include "cluster/region_streams.h"

#include <algorithm>
#include <charconv>
#include <sstream>

#include "cluster/cluster_trust.h"

namespace bgkmap::cluster {
namespace {

constexpr const char* kStreamPrefix = "BGKMAP_REGION_";
constexpr const char* kSubjectPrefix = "bgkmap.region.";
constexpr const char* kMsgIdHeader = "Nats-Msg-Id";
// How long a copy's append or read waits out a stream leader's election (as the log's).
constexpr int64_t kElectionMs = 10000;

std::string StreamName(std::string_view region) { return kStreamPrefix + std::string(region); }

}  // namespace

RegionKey RegionOf(PartitionKey p, int region_partitions) {
  // Centred on the map's origin, where a map frame usually starts (a robot's first pose): a
  // drive from there does not begin on a border between four regions.
  const int half = region_partitions / 2;
  return {FloorDiv(p.x + half, region_partitions), FloorDiv(p.y + half, region_partitions)};
}

std::string RegionName(RegionKey r) { return std::to_string(r.x) + "_" + std::to_string(r.y); }

std::string CopyMessageId(std::string_view msg_id, std::string_view digest) {
  return std::string(msg_id) + "#" + std::string(digest);
}

RegionStreams::RegionStreams(const NatsClient& nats, RegionStreamOptions options)
    : nats_(nats), options_(options) {}

Status RegionStreams::Ensure(RegionKey r) {
  {
    std::lock_guard lock(mu_);
    if (ensured_.count(r) != 0) return Status::Ok();
  }
  const std::string name = StreamName(RegionName(r));
  const std::string subject = kSubjectPrefix + RegionName(r);
  jsStreamConfig cfg;
  jsStreamConfig_Init(&cfg);
  cfg.Name = name.c_str();
  const char* subjects[] = {subject.c_str()};
  cfg.Subjects = subjects;
  cfg.SubjectsLen = 1;
  cfg.Storage = js_FileStorage;
  cfg.Replicas = options_.replicas;
  cfg.Duplicates = static_cast<int64_t>(options_.dedupe_window_s * 1e9);
  cfg.MaxMsgSize = -1;
  // A copy is read by its sequence from any replica, as it was stored (ReadCopy).
  cfg.AllowDirect = true;
  jsStreamInfo* info = nullptr;
  jsErrCode jerr = static_cast<jsErrCode>(0);
  natsStatus st = RetryWhileElecting(
      [&] {
        jsStreamInfo_Destroy(info);
        info = nullptr;
        const natsStatus added = js_AddStream(&info, nats_.jetstream(), &cfg, nullptr, &jerr);
        if (added == NATS_OK) return added;
        // Made by another shard meanwhile: there it is.
        jsStreamInfo_Destroy(info);
        info = nullptr;
        return js_GetStreamInfo(&info, nats_.jetstream(), name.c_str(), nullptr, nullptr);
      },
      kElectionMs);
  NatsPtr<jsStreamInfo> owned(info);
  if (st != NATS_OK) {
    return Status::Unavailable(
        NatsStatus(st, "cluster: cannot create the stream " + name, jerr).message());
  }
  std::lock_guard lock(mu_);
  ensured_.insert(r);
  return Status::Ok();
}

Result<std::string> RegionStreams::Store(const std::string& payload, const std::string& msg_id,
                                         const std::string& digest,
                                         const std::vector<PartitionKey>& touched) {
  std::set<RegionKey> regions;
  for (PartitionKey p : touched) regions.insert(RegionOf(p, options_.region_partitions));
  const std::string copy_id = CopyMessageId(msg_id, digest);
  std::string copies;
  for (RegionKey r : regions) {
    if (Status s = Ensure(r); !s.ok()) return s;
    const std::string region = RegionName(r), subject = kSubjectPrefix + region;
    const std::string stream = StreamName(region);
    jsPubOptions po;
    jsPubOptions_Init(&po);
    po.MsgId = copy_id.c_str();
    po.ExpectStream = stream.c_str();
    jsPubAck* ack_raw = nullptr;
    jsErrCode jerr = static_cast<jsErrCode>(0);
    const natsStatus st = RetryWhileElecting(
        [&] {
          jsPubAck_Destroy(ack_raw);
          ack_raw = nullptr;
          return js_Publish(&ack_raw, nats_.jetstream(), subject.c_str(), payload.data(),
                            static_cast<int>(payload.size()), &po, &jerr);
        },
        kElectionMs);
    NatsPtr<jsPubAck> ack(ack_raw);
    if (st != NATS_OK) {
      return Status::Unavailable(
          NatsStatus(st, "the scan not stored in the region stream " + stream, jerr).message());
    }
    // A duplicate's ack names the copy stored first (the same bytes: its id holds the digest).
    if (!copies.empty()) copies += ' ';
    copies += region + ":" + std::to_string(ack->Sequence);
  }
  return copies;
}

namespace {

struct CopyRef {
  std::string region;
  uint64_t sequence = 0;
};

std::optional<std::vector<CopyRef>> ParseCopies(std::string_view copies) {
  std::vector<CopyRef> out;
  std::istringstream in{std::string(copies)};
  for (std::string item; in >> item;) {
    const size_t colon = item.find(':');
    if (colon == std::string::npos || colon == 0) return std::nullopt;
    CopyRef ref{item.substr(0, colon), 0};
    const char* first = item.data() + colon + 1;
    const char* last = item.data() + item.size();
    if (auto [end, ec] = std::from_chars(first, last, ref.sequence);
        ec != std::errc() || end != last || ref.sequence == 0) {
      return std::nullopt;
    }
    out.push_back(std::move(ref));
  }
  if (out.empty()) return std::nullopt;
  return out;
}

}  // namespace

Result<std::string> ReadCopy(const NatsClient& nats, std::string_view copies,
                             std::string_view msg_id, std::string_view digest,
                             std::optional<RegionKey> prefer) {
  std::optional<std::vector<CopyRef>> refs = ParseCopies(copies);
  if (!refs) return Status::DataLoss("the entry's payload copies header is malformed");
  if (prefer) {
    const std::string mine = RegionName(*prefer);
    std::stable_partition(refs->begin(), refs->end(),
                          [&](const CopyRef& r) { return r.region == mine; });
  }
  const std::string want_id = CopyMessageId(msg_id, digest);
  Status unavailable = Status::Ok();
  std::string why;
  for (const CopyRef& ref : *refs) {
    const std::string stream = StreamName(ref.region);
    natsMsg* raw = nullptr;
    // A direct get: the message's own bytes and headers (the stream API's answer would carry
    // them base64-encoded in JSON, a third more on the wire), from any of the stream's replicas.
    jsDirectGetMsgOptions get;
    jsDirectGetMsgOptions_Init(&get);
    get.Sequence = ref.sequence;
    const natsStatus st = RetryWhileElecting(
        [&] {
          natsMsg_Destroy(raw);
          raw = nullptr;
          return js_DirectGetMsg(&raw, nats.jetstream(), stream.c_str(), nullptr, &get);
        },
        kElectionMs);
    NatsPtr<natsMsg> msg(raw);
    if (st == NATS_NOT_FOUND) {
      why = stream + " holds no message " + std::to_string(ref.sequence);
      continue;
    }
    if (st != NATS_OK) {
      unavailable = Status::Unavailable(
          NatsStatus(st, "read the copy " + std::to_string(ref.sequence) + " of " + stream)
              .message());
      continue;
    }
    const char* id = nullptr;
    const std::string_view data(natsMsg_GetData(msg.get()),
                                static_cast<size_t>(natsMsg_GetDataLength(msg.get())));
    if (natsMsgHeader_Get(msg.get(), kMsgIdHeader, &id) != NATS_OK || id == nullptr ||
        want_id != id || ClusterTrust::Digest(data) != digest) {
      why = stream + " message " + std::to_string(ref.sequence) + " is not the entry's payload";
      continue;
    }
    return std::string(data);
  }
  if (!unavailable.ok()) return unavailable;
  return Status::DataLoss("no copy of the entry's payload: " + why);
}

}  // namespace bgkmap::cluster
