// Orders and runs the changes of the served map (scans and region clears).
//
// Every admitted change gets the next map version. The result must equal applying the changes
// one by one in version order, yet scans whose tiles are disjoint should integrate in parallel.
// So at admission (serialised, in version order) each change records which earlier, unfinished
// changes it conflicts with:
//   - a scan that writes tile T waits for the last writer of T and every reader of T since;
//   - a scan that only reads T (kernel and feature neighbourhoods) waits for the last writer;
//   - a clear is a barrier: it waits for everything before it and everything after waits for it.
// A change is handed to the worker pool only once all of those have finished, so workers never
// block on each other and the wait-for graph, which follows version order, has no cycle.
//
// Sequence numbers: a robot's scan is admitted only if its sequence number is above the robot's
// last admitted one; otherwise it is a duplicate and is not applied again. Admitted changes
// apply unless the journal (the persistent scan log) refuses them: then the change is skipped,
// still finishes (so later changes are not blocked) and its callback carries the error.
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/scan_integrator.h"
#include "bgkmap/core/status.h"
#include "map_store.h"

namespace bgkmap {

struct Stamp {
  int64_t seconds = 0;
  int32_t nanos = 0;
};

struct RobotProgress {
  std::string robot_id;
  uint64_t last_sequence = 0;
  Stamp last_stamp;
  uint64_t scans_applied = 0;
  uint64_t scans_duplicate = 0;
  uint64_t scans_rejected = 0;
  uint64_t points_kept = 0;
};

struct ScanOutcome {
  uint64_t version = 0;
  ScanReport report;
  Status status;  // not OK: the journal refused the scan and it was not applied
};

// A change about to be applied, as the journal sees it.
struct ChangeRecord {
  uint64_t version = 0;
  std::shared_ptr<const PreparedScan> scan;  // null for a clear
  std::string robot_id;
  uint64_t sequence = 0;
  Stamp stamp;
  CellBox clear_box;
};

// Makes changes durable. Both calls run on the worker of the change, before it counts as
// finished, so a barrier (SubmitBarrier) sees every change either journaled and marked or not
// started. Changes that do not conflict call it concurrently.
class ChangeJournal {
 public:
  // Before the change is applied; not OK: skip the change.
  virtual Status Record(const ChangeRecord& change) = 0;
  // After it was applied: every tile it may have changed.
  virtual void Applied(std::span<const TileKey> tiles) = 0;

 protected:
  ~ChangeJournal() = default;
};

class ScanScheduler {
 public:
  // Called on a worker after each change (once it counts as applied), before its completion
  // callback: the changed tiles.
  using TilesChanged = std::function<void(const std::vector<TileKey>&)>;

  ScanScheduler(MapStore& store, boost::asio::thread_pool& pool, uint32_t max_robots,
                TilesChanged on_tiles_changed);
  ~ScanScheduler();

  enum class Admission { kAdmitted, kDuplicate, kTooManyRobots };

  // Admits a prepared scan; `on_applied` then runs on a worker once it is in the map.
  Admission SubmitScan(const std::string& robot_id, uint64_t sequence, Stamp stamp,
                       std::shared_ptr<const PreparedScan> scan,
                       std::function<void(ScanOutcome)> on_applied);

  // Cheap early check (the admission decides): would this sequence number be a duplicate?
  bool IsDuplicate(const std::string& robot_id, uint64_t sequence) const;
  // Counts a rejected scan (only for robots already known, so bad input cannot grow the table).
  void CountRejected(const std::string& robot_id);
  // Counts a duplicate answered without admission.
  void CountDuplicate(const std::string& robot_id);

  // Admits a clear of `box`; `on_cleared(version, changed tiles, status)` runs once it is done
  // (status not OK: the journal refused it and nothing was cleared).
  void SubmitClear(const CellBox& box,
                   std::function<void(uint64_t, std::vector<TileKey>, Status)> on_cleared);

  // Runs `fn(applied version)` on a worker once every change admitted before has finished and
  // before any change admitted after starts: no change is in flight while it runs. Takes no
  // map version.
  void SubmitBarrier(std::function<void(uint64_t)> fn);

  // An exclusive change that makes itself durable instead of going through the journal (an
  // archive import): it takes the next map version and, like a clear, `fn(version)` runs on a
  // worker once every change admitted before has finished and before any change admitted after
  // starts. `fn` returns the tiles it changed (published to watchers once the change counts as
  // applied) or why it changed nothing; then `on_done(version, status)` runs.
  using ExclusiveChange = std::function<Result<std::vector<TileKey>>(uint64_t version)>;
  void SubmitExclusive(ExclusiveChange fn, std::function<void(uint64_t, Status)> on_done);

  // Before anything is submitted: continue from a recovered map.
  void Restore(uint64_t version, const std::map<std::string, uint64_t>& robot_sequences);
  // Before anything is submitted; `journal` must outlive the scheduler's work.
  void SetJournal(ChangeJournal* journal) { journal_ = journal; }

  // Every change up to this version is in the map.
  uint64_t applied_version() const;
  uint64_t assigned_version() const;
  uint64_t scans_applied() const;
  std::optional<uint64_t> LastSequence(const std::string& robot_id) const;
  std::vector<RobotProgress> Robots() const;  // sorted by id

  // Blocks until every admitted change has finished.
  void WaitIdle();

 private:
  struct Job;
  struct TileOrder {
    Job* last_writer = nullptr;
    std::vector<Job*> readers;  // since last_writer
  };

  Job* AdmitLocked(std::unique_ptr<Job> job);  // requires mu_
  void Run(Job* job);
  void Finish(Job* job, bool applied);
  void PostReady(const std::vector<Job*>& ready);

  MapStore& store_;
  boost::asio::thread_pool& pool_;
  const uint32_t max_robots_;
  TilesChanged on_tiles_changed_;
  ChangeJournal* journal_ = nullptr;

  mutable std::mutex mu_;
  std::condition_variable idle_cv_;
  uint64_t next_version_ = 1;
  uint64_t applied_version_ = 0;
  std::set<uint64_t> finished_ahead_;  // finished versions above applied_version_
  uint64_t scans_applied_ = 0;
  std::unordered_map<TileKey, TileOrder, TileKeyHash> order_;
  std::unordered_map<Job*, std::unique_ptr<Job>> active_;
  Job* barrier_ = nullptr;
  std::map<std::string, RobotProgress> robots_;
};

}  // namespace bgkmap
