// CRC-32C (Castagnoli), the checksum of every tile encoding, log record and archive entry.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace bgkmap::storage {

// CRC-32C of `data`, continuing from `crc` (the CRC of the bytes before it; 0 to start).
// Uses the SSE4.2 instruction when the CPU has it, a table otherwise; both give the same value.
uint32_t Crc32cExtend(uint32_t crc, const void* data, size_t size);

inline uint32_t Crc32c(std::string_view bytes) {
  return Crc32cExtend(0, bytes.data(), bytes.size());
}

}  // namespace bgkmap::storage
