// Runs a few tasks on the calling thread and on whichever pool threads are free to take them.
//
// Every task but the first is offered to the pool; the caller runs the first, then each offered
// task no pool thread has started yet, and returns once all have finished. So the caller never
// waits for a pool thread to become free: on a busy pool it runs everything itself, and an offer
// taken too late finds its task done and does nothing. (A scan's integration bands, while the
// caller holds the scan's tile locks: a pool thread that takes a band takes no lock.)
#pragma once

#include <functional>
#include <span>

namespace bgkmap {

// `offer` hands a function to a pool (it may run it at any time, on any thread, or after this
// returns: it then only finds its task taken).
using Offer = std::function<void(std::function<void()>)>;

void RunSharingWithPool(std::span<const std::function<void()>> tasks, const Offer& offer);

}  // namespace bgkmap
