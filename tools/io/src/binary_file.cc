#include "binary_file.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

namespace bgkmap::io::internal {

Status ReadWholeFileInto(const std::string& path, std::string& bytes) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return Status::IoError(path + ": cannot open (" + std::strerror(errno) + ")");
  // One read of the size the file says it has (a scan is megabytes: no growing copies), then
  // whatever a growing file or a pipe still gives.
  struct stat st {};
  bytes.clear();
  if (fstat(fileno(f), &st) == 0 && S_ISREG(st.st_mode)) {
    bytes.resize(static_cast<size_t>(st.st_size));
  }
  const size_t have = std::fread(bytes.data(), 1, bytes.size(), f);
  bytes.resize(have);
  char chunk[65536];
  while (!std::ferror(f) && !std::feof(f)) {
    const size_t got = std::fread(chunk, 1, sizeof chunk, f);
    bytes.append(chunk, got);
  }
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) return Status::IoError(path + ": read failed");
  return Status::Ok();
}

Result<std::string> ReadWholeFile(const std::string& path) {
  std::string bytes;
  if (Status s = ReadWholeFileInto(path, bytes); !s.ok()) return s;
  return bytes;
}

Status WriteWholeFile(const std::string& path, std::string_view bytes, bool append) {
  std::ofstream out(path, std::ios::binary | (append ? std::ios::app : std::ios::trunc));
  if (!out)
    return Status::IoError(path + ": cannot open for writing (" + std::strerror(errno) + ")");
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) return Status::IoError(path + ": write failed");
  return Status::Ok();
}

}  // namespace bgkmap::io::internal
