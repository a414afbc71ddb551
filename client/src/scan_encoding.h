// How the client puts a scan on the wire (docs/server.md "Compact scans"): compact by default,
// without the points the map would drop anyway, and the ack's counts as if every point had been
// sent.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>

#include "bgkmap/client/client.h"
#include "bgkmap/core/map_params.h"
#include "bgkmap/proto/compact_points.h"
#include "bgkmap/v1/ingest.pb.h"

namespace bgkmap::client_codec {

struct ScanEncoding {
  double step = 0.0;                // > 0: compact points quantized to it; 0: packed float32
  std::optional<MapParams> filter;  // the map's parameters: drop what its range filter drops
  bool drop_height = false;         // ... and its height filter (see ClientOptions)
};

// The order a stream's compact scans are encoded in (compact_points.h). A sensor gives its points
// in the same order scan after scan, so the smaller order of one scan is that of the next ones:
// the stream's first scan and every kProbeEvery-th after it try both (EncodeQuantizedPoints picks
// the smaller), the others take the last such winner, half the encoding time. Thread-safe.
class OrderHint {
 public:
  static constexpr uint64_t kProbeEvery = 16;
  // For the stream's `index`-th scan (from 0): none to try both.
  std::optional<PointOrder> For(uint64_t index) const;
  // The order a scan that tried both was sent in.
  void Learn(PointOrder chosen);

 private:
  std::atomic<int> order_{-1};  // -1: no scan tried both yet
};

// Fills `out` (a scan whose points cannot all be quantized goes as float32), compact in `order`
// (none: the smaller of the orders; `chosen`, if given, says which one it was). Returns what was
// dropped here: input is every point of `scan`, dropped_* what was not sent, kept unused.
ScanPointCounts EncodeScan(const ScanData& scan, const ScanEncoding& encoding, v1::Scan* out,
                           std::optional<PointOrder> order = std::nullopt,
                           PointOrder* chosen = nullptr);

// EncodeScan for a stream's `index`-th scan, in the order `hint` gives; a scan that tried both
// orders teaches `hint` the winner.
ScanPointCounts EncodeHinted(const ScanData& scan, uint64_t index, const ScanEncoding& encoding,
                             OrderHint* hint, v1::Scan* out);

// An ack's counts as if every point had been sent: the points dropped here are added.
void AddDroppedHere(const ScanPointCounts& here, ScanPointCounts* ack);

}  // namespace bgkmap::client_codec
