#include "cluster/partition_replica.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "bgkmap/core/tile_summary.h"
#include "bgkmap/storage/tile_codec.h"
#include "bgkmap/v1/cluster.pb.h"

namespace bgkmap::cluster {
namespace {

// Past this, a fetch that asks for entries the replica has not applied yet is answered with an
// error: the asking node retries (another replica, or later).
constexpr int64_t kFetchWaitMs = 2000;

std::string FetchSubject(PartitionKey key) { return "bgkmap.tiles." + PartitionName(key); }

}  // namespace

std::string TileReplyMac(const ClusterTrust& trust, std::string_view subject,
                         std::string_view reply_to, std::string_view request,
                         std::string_view reply) {
  return trust.Sign({"bgkmap-tiles-1", subject, reply_to, request, reply});
}

bool TileReplyVerifies(const ClusterTrust& trust, std::string_view mac, std::string_view subject,
                       std::string_view reply_to, std::string_view request,
                       std::string_view reply) {
  return trust.Verify(mac, {"bgkmap-tiles-1", subject, reply_to, request, reply});
}

PartitionReplica::PartitionReplica(const NatsClient& nats, const ClusterTrust& trust,
                                   const PartitionLayout& layout, PartitionKey key,
                                   std::unique_ptr<TerrainMap> map, uint64_t serve_from,
                                   RobotSequenceRule rule,
                                   std::optional<PartitionCheckpoint> restored)
    : nats_(nats),
      trust_(trust),
      layout_(layout),
      key_(key),
      halo_(layout.HaloCells(key)),
      serve_from_(serve_from),
      map_(std::move(map)),
      sequence_rule_(rule) {
  if (restored) {
    for (auto& [k, tile] : restored->tiles) map_->SetTile(k, *tile);
    robot_last_ = std::move(restored->robot_sequences);
    applied_ = restored_from_ = checkpointed_sequence_ = restored->log_sequence;
  }
  if (applied_ >= serve_from_) StartServing();
}

std::optional<PartitionCheckpoint> PartitionReplica::CheckpointIfDue(uint32_t every_scans,
                                                                     uint32_t lag_entries) {
  uint64_t integrated = 0;
  PartitionCheckpoint c;
  {
    std::lock_guard progress(progress_mu_);
    integrated = scans_integrated_;
    c.log_sequence = applied_;
  }
  const bool by_scans = every_scans > 0 && integrated - checkpointed_scans_ >= every_scans;
  const bool by_lag = lag_entries > 0 && c.log_sequence - checkpointed_sequence_ >= lag_entries;
  if (!by_scans && !by_lag) return std::nullopt;
  checkpointed_scans_ = integrated;
  checkpointed_sequence_ = c.log_sequence;
  c.robot_sequences = robot_last_;
  std::shared_lock map_lock(map_mu_);
  map_->ForEachTile(
      [&](TileKey k, const Tile& t) { c.tiles.emplace_back(k, std::make_unique<Tile>(t)); });
  std::sort(c.tiles.begin(), c.tiles.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  return c;
}

void PartitionReplica::BeginStop() {
  {
    // A fetch waiting for entries this replica will not read now is answered (refused) at once:
    // the drain below ends when the queued fetches are answered, not 2 s per fetch later.
    std::lock_guard progress(progress_mu_);
    stopping_ = true;
    progress_cv_.notify_all();
  }
  std::lock_guard serve(serve_mu_);
  if (stopped_) return;
  stopped_ = true;
  if (fetch_sub_) fetch_sub_->BeginStop();
}

PartitionReplica::~PartitionReplica() {
  BeginStop();
  std::unique_ptr<AsyncSubscription> sub;
  {
    std::lock_guard serve(serve_mu_);
    sub = std::move(fetch_sub_);
  }
  sub.reset();  // waits for the fetch handler's last return (it takes no lock of serve_mu_)
}

uint64_t PartitionReplica::applied() const {
  std::lock_guard progress(progress_mu_);
  return applied_;
}

bool PartitionReplica::Admit(uint64_t /*sequence*/, const LogEntryHeader& header, bool revised) {
  auto it = robot_last_.find(header.robot_id);
  const std::optional<uint64_t> last =
      it == robot_last_.end() ? std::nullopt : std::optional<uint64_t>(it->second);
  if (sequence_rule_.Judge(last, header.robot_sequence, robot_last_.size()) !=
      RobotAdmission::kAdmitted) {
    return false;
  }
  robot_last_[header.robot_id] = header.robot_sequence;
  return revised || std::binary_search(header.touched.begin(), header.touched.end(), key_);
}

void PartitionReplica::AdoptRebuilt(PartitionReplica& rebuilt, uint64_t sequence,
                                    const std::vector<TileKey>& affected) {
  std::unique_ptr<TerrainMap> map;
  {
    std::unique_lock theirs(rebuilt.map_mu_);
    map = std::move(rebuilt.map_);
  }
  std::unique_lock map_lock(map_mu_);
  map_ = std::move(map);
  StampAndAdvance(map_lock, sequence, affected);
}

void PartitionReplica::StampLocked(uint64_t sequence, const std::vector<TileKey>& affected) {
  const GridGeometry& g = layout_.geometry();
  const TileKey lo = g.TileOf(halo_.min), hi = g.TileOf(halo_.max);
  for (int x = lo.x; x <= hi.x; ++x) {
    for (int y = lo.y; y <= hi.y; ++y) {
      Tile* tile = map_->FindMutableTile({x, y});
      if (tile != nullptr && std::binary_search(affected.begin(), affected.end(), TileKey{x, y})) {
        tile->set_version(sequence);
      }
    }
  }
}

void PartitionReplica::ApplyStamp(uint64_t sequence, const std::vector<TileKey>& affected) {
  std::unique_lock map_lock(map_mu_);
  StampAndAdvance(map_lock, sequence, affected);
}

void PartitionReplica::StampAndAdvance(std::unique_lock<std::shared_mutex>& map_lock,
                                       uint64_t sequence, const std::vector<TileKey>& affected) {
  StampLocked(sequence, affected);
  {
    // Under the map's lock: a reader sees the tiles and stamps with the entry's sequence.
    std::lock_guard progress(progress_mu_);
    applied_ = sequence;
    progress_cv_.notify_all();
  }
  map_lock.unlock();
  if (!serving_ && sequence >= serve_from_) StartServing();
}

void PartitionReplica::Apply(uint64_t sequence, const PreparedScan* prepared) {
  std::unique_lock map_lock(map_mu_, std::defer_lock);
  bool integrated = false;
  if (prepared != nullptr) {
    const PreparedScan restricted = RestrictScan(map_->params(), *prepared, halo_);
    if (!restricted.cells.empty()) {
      map_lock.lock();
      const TileWindow window = map_->MakeWindow(restricted);
      map_->Integrate(restricted, window, sequence);
      integrated = true;
    }
  }
  {
    // Under the map's lock when it changed: a reader sees the tiles and their sequence together.
    std::lock_guard progress(progress_mu_);
    applied_ = sequence;
    if (integrated) ++scans_integrated_;
    progress_cv_.notify_all();
  }
  if (map_lock.owns_lock()) map_lock.unlock();
  if (!serving_ && sequence >= serve_from_) StartServing();
}

void PartitionReplica::ApplyRetire(uint64_t sequence, const std::string& robot_id) {
  robot_last_.erase(robot_id);
  Apply(sequence, nullptr);
}

void PartitionReplica::ApplyExport(uint64_t sequence) {
  auto copy = std::make_shared<std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>>();
  {
    std::shared_lock map_lock(map_mu_);
    const TileKey lo = layout_.MinTile(key_), hi = layout_.MaxTile(key_);
    map_->ForEachTile([&](TileKey k, const Tile& t) {
      if (k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y) {
        copy->emplace_back(k, std::make_unique<Tile>(t));
      }
    });
  }
  std::sort(copy->begin(), copy->end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  {
    std::lock_guard lock(snapshots_mu_);
    snapshots_[sequence] = std::move(copy);
    while (snapshots_.size() > kKeptSnapshots) snapshots_.erase(snapshots_.begin());
  }
  Apply(sequence, nullptr);
}

void PartitionReplica::ServeSnapshot(const v1::TileFetchRequest& request, TileKey lo, TileKey hi,
                                     int64_t budget, v1::TileFetchReply* reply) const {
  std::shared_ptr<const std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>> tiles;
  {
    std::lock_guard lock(snapshots_mu_);
    auto it = snapshots_.find(request.at_log_sequence());
    if (it != snapshots_.end()) tiles = it->second;
  }
  if (tiles == nullptr) {
    reply->set_error("partition " + PartitionName(key_) + " has no snapshot at log entry " +
                     std::to_string(request.at_log_sequence()) +
                     " (taken over since, or too many exports since)");
    return;
  }
  reply->set_log_sequence(request.at_log_sequence());
  int64_t bytes = 0;
  uint32_t skipped = 0;
  for (const auto& [k, tile] : *tiles) {
    if (k.x < lo.x || k.x > hi.x || k.y < lo.y || k.y > hi.y) continue;
    if (skipped < request.skip()) {
      ++skipped;
      continue;
    }
    std::string encoded = storage::EncodeTile(*tile);
    if (bytes + static_cast<int64_t>(encoded.size()) + 16 > budget && reply->keys_size() > 0) {
      reply->set_more(true);
      return;
    }
    bytes += static_cast<int64_t>(encoded.size()) + 16;
    v1::TileKey* key = reply->add_keys();
    key->set_x(k.x);
    key->set_y(k.y);
    reply->add_tiles(std::move(encoded));
  }
}

void PartitionReplica::ApplyClear(uint64_t sequence, const CellBox& box) {
  CellBox cut;
  cut.min = {std::max(box.min.x, halo_.min.x), std::max(box.min.y, halo_.min.y)};
  cut.max = {std::min(box.max.x, halo_.max.x), std::min(box.max.y, halo_.max.y)};
  std::unique_lock map_lock(map_mu_);
  if (!cut.empty()) map_->ClearBox(cut, sequence);
  {
    std::lock_guard progress(progress_mu_);
    applied_ = sequence;
    progress_cv_.notify_all();
  }
  map_lock.unlock();
  if (!serving_ && sequence >= serve_from_) StartServing();
}

void PartitionReplica::ApplyImport(
    uint64_t sequence, const std::vector<std::pair<TileKey, std::unique_ptr<Tile>>>& tiles) {
  const GridGeometry& g = layout_.geometry();
  const TileKey lo = g.TileOf(halo_.min), hi = g.TileOf(halo_.max);
  std::unique_lock map_lock(map_mu_);
  for (const auto& [key, tile] : tiles) {
    if (key.x < lo.x || key.x > hi.x || key.y < lo.y || key.y > hi.y) continue;
    map_->AddTile(key, *tile);
    map_->FindMutableTile(key)->set_version(sequence);
  }
  {
    std::lock_guard progress(progress_mu_);
    applied_ = sequence;
    progress_cv_.notify_all();
  }
  map_lock.unlock();
  if (!serving_ && sequence >= serve_from_) StartServing();
}

void PartitionReplica::StartServing() {
  std::lock_guard serve(serve_mu_);
  if (stopped_ || serving_) return;
  Result<std::unique_ptr<AsyncSubscription>> sub = AsyncSubscription::Start(
      nats_.connection(), FetchSubject(key_), "owners", [this](natsMsg* m) {
        NatsPtr<natsMsg> owned(m);
        ServeFetch(m);
      });
  if (!sub.ok()) {
    // Tried again after the next entry (or by the reader when idle).
    spdlog::warn("event=partition_serve_failed partition={} reason=\"{}\"", PartitionName(key_),
                 sub.status().message());
    return;
  }
  fetch_sub_ = std::move(sub).value();
  {
    std::lock_guard progress(progress_mu_);
    catch_up_seconds_ =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - created_).count();
  }
  serving_ = true;
  spdlog::info("event=partition_serving partition={} log_sequence={} catch_up_s={:.3f}",
               PartitionName(key_), serve_from_, catch_up_seconds_);
}

void PartitionReplica::ServeFetch(natsMsg* msg) {
  const char* reply_to = natsMsg_GetReply(msg);
  if (reply_to == nullptr) return;
  v1::TileFetchRequest request;
  v1::TileFetchReply reply;
  if (!request.ParseFromArray(natsMsg_GetData(msg), natsMsg_GetDataLength(msg))) {
    reply.set_error("tile fetch: the request does not decode");
  } else if (!WaitFor(std::max(request.min_log_sequence(), request.at_log_sequence()),
                      kFetchWaitMs)) {
    reply.set_error("partition " + PartitionName(key_) + " has read the log up to " +
                    std::to_string(Stats().log_sequence) + ", not yet " +
                    std::to_string(request.min_log_sequence()));
  } else {
    TileKey lo{std::max(request.min().x(), layout_.MinTile(key_).x),
               std::max(request.min().y(), layout_.MinTile(key_).y)};
    const TileKey hi{std::min(request.max().x(), layout_.MaxTile(key_).x),
                     std::min(request.max().y(), layout_.MaxTile(key_).y)};
    const int64_t budget = nats_.max_payload() - 4096;
    int64_t bytes = 0;
    uint32_t skipped = 0;
    if (request.at_log_sequence() != 0) {
      ServeSnapshot(request, lo, hi, budget, &reply);
      lo = {hi.x + 1, hi.y + 1};  // served: nothing from the live map
    }
    std::shared_lock map_lock(map_mu_);
    if (request.at_log_sequence() == 0) {
      std::lock_guard progress(progress_mu_);
      reply.set_log_sequence(applied_);
    }
    if (request.summary_only()) {
      SummarizeInto(lo, hi, reply.mutable_summary());
      lo = {hi.x + 1, hi.y + 1};  // nothing more: no keys, no tiles
    }
    for (int x = lo.x; x <= hi.x && !reply.more(); ++x) {
      for (int y = lo.y; y <= hi.y; ++y) {
        const Tile* tile = map_->FindTile({x, y});
        if (tile == nullptr) continue;
        if (skipped < request.skip()) {
          ++skipped;
          continue;
        }
        std::string encoded = request.keys_only() ? std::string() : storage::EncodeTile(*tile);
        if (bytes + static_cast<int64_t>(encoded.size()) + 16 > budget && reply.keys_size() > 0) {
          reply.set_more(true);
          break;
        }
        bytes += static_cast<int64_t>(encoded.size()) + 16;
        v1::TileKey* k = reply.add_keys();
        k->set_x(x);
        k->set_y(y);
        if (!request.keys_only()) reply.add_tiles(std::move(encoded));
      }
    }
  }
  const std::string out = reply.SerializeAsString();
  natsMsg* raw = nullptr;
  if (natsMsg_Create(&raw, reply_to, nullptr, out.data(), static_cast<int>(out.size())) !=
      NATS_OK) {
    return;  // the asker retries
  }
  NatsPtr<natsMsg> answer(raw);
  if (trust_.keyed()) {
    const std::string mac = TileReplyMac(
        trust_, natsMsg_GetSubject(msg), reply_to,
        std::string_view(natsMsg_GetData(msg), static_cast<size_t>(natsMsg_GetDataLength(msg))),
        out);
    if (natsMsgHeader_Set(answer.get(), kTileReplyMacHeader, mac.c_str()) != NATS_OK) return;
  }
  natsConnection_PublishMsg(nats_.connection(), answer.get());
}

void PartitionReplica::SummarizeInto(TileKey lo, TileKey hi, v1::PartitionSummary* out) const {
  // Requires map_mu_ (shared). The tiles of the range that exist, as Info counts them.
  CellBox bounds;
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    if (k.x < lo.x || k.x > hi.x || k.y < lo.y || k.y > hi.y) return;
    const TileSummary summary = SummarizeTile(layout_.geometry(), k, &t);
    if (summary.known_cells == 0) return;
    out->set_known_tiles(out->known_tiles() + 1);
    out->set_known_cells(out->known_cells() + summary.known_cells);
    bounds.Extend(summary.known_box.min);
    bounds.Extend(summary.known_box.max);
  });
  if (bounds.empty()) return;
  v1::CellBox* box = out->mutable_known_cells_box();
  box->set_min_x(bounds.min.x);
  box->set_min_y(bounds.min.y);
  box->set_max_x(bounds.max.x);
  box->set_max_y(bounds.max.y);
}

bool PartitionReplica::WaitFor(uint64_t sequence, int64_t timeout_ms) const {
  std::unique_lock lock(progress_mu_);
  progress_cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                        [&] { return applied_ >= sequence || stopping_; });
  return applied_ >= sequence;
}

ReplicaStats PartitionReplica::Stats() const {
  ReplicaStats s;
  s.key = key_;
  {
    std::lock_guard progress(progress_mu_);
    s.log_sequence = applied_;
    s.scans_integrated = scans_integrated_;
    s.catch_up_seconds = catch_up_seconds_;
  }
  s.serving = serving_;
  s.restored_from = restored_from_;
  std::shared_lock map_lock(map_mu_);
  s.tiles = map_->tile_count();
  return s;
}

std::unique_ptr<TerrainMap> PartitionReplica::Snapshot() const {
  std::unique_ptr<TerrainMap> out = TerrainMap::Create(map_->params()).value();
  std::shared_lock map_lock(map_mu_);
  const TileKey lo = layout_.MinTile(key_), hi = layout_.MaxTile(key_);
  map_->ForEachTile([&](TileKey k, const Tile& t) {
    if (k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y) out->SetTile(k, t);
  });
  return out;
}

}  // namespace bgkmap::cluster
