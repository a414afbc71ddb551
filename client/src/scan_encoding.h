// How the client puts a scan on the wire (docs/server.md "Compact scans"): compact by default,
// without the points the map would drop anyway, and the ack's counts as if every point had been
// sent.
#pragma once

#include <optional>

#include "bgkmap/client/client.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/v1/ingest.pb.h"

namespace bgkmap::client_codec {

struct ScanEncoding {
  double step = 0.0;                // > 0: compact points quantized to it; 0: packed float32
  std::optional<MapParams> filter;  // the map's parameters: drop what its range filter drops
  bool drop_height = false;         // ... and its height filter (see ClientOptions)
};

// Fills `out` (a scan whose points cannot all be quantized goes as float32). Returns what was
// dropped here: input is every point of `scan`, dropped_* what was not sent, kept unused.
ScanPointCounts EncodeScan(const ScanData& scan, const ScanEncoding& encoding, v1::Scan* out);

// An ack's counts as if every point had been sent: the points dropped here are added.
void AddDroppedHere(const ScanPointCounts& here, ScanPointCounts* ack);

}  // namespace bgkmap::client_codec
