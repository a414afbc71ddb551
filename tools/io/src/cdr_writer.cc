#include "bgkmap/io/cdr_writer.h"

#include <bit>
#include <cstring>

namespace bgkmap::io {

// The writer copies the host's bytes: it writes little-endian CDR on a little-endian host only.
static_assert(std::endian::native == std::endian::little, "CdrWriter assumes little-endian");

CdrWriter::CdrWriter() : out_("\x00\x01\x00\x00", 4) {}

void CdrWriter::Align(size_t n) {
  const size_t pos = out_.size() - 4;
  out_.append((n - pos % n) % n, '\0');
}

void CdrWriter::Put(const void* v, size_t size, size_t align) {
  Align(align);
  out_.append(static_cast<const char*>(v), size);
}

void CdrWriter::String(std::string_view s) {
  U32(static_cast<uint32_t>(s.size() + 1));
  out_.append(s);
  out_.push_back('\0');
}

void CdrWriter::Bytes(std::span<const uint8_t> bytes) {
  Length(bytes.size());
  out_.append(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

void CdrWriter::Floats(std::span<const float> values) {
  Length(values.size());
  Align(4);
  const size_t at = out_.size();
  out_.resize(at + values.size() * sizeof(float));
  if (!values.empty()) std::memcpy(out_.data() + at, values.data(), values.size() * sizeof(float));
}

}  // namespace bgkmap::io
