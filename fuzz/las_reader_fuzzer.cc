// ReadLas (header, variable-length records, points) on arbitrary files: never crashes, never
// allocates beyond the file; what it reads is consistent with its header.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "bgkmap/io/las_reader.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  static fuzz::InputFile file(".las");
  const std::string& path = file.Write({reinterpret_cast<const char*>(data), size});
  Result<io::LasCloud> all = io::ReadLas(path);
  if (!all.ok()) return 0;
  if (all->points.size() != all->header.point_count ||
      all->classification.size() != all->points.size()) {
    std::abort();
  }
  // The class filter keeps a subset.
  Result<io::LasCloud> ground = io::ReadLas(path, {.classes = {2}});
  if (!ground.ok() || ground->points.size() > all->points.size()) std::abort();
  return 0;
}
