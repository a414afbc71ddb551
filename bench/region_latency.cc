// Region query latency against any bgkmapd (a single server or a cluster shard): the same box
// queried repeatedly, median and p95 over the repetitions. scripts/bench-cluster.sh runs it
// against a single server and through a cluster shard, for a box inside one partition and one
// spanning four.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/client/heap_policy.h"
#include "percentile.h"

int main(int argc, char** argv) {
  CLI::App app{"Region query latency (median, p95) against a bgkmapd"};
  std::string server = "127.0.0.1:50051";
  std::vector<double> box;
  int repetitions = 30;
  std::string label = "region";
  app.add_option("--server", server, "bgkmapd address");
  app.add_option("--bbox", box, "xmin ymin xmax ymax (metres)")->expected(4)->required();
  app.add_option("--repetitions", repetitions, "queries to time")->check(CLI::Range(1, 100000));
  app.add_option("--label", label, "row label");
  bool default_malloc = false;
  app.add_flag("--default-malloc", default_malloc,
               "glibc's own policy instead of KeepFreedHeapMemoryForReuse() (heap_policy.h)");
  CLI11_PARSE(app, argc, argv);
  if (!default_malloc) bgkmap::KeepFreedHeapMemoryForReuse();  // as a planner would
  bgkmap::Client client(server);
  if (!client.WaitForConnected(std::chrono::seconds(10))) {
    std::fprintf(stderr, "region_latency: cannot reach %s\n", server.c_str());
    return 1;
  }
  const bgkmap::RegionQuery query{{box[0], box[1], box[2], box[3]}, {}, 1};
  std::vector<double> ms;
  int64_t known = 0;
  for (int i = 0; i < repetitions + 1; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    bgkmap::RpcResult<bgkmap::Raster> r = client.QueryRegion(query);
    const double elapsed =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (!r.ok()) {
      std::fprintf(stderr, "region_latency: %s\n", r.status().message().c_str());
      return 1;
    }
    if (i == 0) {  // the first warms connections and caches
      for (float v : r->data[0]) known += v == v ? 1 : 0;
      continue;
    }
    ms.push_back(elapsed);
  }
  std::printf("| %s | %lld | %.1f | %.1f |\n", label.c_str(), static_cast<long long>(known),
              bgkmap::bench::Percentile(ms, 0.5), bgkmap::bench::Percentile(ms, 0.95));
  return 0;
}
