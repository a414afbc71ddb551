#include "worker_threads.h"

#include <pthread.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <boost/asio/post.hpp>
#include <latch>
#include <memory>
#include <string>

namespace bgkmap {
namespace {

// "0-3,6": the CPUs of `set`, as taskset and /proc write them.
std::string CpuList(const cpu_set_t& set) {
  std::string out;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (!CPU_ISSET(c, &set)) continue;
    int last = c;
    while (last + 1 < CPU_SETSIZE && CPU_ISSET(last + 1, &set)) ++last;
    if (!out.empty()) out += ",";
    out += last > c ? std::to_string(c) + "-" + std::to_string(last) : std::to_string(c);
    c = last;
  }
  return out;
}

}  // namespace

Status CheckWorkerCpus(const std::vector<int>& cpus) {
  if (cpus.empty()) return Status::Ok();
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof(allowed), &allowed) != 0) {
    return Status::FailedPrecondition(
        "server.worker_cpus: cannot read this process's CPUs (errno " + std::to_string(errno) +
        ")");
  }
  for (int c : cpus) {
    if (c < 0 || c >= CPU_SETSIZE || !CPU_ISSET(c, &allowed)) {
      return Status::InvalidArgument("server.worker_cpus: CPU " + std::to_string(c) +
                                     " is not one this process may run on (" + CpuList(allowed) +
                                     ")");
    }
  }
  return Status::Ok();
}

void ConfigureWorkerThreads(boost::asio::thread_pool& pool, size_t threads, int nice,
                            const std::vector<int>& cpus) {
  if (nice == 0 && cpus.empty()) return;
  auto started = std::make_shared<std::latch>(static_cast<std::ptrdiff_t>(threads));
  for (size_t i = 0; i < threads; ++i) {
    const int cpu = cpus.empty() ? -1 : cpus[i % cpus.size()];  // -1: not pinned
    boost::asio::post(pool, [started, nice, cpu] {
      if (nice != 0 && setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice) != 0) {
        spdlog::warn("event=worker_nice_failed errno={}", errno);
      }
      if (cpu >= 0) {
        cpu_set_t one;
        CPU_ZERO(&one);
        CPU_SET(cpu, &one);
        if (const int e = pthread_setaffinity_np(pthread_self(), sizeof(one), &one); e != 0) {
          spdlog::warn("event=worker_pin_failed cpu={} errno={}", cpu, e);
        }
      }
      started->arrive_and_wait();  // so that no thread takes two of these tasks
    });
  }
  started->wait();
}

}  // namespace bgkmap
