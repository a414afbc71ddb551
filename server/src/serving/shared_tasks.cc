#include "serving/shared_tasks.h"

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <vector>

namespace bgkmap {
namespace {

// What the caller and the offers share: an offer may outlive the call, so it holds this, and
// touches the tasks only once it has taken one (the caller then waits for it).
struct Sharing {
  explicit Sharing(std::span<const std::function<void()>> t) : tasks(t), taken(t.size()) {}

  // Runs task i unless someone took it first.
  void RunIfFree(size_t i) {
    if (taken[i].exchange(true)) return;
    tasks[i]();
    std::lock_guard lock(mu);
    if (++finished == tasks.size()) all_done.notify_one();
  }

  std::span<const std::function<void()>> tasks;
  std::vector<std::atomic<bool>> taken;
  std::mutex mu;
  std::condition_variable all_done;
  size_t finished = 0;  // under mu
};

}  // namespace

void RunSharingWithPool(std::span<const std::function<void()>> tasks, const Offer& offer) {
  if (tasks.empty()) return;
  auto sharing = std::make_shared<Sharing>(tasks);
  for (size_t i = 1; i < tasks.size(); ++i) {
    offer([sharing, i] { sharing->RunIfFree(i); });
  }
  for (size_t i = 0; i < tasks.size(); ++i) sharing->RunIfFree(i);
  std::unique_lock lock(sharing->mu);
  sharing->all_done.wait(lock, [&] { return sharing->finished == tasks.size(); });
}

}  // namespace bgkmap
