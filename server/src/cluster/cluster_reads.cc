#include "cluster/cluster_reads.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include "bgkmap/storage/tile_codec.h"
#include "bgkmap/v1/cluster.pb.h"
#include "cluster/cluster_log.h"
#include "cluster/nats_subscription.h"
#include "cluster/partition_replica.h"
#include "serving/tile_table.h"

namespace bgkmap::cluster {
namespace {

// One request's wait for its reply; a partition being taken over is asked again until
// fetch_timeout_ms.
constexpr int64_t kRequestTimeoutMs = 3000;

struct InboxDeleter {
  void operator()(natsInbox* inbox) const { natsInbox_Destroy(inbox); }
};

}  // namespace

// One inbox for every fetch of this node ("_INBOX.<nuid>.<token>"), followed by one subscription
// for the node's life: replies are routed to the waiting fetch by their token, and a reply for a
// fetch no longer waiting is dropped. (No subscription per request: under a flood of forged
// replies, short-lived inbox subscriptions crashed nats.c 3.4 in this process.)
struct ClusterReads::Replies {
  std::string prefix;
  std::mutex mu;
  std::condition_variable cv;
  std::map<uint64_t, std::deque<NatsPtr<natsMsg>>> waiting;  // by token
  uint64_t next = 0;                                         // guarded by mu
  // Last: its handler (OnReply) uses the members above; its destruction waits for the handler.
  std::unique_ptr<AsyncSubscription> sub;

