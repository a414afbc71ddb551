// The ingest workers' scheduling: their nice value, and the CPUs each is pinned to
// (server.worker_nice, server.worker_cpus; docs/server.md "Server keys").
#pragma once

#include <boost/asio/thread_pool.hpp>
#include <cstddef>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap {

// OK when every CPU of `cpus` is one this process may run on (its affinity mask), else
// InvalidArgument naming the first that is not and the CPUs that are.
Status CheckWorkerCpus(const std::vector<int>& cpus);

// Gives each of the `threads` threads of `pool` the nice increment `nice` and, when `cpus` is not
// empty, pins the i-th of them to cpus[i % cpus.size()]. Each thread takes exactly one task: all
// of them wait until every one has started. Failures are logged; the threads keep running.
void ConfigureWorkerThreads(boost::asio::thread_pool& pool, size_t threads, int nice,
                            const std::vector<int>& cpus);

}  // namespace bgkmap
