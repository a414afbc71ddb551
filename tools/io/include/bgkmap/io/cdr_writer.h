// Writes OMG CDR (XCDR1) little-endian, as ROS 2 serializes messages: the encapsulation header
// 0x00 0x01 0x00 0x00, primitives aligned to their size from the end of the header, strings as
// a uint32 length counting a NUL, then the bytes and the NUL. The inverse of CdrReader.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace bgkmap::io {

class CdrWriter {
 public:
  CdrWriter();

  void U8(uint8_t v) { Put(&v, 1, 1); }
  void I8(int8_t v) { Put(&v, 1, 1); }
  void U16(uint16_t v) { Put(&v, 2, 2); }
  void U32(uint32_t v) { Put(&v, 4, 4); }
  void I32(int32_t v) { Put(&v, 4, 4); }
  void F32(float v) { Put(&v, 4, 4); }
  void F64(double v) { Put(&v, 8, 8); }
  void String(std::string_view s);
  // A sequence's element count (the elements follow).
  void Length(size_t n) { U32(static_cast<uint32_t>(n)); }
  // A uint8[] / int8[]: the count, then the bytes.
  void Bytes(std::span<const uint8_t> bytes);
  // A float32[]: the count, then the values.
  void Floats(std::span<const float> values);

  const std::string& bytes() const { return out_; }
  std::string Take() { return std::move(out_); }

 private:
  void Align(size_t n);
  void Put(const void* v, size_t size, size_t align);
  std::string out_;
};

}  // namespace bgkmap::io
