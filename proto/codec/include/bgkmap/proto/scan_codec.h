// What ingestion reports about a scan <-> bgkmap.v1.PointCounts; compact points <->
// bgkmap.v1.CompactPoints.
#pragma once

#include "bgkmap/core/scan.h"
#include "bgkmap/proto/compact_points.h"
#include "bgkmap/v1/ingest.pb.h"

namespace bgkmap {

void ToProto(const ScanPointCounts& counts, v1::PointCounts* out);
ScanPointCounts FromProto(const v1::PointCounts& counts);

// By value: an encoder that is done with `compact` moves its data (a few hundred kB) in.
void ToProto(CompactPoints compact, v1::CompactPoints* out);
// An order the codec does not know stays unknown (DecodeCompactPoints refuses it).
CompactPoints FromProto(const v1::CompactPoints& compact);

}  // namespace bgkmap
