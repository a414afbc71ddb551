// Ingest: a robot's bidirectional scan stream.
//
// The stream reads ahead at most max_inflight_scans_per_stream scans; until acks free a slot no
// read is posted, so HTTP/2 flow control pushes back on the robot (no unbounded queue). Scans
// are prepared and admitted one at a time in stream order (sequence numbers stay ordered) while
// earlier ones integrate; acks go out in stream order.
#include <spdlog/spdlog.h>

#include <boost/asio/post.hpp>
#include <chrono>
#include <deque>
#include <mutex>
#include <optional>

#include "bgkmap/server/log_safe.h"
#include "rpc/handlers/handlers.h"
#include "rpc/handlers/ingest_pipeline.h"

namespace bgkmap {
namespace {

class IngestStream final : public grpc::ServerBidiReactor<v1::Scan, v1::ScanAck>,
                           public DrainListener {
 public:
  IngestStream(ServiceContext& ctx, grpc::CallbackServerContext* call, PrincipalRef who)
      : ctx_(ctx),
        who_(std::move(who)),
        call_(call),
        peer_(call->peer()),
        window_(ctx.limits.max_inflight_scans_per_stream),
        idle_timeout_(TimeoutOf(ctx.limits.ingest_idle_timeout_s)),
        stalled_timeout_(TimeoutOf(ctx.limits.stalled_write_timeout_s)),
        last_activity_(std::chrono::steady_clock::now()) {
    const SessionRegistry::Admit admit =
        ctx_.sessions.Add(this, SessionRegistry::Kind::kIngest, ctx_.limits.max_ingest_streams);
    if (admit != SessionRegistry::Admit::kOk) {
      finished_ = true;
      Finish(admit == SessionRegistry::Admit::kDraining
                 ? grpc::Status(grpc::StatusCode::UNAVAILABLE, "server is shutting down")
                 : grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                                "server.max_ingest_streams = " +
                                    std::to_string(ctx_.limits.max_ingest_streams) +
                                    " ingest streams are already open"));
      return;
    }
    registered_ = true;
    if (who_->usage != nullptr) {
      token_slot_.emplace(who_->usage->ingest_streams, who_->max_ingest_streams);
      if (!*token_slot_) {
        finished_ = true;
        Finish(TokenQuotaReached(*who_, who_->max_ingest_streams, "open ingest streams",
                                 "server.auth.max_ingest_streams_per_token"));
        return;
      }
    }
    spdlog::debug("event=ingest_open peer=\"{}\"", LogSafe(peer_));
    std::unique_lock lock(mu_);
    Step(lock);
  }

  void OnReadDone(bool ok) override {
    std::unique_lock lock(mu_);
    reading_ = false;
    last_activity_ = std::chrono::steady_clock::now();
    if (finished_) return;  // a read that was pending when the call ended
    if (!ok) {
      read_closed_ = true;
    } else {
      Slot& slot = slots_.emplace_back();
      if (draining_ || broken_) {
        // Read after the drain began: answered, never applied.
        slot.ack =
            RejectedAck(ctx_, incoming_,
                        revoked_ ? RevokedStatus("scan not applied")
                                 : grpc::Status(grpc::StatusCode::UNAVAILABLE,
                                                "server is shutting down: scan not applied"));
        slot.ready = true;
      } else {
        to_prepare_.push_back({std::move(incoming_), &slot});
        if (!preparing_) {
          preparing_ = true;
          boost::asio::post(ctx_.ingest_pool, [this] { PrepareLoop(); });
        }
      }
      incoming_.Clear();
    }
    Step(lock);
  }

  void OnWriteDone(bool ok) override {
    std::unique_lock lock(mu_);
    writing_ = false;
    last_activity_ = std::chrono::steady_clock::now();
    slots_.pop_front();
    if (!ok) broken_ = true;
    Step(lock);
  }

  void OnCancel() override {
    std::unique_lock lock(mu_);
    broken_ = true;
    Step(lock);
  }

  void OnDone() override {
    if (registered_) ctx_.sessions.Remove(this);
    delete this;
  }

  void BeginDrain() override {
    std::unique_lock lock(mu_);
    draining_ = true;
    Step(lock);
  }

  // An idle stream (waiting for a scan, nothing in flight) ends with DEADLINE_EXCEEDED after
  // server.ingest_idle_timeout_s; a client that takes no ack for server.stalled_write_timeout_s
  // is cancelled (its scans still apply). Either way the stream's slot is free again.
  void Tick(std::chrono::steady_clock::time_point now) override {
    std::unique_lock lock(mu_);
    if (finished_) return;
    if (who_->Revoked() && !revoked_) {
      // The token was revoked: no more reads; what was read is answered, then the call ends.
      revoked_ = true;
      draining_ = true;
      Step(lock);
      return;
    }
    const auto zero = std::chrono::steady_clock::duration::zero();
    if (writing_ && !broken_ && stalled_timeout_ != zero &&
        now - last_activity_ > stalled_timeout_) {
      broken_ = true;
      stalled_ = true;
      lock.unlock();
      call_->TryCancel();  // the outstanding write fails: OnWriteDone ends the call
      return;
    }
    const bool idle = reading_ && !writing_ && slots_.empty() && to_prepare_.empty() &&
                      !preparing_ && !draining_ && !broken_ && !idle_;
    if (idle && idle_timeout_ != zero && now - last_activity_ > idle_timeout_) {
      idle_ = true;
      Step(lock);
    }
  }

