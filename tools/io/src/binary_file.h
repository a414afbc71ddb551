// Whole-file reads and writes shared by the readers and writers (internal to bgkmap_io).
#pragma once

#include <string>
#include <string_view>

#include "bgkmap/core/status.h"

namespace bgkmap::io::internal {

// The file's bytes; IoError "<path>: cannot open (...)" if it cannot be read.
Result<std::string> ReadWholeFile(const std::string& path);
// The same into `bytes`, whose memory is reused (a reader of many scan files keeps one buffer).
Status ReadWholeFileInto(const std::string& path, std::string& bytes);

// Writes `bytes` to `path` (truncating, or appending if `append`); IoError naming the path.
Status WriteWholeFile(const std::string& path, std::string_view bytes, bool append = false);

}  // namespace bgkmap::io::internal
