// How bgkmapd uses glibc's heap. It keeps freed large buffers (region rasters, chunks, scans)
// for the next request instead of faulting them in again, and hands memory back to the system
// only at chosen moments: after eviction, and when its workers go idle.
#pragma once

namespace bgkmap {

// glibc hands large buffers back to the kernel when they are freed and page-faults them in
// again on the next query, which made a 50 x 50 m region query ~3x slower. This keeps them in
// the heap: the process keeps its peak memory, except where it returns it (below). Call once at
// start; bgkmapd does. Process-wide, so embedders decide.
void KeepLargeAllocationsInHeap();

// At most `arenas` glibc heap arenas (0: glibc's own limit), unless the environment sets
// MALLOC_ARENA_MAX (the operator's word wins). Call once at start, before threads allocate.
void LimitHeapArenas(int arenas);

// Between these two calls memory freed on any thread goes back to the system as it is freed
// (each arena's top is shrunk: with KeepLargeAllocationsInHeap it never is, and malloc_trim
// releases free pages inside an arena, not its top); End also releases every arena's free pages
// and restores the policy once no other window is open (windows are counted, so two threads may
// open theirs at once). Without KeepLargeAllocationsInHeap, glibc trims by itself: End only
// trims.
void BeginReturningFreedMemory();
void EndReturningFreedMemory();

// Frees the calling thread's engine scratch (ReleaseThreadScratch, bgkmap/core/thread_scratch.h)
// inside such a window, so it leaves the process: for a thread that integrates by itself once
// it goes quiet.
void ReturnThreadScratch();

}  // namespace bgkmap
