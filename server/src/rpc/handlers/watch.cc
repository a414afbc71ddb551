// Watch: streams changed tiles of a region. Coalescing lives in WatchHub; this reactor sends one
// tile at a time, reading its content only when the previous message has been written, so the
// backlog of a slow watcher is a set of tile keys and never a queue of messages.
#include <atomic>
#include <boost/asio/post.hpp>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "rpc/handlers/handlers.h"
#include "rpc/proto_convert.h"
#include "rpc/request_checks.h"

namespace bgkmap {
namespace {

class WatchStream final : public grpc::ServerWriteReactor<v1::TileUpdate>, public DrainListener {
 public:
  WatchStream(ServiceContext& ctx, grpc::CallbackServerContext* call, PrincipalRef who,
              const v1::WatchRequest& request)
      : ctx_(ctx), who_(std::move(who)), stalled_(call, ctx.limits.stalled_write_timeout_s) {
    if (grpc::Status s = Parse(request); !s.ok()) {
      Finish(s);
      return;
    }
    // One token holds at most its share of the server.max_watchers slots (issue 25).
    if (who_->usage != nullptr) {
      token_slot_.emplace(who_->usage->watchers, who_->max_watchers);
      if (!*token_slot_) {
        Finish(TokenQuotaReached(*who_, who_->max_watchers, "open watches",
                                 "server.auth.max_watchers_per_token"));
        return;
      }
    }
    const SessionRegistry::Admit admit =
        ctx_.sessions.Add(this, SessionRegistry::Kind::kWatch, ctx_.limits.max_watchers);
    if (admit != SessionRegistry::Admit::kOk) {
      Finish(
          admit == SessionRegistry::Admit::kDraining
              ? grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down")
              : grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                             "server.max_watchers = " + std::to_string(ctx_.limits.max_watchers) +
                                 " watchers are already subscribed"));
      return;
    }
    registered_ = true;
    // A watcher that stops reading gives its slot back.
    stalled_registered_ = ctx_.sessions.Add(&stalled_, SessionRegistry::Kind::kStream,
                                            UINT32_MAX) == SessionRegistry::Admit::kOk;
    id_ = ctx_.hub.Subscribe(min_, max_, [this] { Wake(); }, {});
    if (request.initial_snapshot()) {
      // Listed on the query pool (on a cluster it asks the partitions' owners), as the first
      // cycle; changes published meanwhile are pending already.
      {
        std::lock_guard lock(mu_);
        active_ = true;
      }
      boost::asio::post(ctx_.query_pool, [this] { ListInitial(); });
    } else {
      // A wake that ran before id_ was known found nothing to take: start a cycle now.
      Wake();
    }
  }

  void OnWriteDone(bool ok) override {
    stalled_.WriteDone();
    if (!ok) {
      Stop(grpc::Status(grpc::StatusCode::CANCELLED,
                        stalled_.cancelled() ? "watch cancelled: the client took no update for "
                                               "server.stalled_write_timeout_s"
                                             : "watch cancelled"),
           /*was_active=*/true);
      return;
    }
    boost::asio::post(ctx_.query_pool, [this] { SendNext(); });
  }

  void OnCancel() override {
    std::unique_lock lock(mu_);
    stopping_ = true;
    status_ = grpc::Status(grpc::StatusCode::CANCELLED, "watch cancelled");
    MaybeFinish(lock);
  }

  void BeginDrain() override {
    std::unique_lock lock(mu_);
    stopping_ = true;
    status_ = grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down");
    MaybeFinish(lock);
  }

  // A revoked token's watch ends within the watchdog period (an update being written first).
  void Tick(std::chrono::steady_clock::time_point /*now*/) override {
    if (!who_->Revoked()) return;
    std::unique_lock lock(mu_);
    if (stopping_) return;
    stopping_ = true;
    status_ = grpc::Status(grpc::StatusCode::UNAUTHENTICATED,
                           "token '" + who_->name +
                               "' revoked (server.auth.tokens_file reloaded): the watch is closed");
    MaybeFinish(lock);
  }

  void OnDone() override {
    if (stalled_registered_) ctx_.sessions.Remove(&stalled_);
    if (registered_) ctx_.sessions.Remove(this);
    delete this;
  }

