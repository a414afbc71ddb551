// What ingestion reports about a scan <-> bgkmap.v1.PointCounts.
#pragma once

#include "bgkmap/core/scan.h"
#include "bgkmap/v1/ingest.pb.h"

namespace bgkmap {

void ToProto(const ScanPointCounts& counts, v1::PointCounts* out);
ScanPointCounts FromProto(const v1::PointCounts& counts);

}  // namespace bgkmap
