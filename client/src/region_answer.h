// A region answer assembled from its chunks: the whole region as rows, or a delta's patches
// (docs/server.md, "Region deltas"), checked as they arrive.
#pragma once

#include "bgkmap/client/client.h"
#include "bgkmap/v1/query.pb.h"

namespace bgkmap {

class RegionAnswerReader {
 public:
  // InvalidArgument saying what is wrong with `chunk` (out of order, wrong sizes, ...).
  Status Add(const v1::RegionChunk& chunk);
  // The answer; InvalidArgument if the stream ended early.
  Result<RegionDelta> Finish() &&;

 private:
  RegionDelta out_;
  bool have_header_ = false;
  int64_t next_row_ = 0;
};

}  // namespace bgkmap
