#include "store_keys.h"

#include <cstring>

#include "byte_coding.h"

namespace bgkmap::storage {
namespace {

void PutBigEndian(std::string* out, uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out->push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

uint64_t GetBigEndian(std::string_view in) {
  uint64_t v = 0;
  for (char c : in) v = (v << 8) | static_cast<uint8_t>(c);
  return v;
}

uint32_t Biased(int v) { return static_cast<uint32_t>(v) ^ 0x80000000u; }
int Unbiased(uint64_t v) { return static_cast<int>(static_cast<uint32_t>(v) ^ 0x80000000u); }

}  // namespace

std::string TileKeyBytes(TileKey key) {
  std::string out;
  out.reserve(8);
  PutBigEndian(&out, Biased(key.x), 4);
  PutBigEndian(&out, Biased(key.y), 4);
  return out;
}

bool ParseTileKeyBytes(std::string_view bytes, TileKey* key) {
  if (bytes.size() != 8) return false;
  key->x = Unbiased(GetBigEndian(bytes.substr(0, 4)));
  key->y = Unbiased(GetBigEndian(bytes.substr(4, 4)));
  return true;
}

std::string VersionKeyBytes(uint64_t version) {
  std::string out;
  out.reserve(8);
  PutBigEndian(&out, version, 8);
  return out;
}

bool ParseVersionKeyBytes(std::string_view bytes, uint64_t* version) {
  if (bytes.size() != 8) return false;
  *version = GetBigEndian(bytes);
  return true;
}

std::string U64Bytes(uint64_t v) {
  std::string out(8, '\0');
  std::memcpy(out.data(), &v, 8);
  return out;
}

bool ParseU64Bytes(std::string_view bytes, uint64_t* v) {
  if (bytes.size() != 8) return false;
  std::memcpy(v, bytes.data(), 8);
  return true;
}

std::string TileKeyName(TileKey key) {
  std::string name = "(";  // appended piecewise: GCC 12 warns falsely on "(" + std::string
  name += std::to_string(key.x);
  name += ", ";
  name += std::to_string(key.y);
  name += ")";
  return name;
}

}  // namespace bgkmap::storage

namespace bgkmap::storage {

std::string EncodeVersionList(const std::vector<uint64_t>& versions) {
  std::string out;
  ByteWriter w(&out);
  w.PutVarint(versions.size());
  uint64_t prev = 0;
  for (uint64_t v : versions) {
    w.PutVarint(v - prev);
    prev = v;
  }
  return out;
}

bool DecodeVersionList(std::string_view bytes, std::vector<uint64_t>* versions) {
  ByteReader r(bytes);
  uint64_t n;
  if (!r.GetVarint(&n) || n > r.remaining()) return false;
  versions->clear();
  uint64_t v = 0;
  for (uint64_t i = 0; i < n; ++i) {
    uint64_t delta;
    if (!r.GetVarint(&delta) || delta > UINT64_MAX - v || (i > 0 && delta == 0)) return false;
    v += delta;
    versions->push_back(v);
  }
  return r.remaining() == 0;
}

}  // namespace bgkmap::storage
