// A reader of OMG CDR (XCDR1) as ROS 2 serializes messages: a 4-byte encapsulation header
// (0x00 0x00 big-endian, 0x00 0x01 little-endian, then two option bytes) and primitives aligned
// to their own size counted from the end of that header. Strings are a uint32 length that
// counts a terminating NUL, then the bytes; sequences a uint32 count, then the elements.
//
// The same reader reads ROS 1's serialization (`kRos1`): little-endian, no header, no
// alignment, strings without the NUL.
//
// Reads never go past the buffer: the first short or malformed read records an error naming the
// field, every later read returns zero, and status() reports the first error.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

// How a recording's messages are serialized.
enum class RosEncoding { kCdr, kRos1 };

class CdrReader {
 public:
  // `message` names the message in errors (e.g. "sensor_msgs/msg/PointCloud2").
  CdrReader(std::span<const uint8_t> bytes, std::string message,
            RosEncoding encoding = RosEncoding::kCdr);

  bool ros1() const { return ros1_; }
  bool big_endian() const { return big_endian_; }
  uint8_t U8(const char* field);
  bool Bool(const char* field);
  uint32_t U32(const char* field);
  int32_t I32(const char* field);
  double F64(const char* field);
  std::string String(const char* field);
  // A uint32 element count, checked against the bytes left (each element takes at least
  // `min_element_bytes`), so a corrupt count cannot ask for gigabytes.
  uint32_t SequenceLength(const char* field, size_t min_element_bytes);
  // A uint8[] as a view into the buffer.
  std::span<const uint8_t> Bytes(const char* field);

  const Status& status() const { return status_; }
  bool ok() const { return status_.ok(); }
  size_t remaining() const { return bytes_.size() - pos_; }

 private:
  bool Take(size_t align, size_t size, const char* field, const uint8_t** out);
  void Fail(const char* field, const std::string& why);

  std::span<const uint8_t> bytes_;
  std::string message_;
  size_t pos_ = 4;
  bool big_endian_ = false;
  bool ros1_ = false;
  Status status_;
};

// Loads a value of size N stored with the given byte order (the PointCloud2 field decoders share
// it with the reader).
template <typename T>
T LoadScalar(const uint8_t* p, bool big_endian);

}  // namespace bgkmap::io
