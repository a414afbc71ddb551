#include "byte_coding.h"

#include <bit>
#include <cstring>

namespace bgkmap::storage {

static_assert(std::endian::native == std::endian::little,
              "the storage formats are little-endian; add byte swaps for this platform");

void ByteWriter::PutFixed32(uint32_t v) {
  char b[4];
  std::memcpy(b, &v, 4);
  out_->append(b, 4);
}

void ByteWriter::PutFixed64(uint64_t v) {
  char b[8];
  std::memcpy(b, &v, 8);
  out_->append(b, 8);
}

void ByteWriter::PutVarint(uint64_t v) {
  while (v >= 0x80) {
    out_->push_back(static_cast<char>((v & 0x7F) | 0x80));
    v >>= 7;
  }
  out_->push_back(static_cast<char>(v));
}

void ByteWriter::PutSignedVarint(int64_t v) {
  PutVarint((static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63));
}

void ByteWriter::PutDouble(double v) { PutFixed64(std::bit_cast<uint64_t>(v)); }

void ByteWriter::PutLengthPrefixed(std::string_view bytes) {
  PutVarint(bytes.size());
  out_->append(bytes);
}

void ByteWriter::PutShuffled(const void* values, size_t count, size_t width) {
  const size_t start = out_->size();
  out_->resize(start + count * width);
  const auto* src = static_cast<const unsigned char*>(values);
  char* dst = out_->data() + start;
  for (size_t plane = 0; plane < width; ++plane) {
    for (size_t i = 0; i < count; ++i) *dst++ = static_cast<char>(src[i * width + plane]);
  }
}

bool ByteReader::GetU8(uint8_t* v) {
  if (remaining() < 1) return false;
  *v = static_cast<uint8_t>(in_[pos_++]);
  return true;
}

bool ByteReader::GetFixed32(uint32_t* v) {
  if (remaining() < 4) return false;
  std::memcpy(v, in_.data() + pos_, 4);
  pos_ += 4;
  return true;
}

bool ByteReader::GetFixed64(uint64_t* v) {
  if (remaining() < 8) return false;
  std::memcpy(v, in_.data() + pos_, 8);
  pos_ += 8;
  return true;
}

bool ByteReader::GetVarint(uint64_t* v) {
  uint64_t result = 0;
  for (int shift = 0; shift <= 63; shift += 7) {
    if (remaining() < 1) return false;
    const auto byte = static_cast<uint8_t>(in_[pos_++]);
    result |= static_cast<uint64_t>(byte & 0x7F) << shift;
    if ((byte & 0x80) == 0) {
      *v = result;
      return true;
    }
  }
  return false;  // more than 10 bytes: not a varint we wrote
}

bool ByteReader::GetSignedVarint(int64_t* v) {
  uint64_t u;
  if (!GetVarint(&u)) return false;
  *v = static_cast<int64_t>((u >> 1) ^ (~(u & 1) + 1));
  return true;
}

bool ByteReader::GetDouble(double* v) {
  uint64_t bits;
  if (!GetFixed64(&bits)) return false;
  *v = std::bit_cast<double>(bits);
  return true;
}

bool ByteReader::GetBytes(size_t n, std::string_view* bytes) {
  if (remaining() < n) return false;
  *bytes = in_.substr(pos_, n);
  pos_ += n;
  return true;
}

bool ByteReader::GetLengthPrefixed(std::string_view* bytes) {
  uint64_t n;
  return GetVarint(&n) && GetBytes(n, bytes);
}

bool ByteReader::GetShuffled(void* values, size_t count, size_t width) {
  if (width != 0 && count > remaining() / width) return false;
  auto* dst = static_cast<unsigned char*>(values);
  const char* src = in_.data() + pos_;
  for (size_t plane = 0; plane < width; ++plane) {
    for (size_t i = 0; i < count; ++i) dst[i * width + plane] = static_cast<unsigned char>(*src++);
  }
  pos_ += count * width;
  return true;
}

}  // namespace bgkmap::storage
