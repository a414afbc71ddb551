// ReadScanGraph (OctoMap .graph files, tools/bgkmap) on arbitrary files: never crashes, never
// allocates beyond the file; every pose it returns is finite.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_input.h"
#include "scan_graph_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  static fuzz::InputFile file(".graph");
  const std::string& path = file.Write({reinterpret_cast<const char*>(data), size});
  Result<std::vector<cli::GraphScan>> scans = cli::ReadScanGraph(path);
  if (!scans.ok()) return 0;
  for (const cli::GraphScan& scan : *scans) {
    if (!scan.pose.translation.allFinite() || !scan.pose.rotation.allFinite()) std::abort();
  }
  return 0;
}
