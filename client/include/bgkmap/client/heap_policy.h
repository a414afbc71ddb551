// A process-wide malloc policy for processes that move large buffers again and again: a planner
// refreshing regions, the bgkmap CLI building a map scan by scan. glibc gives freed memory at
// the heap's top back to the kernel (and serves blocks of 128 KiB and more from their own
// mappings), so the next region answer or scan faults every page of its buffers in again; on a
// virtual machine a page fault can cost several microseconds. Measured (docs/benchmarks.md,
// "Region extraction"): a 50 m region's answer 5x faster, `bgkmap build` 18 % faster.
//
// The Client never calls this itself (it is the process's choice, not a library's): a program
// calls it once at its start. It keeps up to 64 MiB of freed memory for reuse and serves blocks
// of up to 4 MiB from the heap; larger ones (a 200 m region's layers) still go back at once. An
// operator's GLIBC_TUNABLES, if set, wins: then this does nothing.
#pragma once

namespace bgkmap {

void KeepFreedHeapMemoryForReuse();

}  // namespace bgkmap
