// The engine keeps scratch buffers of the per-scan work per thread, from scan to scan, so that a
// dense scan's megabytes are not allocated, zeroed and faulted in every time (each buffer at most
// 8 MiB; what a larger scan needs is freed when it is done). A long-running process whose
// threads go idle hands them back with ReleaseThreadScratch on each of those threads: a robot
// streaming keeps its buffers warm, a server left idle keeps only its map.
#pragma once

#include <cstddef>

namespace bgkmap {

// Frees the calling thread's kept scratch buffers. Safe at any time the thread is not inside an
// engine call; the next scan on this thread allocates them again.
void ReleaseThreadScratch();

// Bytes the calling thread's kept scratch buffers hold (their capacity).
std::size_t ThreadScratchBytes();

}  // namespace bgkmap