  void OnReply(natsMsg* msg) {
    NatsPtr<natsMsg> owned(msg);
    const std::string_view subject = natsMsg_GetSubject(msg);
    if (subject.size() <= prefix.size()) return;
    const std::string_view tail = subject.substr(prefix.size());
    uint64_t token = 0;
    if (auto [end, ec] = std::from_chars(tail.data(), tail.data() + tail.size(), token);
        ec != std::errc() || end != tail.data() + tail.size()) {
      return;
    }
    std::lock_guard lock(mu);
    auto it = waiting.find(token);
    if (it == waiting.end() || it->second.size() >= 64) return;
    it->second.push_back(std::move(owned));
    cv.notify_all();
  }
};

// The replies' subscription first (Replies' member order): its handler's last return is waited for.
ClusterReads::~ClusterReads() = default;

natsStatus ClusterReads::RequestTrusted(const std::string& subject, const std::string& request,
                                        NatsPtr<natsMsg>* reply) const {
  Replies& r = *replies_;
  if (!r.sub) return NATS_ERR;
  uint64_t token = 0;
  {
    std::lock_guard lock(r.mu);
    token = r.next++;
    r.waiting[token];
  }
  const std::string reply_to = r.prefix + std::to_string(token);
  natsStatus st =
      natsConnection_PublishRequest(nats_.connection(), subject.c_str(), reply_to.c_str(),
                                    request.data(), static_cast<int>(request.size()));
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(kRequestTimeoutMs);
  std::unique_lock lock(r.mu);
  std::deque<NatsPtr<natsMsg>>& queue = r.waiting[token];
  while (st == NATS_OK) {
    if (!r.cv.wait_until(lock, deadline, [&] { return !queue.empty(); })) {
      st = NATS_TIMEOUT;
      break;
    }
    NatsPtr<natsMsg> msg = std::move(queue.front());
    queue.pop_front();
    if (natsMsg_IsNoResponders(msg.get())) {
      st = NATS_NO_RESPONDERS;
      break;
    }
    const char* mac = nullptr;
    if (!trust_.keyed() ||
        (natsMsgHeader_Get(msg.get(), kTileReplyMacHeader, &mac) == NATS_OK && mac != nullptr &&
         TileReplyVerifies(
             trust_, mac, subject, reply_to, request,
             std::string_view(natsMsg_GetData(msg.get()),
                              static_cast<size_t>(natsMsg_GetDataLength(msg.get())))))) {
      *reply = std::move(msg);
      break;
    }
    trust_.Refuse(Untrusted::kTileReply, "a reply to a fetch of " + subject + " is not signed");
  }
  r.waiting.erase(token);
  return st;
}

ClusterReads::ClusterReads(const NatsClient& nats, const ClusterTrust& trust,
                           const PartitionLayout& layout, const Membership& members,
                           const MapParams& params, int64_t fetch_timeout_ms)
    : nats_(nats),
      trust_(trust),
      layout_(layout),
      members_(members),
      params_(params),
      fetch_timeout_ms_(fetch_timeout_ms),
      replies_(std::make_unique<Replies>()) {
  natsInbox* raw_inbox = nullptr;
  if (natsInbox_Create(&raw_inbox) == NATS_OK) {
    const std::unique_ptr<natsInbox, InboxDeleter> inbox(raw_inbox);
    replies_->prefix = std::string(inbox.get()) + ".";
    Result<std::unique_ptr<AsyncSubscription>> sub =
        AsyncSubscription::Start(nats_.connection(), replies_->prefix + "*", "",
                                 [r = replies_.get()](natsMsg* msg) { r->OnReply(msg); });
    if (sub.ok()) replies_->sub = std::move(sub).value();
  }
  if (!replies_->sub) spdlog::error("event=cluster_reads_no_inbox reason=\"cannot subscribe\"");
}

uint64_t ClusterReads::applied_version() const {
  Result<uint64_t> last = LastSequence(nats_);
  if (last.ok()) last_sequence_ = *last;
  return last_sequence_;
}

Status ClusterReads::FetchPartition(PartitionKey p, TileKey min, TileKey max, uint64_t sequence,
                                    TerrainMap& into, std::vector<TileKey>* keys,
                                    v1::PartitionSummary* summary, uint64_t at) const {
  const std::string subject = "bgkmap.tiles." + PartitionName(p);
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(fetch_timeout_ms_);
  v1::TileFetchRequest request;
  request.mutable_min()->set_x(min.x);
  request.mutable_min()->set_y(min.y);
  request.mutable_max()->set_x(max.x);
  request.mutable_max()->set_y(max.y);
  request.set_min_log_sequence(sequence);
  request.set_keys_only(keys != nullptr);
  request.set_summary_only(summary != nullptr);
  request.set_at_log_sequence(at);
  // A partition without data has no owner to ask (and anyone else on NATS may answer for it).
  if (Result<bool> has = members_.HasPartition(p); has.ok() && !*has) return Status::Ok();
  std::string why;
  while (true) {
    const std::string bytes = request.SerializeAsString();
    NatsPtr<natsMsg> reply_msg;
    const natsStatus st = RequestTrusted(subject, bytes, &reply_msg);
    v1::TileFetchReply reply;
    if (st == NATS_NO_RESPONDERS) {
      // Nobody serves it: a partition without data has nothing to serve; one with data is
      // being taken over.
      Result<bool> has = members_.HasPartition(p);
      if (has.ok() && !*has) return Status::Ok();
      why = has.ok() ? "no shard serves it" : has.status().message();
    } else if (st != NATS_OK) {
      why = natsStatus_GetText(st);
    } else if (!reply.ParseFromArray(natsMsg_GetData(reply_msg.get()),
                                     natsMsg_GetDataLength(reply_msg.get()))) {
      return Status::DataLoss("partition " + PartitionName(p) + ": the reply does not decode");
    } else if (!reply.error().empty()) {
      why = reply.error();
    } else if (summary != nullptr) {
      *summary = reply.summary();
      return Status::Ok();
    } else {
      if (keys != nullptr) {
        for (const v1::TileKey& k : reply.keys()) keys->push_back({k.x(), k.y()});
      } else if (reply.keys_size() != reply.tiles_size()) {
        return Status::DataLoss("partition " + PartitionName(p) + ": keys and tiles differ");
      }
      for (int i = 0; keys == nullptr && i < reply.keys_size(); ++i) {
        Result<std::unique_ptr<Tile>> tile = storage::DecodeTile(reply.tiles(i), params_.tile_size,
                                                                 KeepsPlaneMoments(params_.method));
        if (!tile.ok()) {
          return Status::DataLoss("partition " + PartitionName(p) + ": " + tile.status().message());
        }
        into.SetTile({reply.keys(i).x(), reply.keys(i).y()}, **tile);
      }
      if (!reply.more()) return Status::Ok();
      request.set_skip(request.skip() + static_cast<uint32_t>(reply.keys_size()));
      continue;
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      return Status::Unavailable("partition " + PartitionName(p) + ": " + why + " (waited " +
                                 std::to_string(fetch_timeout_ms_) + " ms)");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

Result<std::unique_ptr<TerrainMap>> ClusterReads::Gather(TileKey min, TileKey max,
                                                         uint64_t sequence) const {
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params_);
  if (!map.ok()) return map.status();
  const CellBox cells{layout_.geometry().TileBox(min).min, layout_.geometry().TileBox(max).max};
  for (PartitionKey p : layout_.Covering(cells)) {
    const TileKey lo{std::max(min.x, layout_.MinTile(p).x), std::max(min.y, layout_.MinTile(p).y)};
    const TileKey hi{std::min(max.x, layout_.MaxTile(p).x), std::min(max.y, layout_.MaxTile(p).y)};
    if (Status s = FetchPartition(p, lo, hi, sequence, **map); !s.ok()) return s;
  }
  return map;
}

Result<std::unique_ptr<TerrainMap>> ClusterReads::GatherAt(
    const std::vector<PartitionKey>& partitions, uint64_t at) const {
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params_);
  if (!map.ok()) return map.status();
  for (PartitionKey p : partitions) {
    if (Status s = FetchPartition(p, layout_.MinTile(p), layout_.MaxTile(p), at, **map, nullptr,
                                  nullptr, at);
        !s.ok()) {
      return s;
    }
  }
  return map;
}

Result<MapSummary> ClusterReads::Summarize(uint64_t sequence) const {
  MapSummary out;
  Result<std::unique_ptr<TerrainMap>> unused = TerrainMap::Create(params_);  // (no tiles come)
  if (!unused.ok()) return unused.status();
  for (PartitionKey p : members_.Partitions()) {
    v1::PartitionSummary s;
    if (Status st = FetchPartition(p, layout_.MinTile(p), layout_.MaxTile(p), sequence, **unused,
                                   nullptr, &s);
        !st.ok()) {
      return st;
    }
    out.tile_count += s.known_tiles();
    out.known_cells += s.known_cells();
    if (s.has_known_cells_box()) {
      const v1::CellBox& b = s.known_cells_box();
      out.known_bounds.Extend({b.min_x(), b.min_y()});
      out.known_bounds.Extend({b.max_x(), b.max_y()});
    }
  }
  return out;
}

Result<Raster> ClusterReads::ReadRegion(const CellBox& box, const std::vector<Layer>& layers,
                                        int stride) {
  Result<uint64_t> last = LastSequence(nats_);
  if (!last.ok()) return last.status();
  last_sequence_ = *last;
  const GridGeometry& g = layout_.geometry();
  Result<std::unique_ptr<TerrainMap>> map = Gather(g.TileOf(box.min), g.TileOf(box.max), *last);
  if (!map.ok()) return map.status();
  // The single server's own banded read, over the gathered tiles: the same answer, bit for bit.
  TileTable table(std::move(map).value(), /*keep_cleared=*/false);
  return table.ReadRegion(box, layers, stride);
}

Result<std::vector<CellEstimate>> ClusterReads::ReadCells(std::span<const CellIndex> cells) {
  Result<uint64_t> last = LastSequence(nats_);
  if (!last.ok()) return last.status();
  last_sequence_ = *last;
  const GridGeometry& g = layout_.geometry();
  // The tiles needed, as one range per partition.
  std::map<PartitionKey, std::pair<TileKey, TileKey>> ranges;
  for (CellIndex c : cells) {
    const TileKey t = g.TileOf(c);
    auto [it, is_new] = ranges.try_emplace(layout_.PartitionOf(t), t, t);
    if (!is_new) {
      it->second.first = {std::min(it->second.first.x, t.x), std::min(it->second.first.y, t.y)};
      it->second.second = {std::max(it->second.second.x, t.x), std::max(it->second.second.y, t.y)};
    }
  }
  Result<std::unique_ptr<TerrainMap>> map = TerrainMap::Create(params_);
  if (!map.ok()) return map.status();
  for (const auto& [p, range] : ranges) {
    if (Status s = FetchPartition(p, range.first, range.second, *last, **map); !s.ok()) return s;
  }
  std::vector<CellEstimate> out;
  out.reserve(cells.size());
  for (CellIndex c : cells) out.push_back((*map)->Estimate(c));
  return out;
}

Result<TileContent> ClusterReads::ReadTile(TileKey key, const std::vector<Layer>& layers) {
  Result<uint64_t> last = LastSequence(nats_);
  if (!last.ok()) return last.status();
  last_sequence_ = *last;
  Result<std::unique_ptr<TerrainMap>> map = Gather(key, key, *last);
  if (!map.ok()) return map.status();
  const bool exists = (*map)->FindTile(key) != nullptr;
  TileTable table(std::move(map).value(), /*keep_cleared=*/false);
  TileContent out;
  out.raster = table.ReadRegion(layout_.geometry().TileBox(key), layers, 1);
  out.version = exists ? *last : 0;
  return out;
}

Result<std::vector<TileKey>> ClusterReads::ListKnownTiles(TileKey min, TileKey max) {
  Result<uint64_t> last = LastSequence(nats_);
  if (!last.ok()) return last.status();
  last_sequence_ = *last;
  const GridGeometry& g = layout_.geometry();
  const CellBox cells{g.TileBox(min).min, g.TileBox(max).max};
  std::vector<TileKey> keys;
  Result<std::unique_ptr<TerrainMap>> unused = TerrainMap::Create(params_);
  if (!unused.ok()) return unused.status();
  for (PartitionKey p : layout_.Covering(cells)) {
    const TileKey lo{std::max(min.x, layout_.MinTile(p).x), std::max(min.y, layout_.MinTile(p).y)};
    const TileKey hi{std::min(max.x, layout_.MaxTile(p).x), std::min(max.y, layout_.MaxTile(p).y)};
    if (Status s = FetchPartition(p, lo, hi, *last, **unused, &keys); !s.ok()) return s;
  }
  std::sort(keys.begin(), keys.end());
  return keys;
}

}  // namespace bgkmap::cluster
