// Helpers shared by the fuzz targets: the readers under test take a path, and the storage
// formats end in CRC-32C checksums a mutation almost never matches (a fuzzer that only ever
// meets "checksum mismatch" tests nothing behind it), so the targets can restore them.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>

#include "bgkmap/storage/crc32c.h"

namespace bgkmap::fuzz {

// A file of this process that holds the current input (one per target process: libFuzzer runs
// the inputs of one process one after the other), in /dev/shm when there is one (memory: a
// disk-backed /tmp costs several times the executions).
class InputFile {
 public:
  explicit InputFile(const char* extension)
      : path_(std::string(access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp") + "/bgkmap-fuzz-" +
              std::to_string(getpid()) + extension) {}
  ~InputFile() { std::remove(path_.c_str()); }

  // Replaces the file's contents with `bytes`; returns its path.
  const std::string& Write(std::string_view bytes) {
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (f == nullptr) std::abort();
    if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size()) {
      std::abort();
    }
    std::fclose(f);
    return path_;
  }

 private:
  std::string path_;
};

inline uint32_t LoadFixed32(const char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;  // little-endian hosts only, as the formats
}

inline void StoreFixed32(char* p, uint32_t v) { std::memcpy(p, &v, 4); }

// Overwrites the last 4 bytes of `bytes` with the CRC-32C of every byte before them (the
// trailer of a tile encoding and of a log record). Shorter inputs are left alone.
inline void FixTrailingCrc(char* bytes, size_t size) {
  if (size < 4) return;
  StoreFixed32(bytes + size - 4, storage::Crc32c(std::string_view(bytes, size - 4)));
}

// Restores every checksum of a map archive (storage/include/bgkmap/storage/map_archive.h):
// each tile encoding's own trailer, and the archive trailer's CRC of every byte before it. Walks
// the entries as the reader does and stops where the structure ends or breaks.
inline void FixArchiveCrcs(std::string& a) {
  constexpr size_t kMagic = 8;
  if (a.size() < kMagic + 4) return;
  size_t at = kMagic + 4 + LoadFixed32(a.data() + kMagic);
  while (at < a.size()) {
    if (a[at] == 'T' && a.size() - at >= 13) {
      const size_t length = LoadFixed32(a.data() + at + 9);
      if (length > a.size() - at - 13) return;
      FixTrailingCrc(a.data() + at + 13, length);
      at += 13 + length;
    } else if (a[at] == 'E' && a.size() - at >= 13) {
      StoreFixed32(a.data() + at + 9, storage::Crc32c(std::string_view(a.data(), at + 9)));
      return;
    } else {
      return;
    }
  }
}

}  // namespace bgkmap::fuzz
