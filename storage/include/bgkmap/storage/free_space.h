// A free-space reserve on the store's file system: writes are refused while fewer bytes than the
// reserve would stay free, so that RocksDB never meets a full disk itself (Debian's RocksDB 7.8
// asserts after a write-ahead log write fails with ENOSPC; docs/storage.md, "Faults").
//
// Cheap enough for every append: the free space is probed (statvfs) at most every refresh_ms or
// after refresh_bytes were admitted since the last probe; in between, the bytes admitted since the
// probe are subtracted from what it found. Thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

#include "bgkmap/core/status.h"

namespace bgkmap::storage {

// Bytes an unprivileged writer may still use on the file system holding `path`.
using FreeSpaceProbe = std::function<Result<uint64_t>(const std::string& path)>;

// statvfs(): f_bavail * f_frsize. IoError naming `path` if it fails.
Result<uint64_t> StatvfsFreeBytes(const std::string& path);

struct FreeSpaceOptions {
  uint64_t reserve_bytes = 0;        // 0: no reserve, nothing is probed
  uint32_t refresh_ms = 100;         // probe again at least this often...
  uint64_t refresh_bytes = 1 << 20;  // ...and after this many bytes admitted since the last probe
  FreeSpaceProbe probe;              // null: StatvfsFreeBytes
  // null: std::chrono::steady_clock::now (tests inject a clock)
  std::function<std::chrono::steady_clock::time_point()> clock;
};

class FreeSpaceGuard {
 public:
  FreeSpaceGuard(std::string path, FreeSpaceOptions options);

  // OK if `bytes` more may be written and the reserve still stays free (by the estimate);
  // otherwise IoError "data dir <path> has X MB free, below the reserve of Y MB; writes resume
  // when space is freed", and nothing is counted. The caller writes nothing then.
  Status Admit(uint64_t bytes);
  // Admit() for a write that frees more than it adds (an operator's clear, removal or robot
  // retirement, a checkpoint that truncates the log): it may use the upper half of the reserve,
  // so the space the reserve stopped the robots at can still be freed (issue 25), while RocksDB
  // keeps half the reserve for its flushes. Does not change below_reserve().
  Status AdmitFreeing(uint64_t bytes);
  // Probes now and answers as Admit(0) would (a paused writer asking whether to resume).
  Status Check();

  // Bytes the store will write on its own, whatever is admitted: RocksDB's memory tables, which
  // a flush writes out (up to the memory budget, 32 MB). They count as written already, or a
  // flush after the robots stopped at the reserve met a full disk (issue 25: the operator's
  // clear failed with ENOSPC in that flush). `pending` is called under the guard's lock.
  void SetPendingBytes(std::function<uint64_t()> pending);

  bool enabled() const { return options_.reserve_bytes > 0; }
  uint64_t reserve_bytes() const { return options_.reserve_bytes; }
  // The estimate: the last probe minus what was admitted since and what is pending (0 before
  // the first probe).
  uint64_t free_bytes() const;
  // As of the last Admit() or Check(): the reserve was not free.
  bool below_reserve() const;

 private:
  // With mu_ held: probes if forced, stale by time, or stale by bytes admitted.
  Status RefreshLocked(bool force);
  // `freeing`: only half the reserve must stay free, and below_ is left as it is.
  Status DecideLocked(uint64_t bytes, bool freeing);
  Status AdmitAs(uint64_t bytes, bool freeing);  // takes mu_
  std::chrono::steady_clock::time_point Now() const;
  uint64_t FreeLocked() const;

  std::function<uint64_t()> pending_;  // guarded by mu_; null: nothing pending

  const std::string path_;
  const FreeSpaceOptions options_;
  mutable std::mutex mu_;
  bool probed_ = false;
  std::chrono::steady_clock::time_point probed_at_;
  uint64_t probed_free_ = 0;
  uint64_t admitted_since_probe_ = 0;
  bool below_ = false;
};

}  // namespace bgkmap::storage
