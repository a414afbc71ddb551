// The process crash_test kills: ingests scans of several robots from several threads into a
// store, as a server does (integrate in version order, append to the log concurrently, ack,
// checkpoint every few versions), and prints "ack <version>" on stdout after each append
// returned OK.
//
//   crash_writer DIR sync|periodic CHANGES CHECKPOINT_EVERY THREADS ROBOTS
#include <unistd.h>

#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/storage/tile_store.h"
#include "store_test_util.h"

namespace storage = bgkmap::storage;
namespace st = bgkmap::storage::testing;
using bgkmap::MapParams;
using bgkmap::Status;
using storage::LogRecord;

namespace {

void Say(const std::string& line) {
  const std::string out = line + "\n";
  if (write(STDOUT_FILENO, out.data(), out.size()) < 0) _exit(3);
}

[[noreturn]] void Fail(const std::string& what) {
  Say("error " + what);
  _exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 7) Fail("usage: crash_writer DIR DURABILITY CHANGES CHECKPOINT_EVERY THREADS ROBOTS");
  storage::StoreOptions options;
  options.durability = *storage::ParseDurability(argv[2]);
  const uint64_t changes = std::stoull(argv[3]);
  const uint64_t checkpoint_every = std::stoull(argv[4]);
  const int threads = std::stoi(argv[5]);
  const int robots = std::stoi(argv[6]);
  const MapParams params = st::SmallParams();

  auto opened = storage::TileStore::Open(argv[1], options, params);
  if (!opened.ok()) Fail(opened.status().ToString());
  storage::TileStore& store = **opened;
  auto map = st::NewMap(params);
  if (!store.log().Stats()->records && store.map_version() > 0) Fail("store not empty");
  Say("ready");

  std::mutex mu;
  std::condition_variable cv;
  uint64_t next = 0, applied = 0, inflight = 0;
  bool checkpointing = false;
  st::Checkpointer checkpointer;

  auto worker = [&] {
    for (;;) {
      std::unique_lock<std::mutex> lock(mu);
      const uint64_t v = ++next;
      if (v > changes) return;
      const int robot = static_cast<int>(v % robots);
      const int index = static_cast<int>(v / robots);
      lock.unlock();
      const auto scan = st::MakeScan(params, robot, index);  // prepared in parallel
      lock.lock();
      cv.wait(lock, [&] { return applied == v - 1 && !checkpointing; });
      checkpointer.MarkDirty(st::Apply(*map, *scan, v));
      applied = v;
      ++inflight;
      const bool checkpoint = v % checkpoint_every == 0;
      if (checkpoint) checkpointing = true;
      cv.notify_all();
      lock.unlock();

      const Status s =
          store.log().Append(LogRecord::Scan(v, "robot-" + std::to_string(robot), index + 1, scan));
      if (!s.ok()) Fail(s.ToString());
      Say("ack " + std::to_string(v));

      lock.lock();
      --inflight;
      cv.notify_all();
      if (checkpoint) {
        // A consistent snapshot: nothing past v is integrated, everything up to v is logged.
        cv.wait(lock, [&] { return inflight == 0; });
        if (Status c = checkpointer.Checkpoint(store, *map); !c.ok()) Fail(c.ToString());
        Say("checkpoint " + std::to_string(v));
        checkpointing = false;
        cv.notify_all();
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  Say("done");
  return 0;
}
