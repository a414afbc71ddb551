// The path of one scan shared by the streaming and unary Ingest calls: checks, preparation,
// admission, integration, ack.
#pragma once

#include <grpcpp/support/status.h>

#include <functional>

#include "bgkmap/v1/ingest.pb.h"
#include "rpc/service_context.h"

namespace bgkmap {

// Called exactly once per scan. `status` is OK for applied and duplicate scans and the reason for
// a rejected one (the ack carries the same code and message).
using AckCallback = std::function<void(v1::ScanAck ack, grpc::Status status)>;

// Runs the checks and preparation on the calling thread, then admits the scan. Rejections and
// duplicates are answered before returning; an admitted scan is answered on a worker once it is
// in the map. Scans of one robot must be passed in the order they were sent.
// `who` must be allowed to ingest as the scan's robot id (PERMISSION_DENIED otherwise).
void IngestScanMessage(ServiceContext& ctx, const Principal& who, const v1::Scan& scan,
                       AckCallback done);

// An ACK_REJECTED ack for `scan` with `status`.
v1::ScanAck RejectedAck(ServiceContext& ctx, const v1::Scan& scan, const grpc::Status& status);

}  // namespace bgkmap
