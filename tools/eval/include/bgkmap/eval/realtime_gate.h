// Which scans a real-time system keeps (paper Sec. 3.1): scans arrive every `period` seconds and
// flow through two processes, (1) registration and elevation inference, (2) traversability
// computation and inference. A scan that arrives while process 1 is busy, or that process 1
// hands over while process 2 is busy, is dropped ("skipped").
#pragma once

#include <span>
#include <vector>

namespace bgkmap::eval {

struct ScanTiming {
  double process1 = 0;  // seconds: preparation + elevation
  double process2 = 0;  // seconds: traversability computation + inference
};

// admitted[k] for each scan k arriving at k * period.
std::vector<bool> AdmitScans(std::span<const ScanTiming> timings, double period);

}  // namespace bgkmap::eval
