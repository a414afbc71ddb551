#include "rpc/service_context.h"

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

}  // namespace bgkmap