 private:
  grpc::Status Parse(const v1::WatchRequest& request) {
    if (grpc::Status s = LayersFromProto(request.layers(), "layers", &layers_); !s.ok()) return s;
    CellBox cells;
    if (grpc::Status s = RegionCells(request.box(), "box", ctx_.map.geometry(), 1, ctx_.limits,
                                     /*limit_cells=*/false, &cells);
        !s.ok()) {
      return s;
    }
    min_ = ctx_.map.geometry().TileOf(cells.min);
    max_ = ctx_.map.geometry().TileOf(cells.max);
    const uint64_t tiles = static_cast<uint64_t>(int64_t{max_.x} - min_.x + 1) *
                           static_cast<uint64_t>(int64_t{max_.y} - min_.y + 1);
    if (tiles > ctx_.limits.max_watch_tiles) {
      return {grpc::StatusCode::INVALID_ARGUMENT, "box: " + std::to_string(tiles) +
                                                      " tiles exceed server.max_watch_tiles = " +
                                                      std::to_string(ctx_.limits.max_watch_tiles)};
    }
    return grpc::Status::OK;
  }

  // Called by the hub (under its lock): schedule a send cycle unless one is running.
  void Wake() {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    if (active_) {
      again_ = true;
      return;
    }
    active_ = true;
    boost::asio::post(ctx_.query_pool, [this] { SendNext(); });
  }

  // On the query pool, with active_ set: the tiles that exist in the box start pending.
  void ListInitial() {
    Result<std::vector<TileKey>> known = ctx_.map.ListKnownTiles(min_, max_);
    if (!known.ok()) {
      Stop(ToGrpcStatus(known.status()), /*was_active=*/true);
      return;
    }
    ctx_.hub.AddPending(id_, *known);
    SendNext();
  }

  // On the query pool, with active_ set: send the next pending tile or go idle.
  void SendNext() {
    TileKey key;
    bool stopping = false;
    {
      std::lock_guard lock(mu_);
      stopping = stopping_;
    }
    // Not under mu_: the hub calls Wake() (which takes mu_) with its own lock held.
    const bool have = !stopping && ctx_.hub.Take(id_, &key);
    {
      std::unique_lock lock(mu_);
      if (!have) {
        if (again_ && !stopping_) {
          again_ = false;
          lock.unlock();
          boost::asio::post(ctx_.query_pool, [this] { SendNext(); });
          return;
        }
        active_ = false;
        MaybeFinish(lock);
        return;
      }
    }
    const uint64_t version = ctx_.map.applied_version();
    Result<TileContent> read = ctx_.map.ReadTile(key, layers_);
    if (!read.ok()) {
      Stop(ToGrpcStatus(read.status()), /*was_active=*/true);
      return;
    }
    const TileContent& content = *read;
    update_.Clear();
    ToProto(key, update_.mutable_key());
    ToProto(content.raster.box, update_.mutable_cells());
    // A tile a clear emptied no longer exists: its last change is covered by the applied version.
    update_.set_tile_version(content.version != 0 ? content.version : version);
    update_.set_resolution(content.raster.resolution);
    update_.set_map_version(std::max(version, content.version));
    AppendRows(content.raster, 0, content.raster.rows, update_.mutable_layers());
    stalled_.WriteStarted();
    StartWrite(&update_);
  }

  void Stop(grpc::Status status, bool was_active) {
    std::unique_lock lock(mu_);
    stopping_ = true;
    if (status_.ok()) status_ = std::move(status);
    if (was_active) active_ = false;
    MaybeFinish(lock);
  }

  void MaybeFinish(std::unique_lock<std::mutex>& lock) {
    if (!stopping_ || active_ || finished_) return;
    finished_ = true;
    grpc::Status status = status_;
    lock.unlock();
    ctx_.hub.Unsubscribe(id_);  // no Wake() after this
    Finish(status);
  }

  ServiceContext& ctx_;
  const PrincipalRef who_;
  std::optional<Permit> token_slot_;  // one of the token's max_watchers, held until OnDone
  StalledWriteWatch stalled_;
  bool registered_ = false;
  bool stalled_registered_ = false;
  std::vector<Layer> layers_;
  TileKey min_, max_;
  std::atomic<uint64_t> id_{0};  // read by pool threads woken during Subscribe()
  v1::TileUpdate update_;

  std::mutex mu_;
  bool active_ = false;  // a send cycle is posted or a write is outstanding
  bool again_ = false;   // woken during a cycle
  bool stopping_ = false;
  bool finished_ = false;
  grpc::Status status_;
};

}  // namespace

grpc::ServerWriteReactor<v1::TileUpdate>* StartWatch(ServiceContext& ctx,
                                                     grpc::CallbackServerContext* call,
                                                     PrincipalRef who,
                                                     const v1::WatchRequest* request) {
  return new WatchStream(ctx, call, std::move(who), *request);
}

}  // namespace bgkmap
