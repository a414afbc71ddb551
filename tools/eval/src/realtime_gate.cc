#include "bgkmap/eval/realtime_gate.h"

#include <limits>

namespace bgkmap::eval {

std::vector<bool> AdmitScans(std::span<const ScanTiming> timings, double period) {
  std::vector<bool> admitted(timings.size(), false);
  double free1 = -std::numeric_limits<double>::infinity();  // when process 1 is idle again
  double free2 = free1;
  for (size_t k = 0; k < timings.size(); ++k) {
    const double arrival = static_cast<double>(k) * period;
    if (free1 > arrival) continue;  // process 1 busy: dropped on arrival
    const double handover = arrival + timings[k].process1;
    free1 = handover;
    if (free2 > handover) continue;  // process 2 busy: dropped after elevation
    free2 = handover + timings[k].process2;
    admitted[k] = true;
  }
  return admitted;
}

}  // namespace bgkmap::eval
