// ReadPcd (ASCII and binary data) on arbitrary files: never crashes, never allocates beyond
// the file; a cloud it returns lists its FIELDS, x, y and z among them.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "bgkmap/io/pcd_reader.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  static fuzz::InputFile file(".pcd");
  const std::string& path = file.Write({reinterpret_cast<const char*>(data), size});
  Result<io::PcdCloud> cloud = io::ReadPcd(path);
  if (!cloud.ok()) return 0;
  if (cloud->fields.size() < 3) std::abort();
  return 0;
}
