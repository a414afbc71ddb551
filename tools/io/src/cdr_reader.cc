#include "bgkmap/io/cdr_reader.h"

#include <fmt/format.h>

#include <bit>
#include <cstring>

namespace bgkmap::io {

template <typename T>
T LoadScalar(const uint8_t* p, bool big_endian) {
  uint8_t raw[sizeof(T)];
  std::memcpy(raw, p, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) {
    for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
  }
  T v;
  std::memcpy(&v, raw, sizeof(T));
  return v;
}

template uint8_t LoadScalar<uint8_t>(const uint8_t*, bool);
template int8_t LoadScalar<int8_t>(const uint8_t*, bool);
template uint16_t LoadScalar<uint16_t>(const uint8_t*, bool);
template int16_t LoadScalar<int16_t>(const uint8_t*, bool);
template uint32_t LoadScalar<uint32_t>(const uint8_t*, bool);
template int32_t LoadScalar<int32_t>(const uint8_t*, bool);
template uint64_t LoadScalar<uint64_t>(const uint8_t*, bool);
template float LoadScalar<float>(const uint8_t*, bool);
template double LoadScalar<double>(const uint8_t*, bool);

CdrReader::CdrReader(std::span<const uint8_t> bytes, std::string message, RosEncoding encoding)
    : bytes_(bytes), message_(std::move(message)), ros1_(encoding == RosEncoding::kRos1) {
  if (ros1_) {
    pos_ = 0;
    return;
  }
  if (bytes_.size() < 4 || bytes_[0] != 0 || bytes_[1] > 1) {
    pos_ = bytes_.size();
    status_ = Status::DataLoss(
        fmt::format("{}: not CDR (no encapsulation header CDR_BE or CDR_LE)", message_));
    return;
  }
  big_endian_ = bytes_[1] == 0;
}

void CdrReader::Fail(const char* field, const std::string& why) {
  if (!status_.ok()) return;
  status_ = Status::DataLoss(fmt::format("{}: field {}: {}", message_, field, why));
  pos_ = bytes_.size();
}

bool CdrReader::Take(size_t align, size_t size, const char* field, const uint8_t** out) {
  if (!status_.ok()) return false;
  // Alignment counts from the end of the 4-byte encapsulation header; ROS 1 packs.
  const size_t aligned = ros1_ ? pos_ : 4 + (pos_ - 4 + align - 1) / align * align;
  if (aligned > bytes_.size() || size > bytes_.size() - aligned) {
    Fail(field, fmt::format("message ends at byte {} (missing field or truncated)", bytes_.size()));
    return false;
  }
  *out = bytes_.data() + aligned;
  pos_ = aligned + size;
  return true;
}

uint8_t CdrReader::U8(const char* field) {
  const uint8_t* p;
  return Take(1, 1, field, &p) ? *p : 0;
}

bool CdrReader::Bool(const char* field) { return U8(field) != 0; }

uint32_t CdrReader::U32(const char* field) {
  const uint8_t* p;
  return Take(4, 4, field, &p) ? LoadScalar<uint32_t>(p, big_endian_) : 0;
}

int32_t CdrReader::I32(const char* field) {
  const uint8_t* p;
  return Take(4, 4, field, &p) ? LoadScalar<int32_t>(p, big_endian_) : 0;
}

double CdrReader::F64(const char* field) {
  const uint8_t* p;
  return Take(8, 8, field, &p) ? LoadScalar<double>(p, big_endian_) : 0.0;
}

std::string CdrReader::String(const char* field) {
  const uint32_t n = U32(field);
  if (!ok()) return {};
  if (n == 0) return {};  // some writers omit the NUL of an empty string
  const uint8_t* p;
  if (!Take(1, n, field, &p)) return {};
  if (ros1_) return std::string(reinterpret_cast<const char*>(p), n);
  if (p[n - 1] != 0) {
    Fail(field, "string without its terminating NUL");
    return {};
  }
  return std::string(reinterpret_cast<const char*>(p), n - 1);
}

uint32_t CdrReader::SequenceLength(const char* field, size_t min_element_bytes) {
  const uint32_t n = U32(field);
  if (ok() && min_element_bytes > 0 && n > remaining() / min_element_bytes) {
    Fail(field, fmt::format("{} elements do not fit in the {} bytes left", n, remaining()));
    return 0;
  }
  return n;
}

std::span<const uint8_t> CdrReader::Bytes(const char* field) {
  const uint32_t n = U32(field);
  const uint8_t* p;
  if (!ok() || !Take(1, n, field, &p)) return {};
  return {p, n};
}

}  // namespace bgkmap::io
