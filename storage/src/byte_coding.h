// Little-endian fixed-width and varint encoding into strings, and a bounds-checked reader: the
// building blocks of the tile, log record and archive formats.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace bgkmap::storage {

class ByteWriter {
 public:
  explicit ByteWriter(std::string* out) : out_(out) {}

  void PutU8(uint8_t v) { out_->push_back(static_cast<char>(v)); }
  void PutFixed32(uint32_t v);
  void PutFixed64(uint64_t v);
  void PutVarint(uint64_t v);
  void PutSignedVarint(int64_t v);  // zigzag, so small negative numbers stay short
  void PutDouble(double v);         // the IEEE bits, exactly
  void PutBytes(std::string_view bytes) { out_->append(bytes); }
  void PutLengthPrefixed(std::string_view bytes);

  // Appends `count` values of `width` bytes as `width` byte planes (all first bytes, then all
  // second bytes...): neighbouring values share sign, exponent and high mantissa bytes, so the
  // planes compress far better than the interleaved values.
  void PutShuffled(const void* values, size_t count, size_t width);

  size_t size() const { return out_->size(); }

 private:
  std::string* out_;
};

// Every Get* returns false (and leaves the output unspecified) if the input is too short or
// malformed; callers turn that into a DataLoss status naming what they were reading.
class ByteReader {
 public:
  explicit ByteReader(std::string_view in) : in_(in) {}

  bool GetU8(uint8_t* v);
  bool GetFixed32(uint32_t* v);
  bool GetFixed64(uint64_t* v);
  bool GetVarint(uint64_t* v);
  bool GetSignedVarint(int64_t* v);
  bool GetDouble(double* v);
  bool GetBytes(size_t n, std::string_view* bytes);
  bool GetLengthPrefixed(std::string_view* bytes);
  // Inverse of ByteWriter::PutShuffled; `values` has room for `count` values of `width` bytes.
  bool GetShuffled(void* values, size_t count, size_t width);

  size_t remaining() const { return in_.size() - pos_; }
  size_t position() const { return pos_; }

 private:
  std::string_view in_;
  size_t pos_ = 0;
};

}  // namespace bgkmap::storage
