#include "rpc/service_context.h"

#include <grpcpp/server_context.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <sstream>

#include "bgkmap/server/log_safe.h"

namespace bgkmap {

SessionRegistry::Admit SessionRegistry::Add(DrainListener* session, Kind kind, uint32_t limit) {
  std::lock_guard lock(mu_);
  if (draining_) return Admit::kDraining;
  size_t n = 0;
  for (const auto& [_, k] : sessions_) n += (k == kind);
  if (n >= limit) return Admit::kFull;
  sessions_.emplace(session, kind);
  return Admit::kOk;
}

void SessionRegistry::Remove(DrainListener* session) {
  std::lock_guard lock(mu_);
  sessions_.erase(session);
}

void SessionRegistry::DrainAll() {
  // Sessions unregister themselves from OnDone, which takes this lock: none can be destroyed
  // while we walk them.
  std::lock_guard lock(mu_);
  draining_ = true;
  for (const auto& [session, _] : sessions_) session->BeginDrain();
}

bool SessionRegistry::draining() const {
  std::lock_guard lock(mu_);
  return draining_;
}

size_t SessionRegistry::count(Kind kind) const {
  std::lock_guard lock(mu_);
  size_t n = 0;
  for (const auto& [_, k] : sessions_) n += (k == kind);
  return n;
}

void SessionRegistry::TickAll() {
  const auto now = std::chrono::steady_clock::now();
  std::lock_guard lock(mu_);
  for (const auto& [session, _] : sessions_) session->Tick(now);
}

void SessionRegistry::StartWatchdog(std::chrono::milliseconds period) {
  std::lock_guard lock(watchdog_mu_);
  if (watchdog_.joinable()) return;
  watchdog_stop_ = false;
  watchdog_ = std::thread([this, period] {
    std::unique_lock wait(watchdog_mu_);
    while (!watchdog_cv_.wait_for(wait, period, [this] { return watchdog_stop_; })) {
      wait.unlock();
      TickAll();
      wait.lock();
    }
  });
}

void SessionRegistry::StopWatchdog() {
  std::thread thread;
  {
    std::lock_guard lock(watchdog_mu_);
    watchdog_stop_ = true;
    thread = std::move(watchdog_);
  }
  watchdog_cv_.notify_all();
  if (thread.joinable()) thread.join();
}

std::chrono::steady_clock::duration TimeoutOf(double seconds) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(seconds));
}

std::string SecondsText(double seconds) {
  std::ostringstream s;
  s << seconds;
  return s.str();
}

StalledWriteWatch::StalledWriteWatch(grpc::CallbackServerContext* call, double timeout_s)
    : call_(call), timeout_(TimeoutOf(timeout_s)) {}

void StalledWriteWatch::WriteStarted() {
  write_since_.store(
      std::max<int64_t>(1, std::chrono::steady_clock::now().time_since_epoch().count()));
}

void StalledWriteWatch::WriteDone() { write_since_.store(0); }

void StalledWriteWatch::Tick(std::chrono::steady_clock::time_point now) {
  const int64_t since = write_since_.load();
  if (since == 0 || timeout_ == std::chrono::steady_clock::duration::zero() || cancelled_.load()) {
    return;
  }
  if (now.time_since_epoch().count() - since > timeout_.count()) {
    cancelled_.store(true);
    call_->TryCancel();  // the outstanding write fails; the reactor ends the call
  }
}

bool ByteBudget::TryAcquire(uint64_t bytes) {
  uint64_t used = used_.load();
  do {
    if (used + bytes > limit_) return false;
  } while (!used_.compare_exchange_weak(used, used + bytes));
  return true;
}

Permit::Permit(std::atomic<uint32_t>& counter, uint32_t limit) : counter_(&counter) {
  if (counter.fetch_add(1) >= limit) {
    counter.fetch_sub(1);
    counter_ = nullptr;
  }
}

Permit::~Permit() {
  if (counter_ != nullptr) counter_->fetch_sub(1);
}

grpc::Status QueriesBusy(const ServiceContext& ctx) {
  return {grpc::StatusCode::RESOURCE_EXHAUSTED,
          "server.max_concurrent_queries = " + std::to_string(ctx.limits.max_concurrent_queries) +
              " queries are already running; retry later"};
}

QueryPermit::QueryPermit(ServiceContext& ctx, const Principal& who) {
  global_.emplace(ctx.queries, ctx.limits.max_concurrent_queries);
  if (!*global_) {
    refusal_ = QueriesBusy(ctx);
    return;
  }
  if (who.usage == nullptr) return;
  token_.emplace(who.usage->queries, who.max_queries);
  if (!*token_) {
    refusal_ = TokenQuotaReached(who, who.max_queries, "concurrent queries",
                                 "server.auth.max_queries_per_token");
    global_.reset();
  }
}

grpc::Status TokenQuotaReached(const Principal& who, uint32_t limit, const std::string& what,
                               const std::string& key) {
  return {grpc::StatusCode::RESOURCE_EXHAUSTED,
          "token '" + who.name + "' already holds its limit of " + std::to_string(limit) + " " +
              what + " (" + key + " or the token's own limit); retry later"};
}

void AuditLog(const Principal& who, const std::string& action, const std::string& details,
              uint64_t map_version, const std::string& peer) {
  spdlog::info("event=audit who=\"{}\" role={} action={} {} map_version={} peer=\"{}\"", who.name,
               RoleName(who.role), action, details, map_version, LogSafe(peer));
}

}  // namespace bgkmap
