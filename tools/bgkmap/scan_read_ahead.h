// Reads a scan source's scans on a thread of its own, a few ahead of the one being sent, so that
// `bgkmap insert` does not read (and parse) scan N+1 only after scan N was handed to the stream.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <thread>

#include "scan_source.h"

namespace bgkmap::cli {

class ScanReadAhead {
 public:
  // Reads scans first, first + 1, ... of `source` (which must outlive this), at most `depth`
  // (>= 1) of them ahead of Next().
  ScanReadAhead(const ScanSource& source, size_t first, size_t depth);
  ~ScanReadAhead();  // stops reading
  ScanReadAhead(const ScanReadAhead&) = delete;
  ScanReadAhead& operator=(const ScanReadAhead&) = delete;

  // The next scan in order, as source.Read() gave it; after an error nothing more is read, and
  // that error is the last result. Call it at most source.size() - first times.
  Result<SourceScan> Next();

 private:
  void ReadLoop(size_t first);

  const ScanSource& source_;
  const size_t depth_;
  std::mutex mu_;
  std::condition_variable changed_;
  std::deque<Result<SourceScan>> ready_;
  bool stopping_ = false;
  std::thread thread_;  // last: started once the rest is in place
};

}  // namespace bgkmap::cli
