// The send side of an ingest stream with the encoding off the caller's path (issue 27): scans are
// encoded (quantize, filter, deltas, zstd: several ms for a dense scan) on worker threads a few
// scans ahead, while a writer thread puts the finished ones on the wire one at a time, in the
// order they were submitted. Without it the caller's thread encoded scan N+1 only after scan N
// was written, so the encoding and the sending took turns.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/client/client.h"
#include "bgkmap/v1/ingest.pb.h"
#include "scan_encoding.h"

namespace bgkmap::client_codec {

// One scan of the pipeline, encoded.
struct EncodedScan {
  std::string robot_id;
  uint64_t sequence = 0;
  v1::Scan message;
  ScanPointCounts here;  // what the encoding dropped (EncodeScan)
};

class EncodePipeline {
 public:
  // Called on the writer thread for each scan, in submission order; false when the stream is
  // broken: no later scan is written, and Submit() returns false from then on.
  using WriteFn = std::function<bool(EncodedScan&)>;

  // `threads` (>= 1) encode; at most `ahead` (>= 1) scans are submitted and not yet written.
  EncodePipeline(ScanEncoding encoding, int threads, int ahead, WriteFn write);
  // Stops after the scan being written, if any (cancel the stream first if that write could
  // block); scans not yet written are dropped.
  ~EncodePipeline();
  EncodePipeline(const EncodePipeline&) = delete;
  EncodePipeline& operator=(const EncodePipeline&) = delete;

  // Copies the scan (its points need not outlive the call) and queues it; blocks while `ahead`
  // scans wait. False, with nothing queued, once a write failed or Close() was called.
  bool Submit(const ScanData& scan);
  // No more scans; returns once every queued scan is written or dropped after a failed write.
  void Close();
  // True once a write failed.
  bool broken() const;

 private:
  struct Job {
    EncodedScan out;
    uint64_t index = 0;  // in the stream, from 0
    ScanData header;     // points point into `points`
    std::vector<Point3f> points;
    bool encoded = false;
  };

  void EncodeLoop();
  void WriteLoop();

  const ScanEncoding encoding_;
  const size_t ahead_;
  const WriteFn write_;
  mutable std::mutex mu_;
  std::condition_variable changed_;        // any of the state below changed
  std::deque<std::unique_ptr<Job>> jobs_;  // submitted, not yet written, in order
  std::deque<Job*> to_encode_;             // of jobs_, not yet taken by an encoder
  bool closed_ = false, failed_ = false, stopping_ = false;
  OrderHint order_hint_;
  uint64_t submitted_ = 0;
  std::vector<std::thread> threads_;
};

}  // namespace bgkmap::client_codec
