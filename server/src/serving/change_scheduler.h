// Orders and runs the changes of the served map.
//
// Every change but a barrier gets the next map version. The result must equal applying the
// changes one by one in version order, yet scans whose tiles are disjoint should integrate in
// parallel. So at admission (serialised, in version order) each change records which earlier,
// unfinished changes it conflicts with, by its kind:
//   - a scan that writes tile T waits for the last writer of T and every reader of T since;
//     one that only reads T (kernel and feature neighbourhoods) waits for the last writer;
//   - an exclusive change (a clear, an import) waits for everything before it, and everything
//     after waits for it;
//   - a barrier is ordered like an exclusive change but takes no version (checkpoints, export
//     snapshots).
// A change is handed to the worker pool only once all of those have finished, so workers never
// block on each other and the wait-for graph, which follows version order, has no cycle.
// What a change does is its Work; the scheduler only orders, runs and counts.
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <unordered_map>
#include <variant>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/tile_blocks.h"

namespace bgkmap {

class ChangeScheduler {
 public:
  // The kinds of change, by what they must wait for.
  struct TileChange {  // a scan
    std::vector<TileKey> write_tiles;
    std::vector<TileKey> read_tiles;
  };
  struct ExclusiveChange {};
  struct Barrier {};
  using Kind = std::variant<TileChange, ExclusiveChange, Barrier>;

  // What a change left once it ran: the tiles it changed (told to `on_tiles_changed` once the
  // change counts as applied, so the applied version covers it) and what to do after that (an
  // ack).
  struct Done {
    std::vector<TileKey> changed_tiles;
    std::function<void()> then;
    // changed_blocks[i]: the blocks of changed_tiles[i] that may have changed (a scan's report);
    // empty: the whole tiles.
    std::vector<TileBlocks> changed_blocks = {};
  };
  // Runs on a worker with the change's version (a barrier: the applied version, which then
  // covers every change admitted before it).
  using Work = std::function<Done(uint64_t version)>;
  using TilesChanged = std::function<void(const std::vector<TileKey>&)>;
  using TilesApplied = std::function<void(uint64_t version, const std::vector<TileKey>&,
                                          const std::vector<TileBlocks>& blocks)>;

  // `on_tiles_applied` is told a change's version and tiles before the applied version covers
  // it (a reader that sees the applied version finds the change recorded); `on_tiles_changed`
  // after (watchers).
  ChangeScheduler(boost::asio::thread_pool& pool, TilesChanged on_tiles_changed,
                  TilesApplied on_tiles_applied = {});
  ~ChangeScheduler();  // WaitIdle()

  // Before anything is submitted: continue from a recovered map.
  void Restore(uint64_t version);

  // Admits a change; its Work runs on a worker once every change it conflicts with finished.
  // Returns its version (0 for a barrier).
  uint64_t Submit(Kind kind, Work work);

  // Every change up to this version has finished.
  uint64_t applied_version() const;
  uint64_t assigned_version() const;
  // Blocks until every admitted change has finished.
  void WaitIdle();

 private:
  struct Job {
    uint64_t version = 0;  // 0 for a barrier
    Kind kind;
    Work work;
    int pending = 0;  // unfinished changes this one waits for
    std::vector<Job*> dependents;
  };
  struct TileOrder {
    Job* last_writer = nullptr;
    std::vector<Job*> readers;  // since last_writer
  };

  std::vector<Job*> DependenciesLocked(Job* job);  // requires mu_; records the job's order
  void Run(Job* job);
  void Finish(Job* job);
  void ForgetLocked(Job* job);  // requires mu_
  void Post(const std::vector<Job*>& ready);

  boost::asio::thread_pool& pool_;
  TilesChanged on_tiles_changed_;
  TilesApplied on_tiles_applied_;

  mutable std::mutex mu_;
  std::condition_variable idle_cv_;
  uint64_t next_version_ = 1;
  uint64_t applied_version_ = 0;
  std::set<uint64_t> finished_ahead_;  // finished versions above applied_version_
  std::unordered_map<TileKey, TileOrder, TileKeyHash> order_;
  std::unordered_map<Job*, std::unique_ptr<Job>> active_;
  Job* exclusive_ = nullptr;  // the last exclusive change or barrier not finished
};

}  // namespace bgkmap
