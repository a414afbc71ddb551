#include "bgkmap/storage/free_space.h"

#include <sys/statvfs.h>

#include <cerrno>
#include <cstring>

namespace bgkmap::storage {
namespace {

std::string Megabytes(uint64_t bytes) {
  // One decimal: a reserve of a few MB must not read "0 MB free".
  const uint64_t tenths = (bytes * 10 + (1 << 19)) >> 20;
  return std::to_string(tenths / 10) + "." + std::to_string(tenths % 10) + " MB";
}

}  // namespace

Result<uint64_t> StatvfsFreeBytes(const std::string& path) {
  struct statvfs st;
  if (statvfs(path.c_str(), &st) != 0) {
    return Status::IoError("cannot read the free space of " + path + ": " + std::strerror(errno));
  }
  return static_cast<uint64_t>(st.f_bavail) * static_cast<uint64_t>(st.f_frsize);
}

FreeSpaceGuard::FreeSpaceGuard(std::string path, FreeSpaceOptions options)
    : path_(std::move(path)), options_(std::move(options)) {}

std::chrono::steady_clock::time_point FreeSpaceGuard::Now() const {
  return options_.clock ? options_.clock() : std::chrono::steady_clock::now();
}

Status FreeSpaceGuard::RefreshLocked(bool force) {
  const auto now = Now();
  if (!force && probed_ && admitted_since_probe_ < options_.refresh_bytes &&
      now - probed_at_ < std::chrono::milliseconds(options_.refresh_ms)) {
    return Status::Ok();
  }
  Result<uint64_t> free = options_.probe ? options_.probe(path_) : StatvfsFreeBytes(path_);
  if (!free.ok()) return free.status();
  probed_ = true;
  probed_at_ = now;
  probed_free_ = *free;
  admitted_since_probe_ = 0;
  return Status::Ok();
}

void FreeSpaceGuard::SetPendingBytes(std::function<uint64_t()> pending) {
  std::lock_guard lock(mu_);
  pending_ = std::move(pending);
}

uint64_t FreeSpaceGuard::FreeLocked() const {
  const uint64_t used = admitted_since_probe_ + (pending_ ? pending_() : 0);
  return probed_free_ > used ? probed_free_ - used : 0;
}

Status FreeSpaceGuard::DecideLocked(uint64_t bytes, bool freeing) {
  const uint64_t free = FreeLocked();
  // What statvfs shows is more than `free` by what RocksDB will flush: say so, or the operator
  // reads "12 MB free" beside a df that says 40.
  const uint64_t pending = pending_ ? pending_() : 0;
  const std::string free_text =
      Megabytes(free) + " free" +
      (pending > 0 ? " once the store's " + Megabytes(pending) + " in memory are flushed" : "");
  const uint64_t floor = freeing ? options_.reserve_bytes / 2 : options_.reserve_bytes;
  const bool admitted = free >= bytes && free - bytes >= floor;
  if (!freeing) below_ = !admitted;
  if (admitted) {
    admitted_since_probe_ += bytes;
    return Status::Ok();
  }
  if (freeing) {
    return Status::IoError("data dir " + path_ + " has " + free_text +
                           ", below half the reserve of " + Megabytes(options_.reserve_bytes) +
                           " (storage.min_free_space_mb), which even a write that frees space "
                           "must leave to the store");
  }
  return Status::IoError("data dir " + path_ + " has " + free_text + ", below the reserve of " +
                         Megabytes(options_.reserve_bytes) +
                         " (storage.min_free_space_mb); writes resume when space is freed");
}

Status FreeSpaceGuard::Admit(uint64_t bytes) { return AdmitAs(bytes, /*freeing=*/false); }

Status FreeSpaceGuard::AdmitFreeing(uint64_t bytes) { return AdmitAs(bytes, /*freeing=*/true); }

Status FreeSpaceGuard::AdmitAs(uint64_t bytes, bool freeing) {
  if (!enabled()) return Status::Ok();
  std::lock_guard lock(mu_);
  // Refused writes admit nothing, so a paused writer would not re-probe by bytes: while below
  // the reserve, the time rule alone brings the answer up to date.
  if (Status s = RefreshLocked(/*force=*/false); !s.ok()) {
    below_ = true;  // unknown counts as full: RocksDB must not find out by writing
    return s;
  }
  return DecideLocked(bytes, freeing);
}

Status FreeSpaceGuard::Check() {
  if (!enabled()) return Status::Ok();
  std::lock_guard lock(mu_);
  if (Status s = RefreshLocked(/*force=*/true); !s.ok()) {
    below_ = true;
    return s;
  }
  return DecideLocked(0, /*freeing=*/false);
}

uint64_t FreeSpaceGuard::free_bytes() const {
  std::lock_guard lock(mu_);
  return FreeLocked();
}

bool FreeSpaceGuard::below_reserve() const {
  std::lock_guard lock(mu_);
  return below_;
}

}  // namespace bgkmap::storage