 private:
  struct Slot {
    v1::ScanAck ack;
    bool ready = false;
  };
  struct Pending {
    v1::Scan scan;
    Slot* slot;
  };

  // Prepares and admits queued scans in order, on the ingest pool.
  void PrepareLoop() {
    for (;;) {
      Pending next;
      {
        std::unique_lock lock(mu_);
        if (to_prepare_.empty()) {
          preparing_ = false;
          Step(lock);  // may finish the call: nothing touches `this` afterwards
          return;
        }
        next = std::move(to_prepare_.front());
        to_prepare_.pop_front();
      }
      Slot* slot = next.slot;
      IngestScanMessage(ctx_, *who_, next.scan, [this, slot](v1::ScanAck ack, grpc::Status) {
        std::unique_lock lock(mu_);
        ++counts_[ack.status()];
        slot->ack = std::move(ack);
        slot->ready = true;
        Step(lock);
      });
    }
  }

  // Decides the next operations under the lock, then starts them without it. Finish is always
  // the last thing done: OnDone may delete `this` as soon as it is called.
  void Step(std::unique_lock<std::mutex>& lock) {
    if (finished_) return;
    const v1::ScanAck* write = nullptr;
    bool read = false;
    bool finish = false;
    grpc::Status status;
    if (broken_) {
      // The client is gone: acks cannot be delivered (its scans still apply).
      while (!writing_ && !slots_.empty() && slots_.front().ready) slots_.pop_front();
    }
    if (!writing_ && !broken_ && !slots_.empty() && slots_.front().ready) {
      writing_ = true;
      last_activity_ = std::chrono::steady_clock::now();  // the stalled-write clock starts
      write = &slots_.front().ack;
    }
    if (!reading_ && !read_closed_ && !draining_ && !broken_ && !idle_ && slots_.size() < window_) {
      reading_ = true;
      read = true;
    }
    const bool no_more_input = read_closed_ || draining_ || broken_ || idle_;
    if (no_more_input && slots_.empty() && !preparing_ && !writing_) {
      finished_ = true;
      finish = true;
      if (broken_) {
        status = grpc::Status(grpc::StatusCode::CANCELLED,
                              stalled_ ? "stream cancelled: the client took no ack for "
                                         "server.stalled_write_timeout_s"
                                       : "stream cancelled");
      } else if (idle_ && !read_closed_) {
        status = grpc::Status(grpc::StatusCode::DEADLINE_EXCEEDED,
                              "no scan for server.ingest_idle_timeout_s = " +
                                  SecondsText(ctx_.limits.ingest_idle_timeout_s) +
                                  " s: the idle stream is closed; open a new one to send more");
      } else if (revoked_) {
        status = RevokedStatus("the stream is closed");
      } else if (draining_ && !read_closed_) {
        status = grpc::Status(grpc::StatusCode::UNAVAILABLE,
                              "server is shutting down: every scan read was acknowledged");
      }
    }
    if (finish) {
      spdlog::info(
          "event=ingest_closed peer=\"{}\" applied={} duplicate={} rejected={} code={} "
          "reason=\"{}\"",
          LogSafe(peer_), counts_[v1::ACK_APPLIED], counts_[v1::ACK_DUPLICATE],
          counts_[v1::ACK_REJECTED], static_cast<int>(status.error_code()),
          LogSafe(status.error_message()));
    }
    lock.unlock();
    if (write != nullptr) StartWrite(write);
    if (read) StartRead(&incoming_);
    if (finish) Finish(status);
  }

  grpc::Status RevokedStatus(const std::string& what) const {
    return grpc::Status(
        grpc::StatusCode::UNAUTHENTICATED,
        "token '" + who_->name + "' revoked (server.auth.tokens_file reloaded): " + what);
  }

  ServiceContext& ctx_;
  const PrincipalRef who_;
  std::optional<Permit> token_slot_;  // one of the token's max_ingest_streams
  grpc::CallbackServerContext* const call_;
  const std::string peer_;
  const size_t window_;
  const std::chrono::steady_clock::duration idle_timeout_;
  const std::chrono::steady_clock::duration stalled_timeout_;
  bool registered_ = false;

  std::mutex mu_;
  v1::Scan incoming_;
  std::deque<Slot> slots_;  // read and not yet acked, in stream order (stable addresses)
  std::deque<Pending> to_prepare_;
  bool reading_ = false;
  bool writing_ = false;
  bool preparing_ = false;
  bool read_closed_ = false;
  bool draining_ = false;
  bool revoked_ = false;  // draining because the token was revoked (Tick)
  bool broken_ = false;
  bool finished_ = false;
  bool idle_ = false;     // closed for idling (server.ingest_idle_timeout_s)
  bool stalled_ = false;  // cancelled: the client took no ack (server.stalled_write_timeout_s)
  std::chrono::steady_clock::time_point last_activity_;  // last read or write completed
  uint64_t counts_[4] = {0, 0, 0, 0};                    // acks by AckStatus
};

}  // namespace

grpc::ServerBidiReactor<v1::Scan, v1::ScanAck>* StartIngestStream(ServiceContext& ctx,
                                                                  grpc::CallbackServerContext* call,
                                                                  PrincipalRef who) {
  return new IngestStream(ctx, call, std::move(who));
}

}  // namespace bgkmap
