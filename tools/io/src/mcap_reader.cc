#include "bgkmap/io/mcap_reader.h"

#include <fmt/format.h>
#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <cstring>

#include "binary_file.h"

namespace bgkmap::io {
namespace {

constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);
constexpr size_t kRecordHeader = 1 + 8;  // opcode, content length
constexpr size_t kFooterContent = 8 + 8 + 4;

enum Opcode : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kDataEnd = 0x0F,
};

uint32_t Crc32(std::string_view bytes) {
  uLong crc = crc32(0L, Z_NULL, 0);
  // zlib's length is a uInt: feed large buffers in pieces.
  while (!bytes.empty()) {
    const size_t n = std::min<size_t>(bytes.size(), 1u << 30);
    crc = crc32(crc, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(n));
    bytes.remove_prefix(n);
  }
  return static_cast<uint32_t>(crc);
}

template <typename T>
T LoadLE(const char* p) {
  T v = 0;
  for (size_t i = 0; i < sizeof(T); ++i) {
    v |= static_cast<T>(static_cast<uint8_t>(p[i])) << (8 * i);
  }
  return v;
}

// The little-endian fields of one record's content; any short read makes ok() false.
class Fields {
 public:
  explicit Fields(std::string_view bytes) : rest_(bytes) {}
  template <typename T>
  T Int() {
    if (!ok_ || rest_.size() < sizeof(T)) return Short<T>();
    const T v = LoadLE<T>(rest_.data());
    rest_.remove_prefix(sizeof(T));
    return v;
  }
  // A uint32-length prefixed string or byte array; a uint64 one with `long_prefix`.
  std::string_view Prefixed(bool long_prefix = false) {
    const uint64_t n = long_prefix ? Int<uint64_t>() : Int<uint32_t>();
    if (!ok_ || n > rest_.size()) return Short<std::string_view>();
    const std::string_view v = rest_.substr(0, n);
    rest_.remove_prefix(n);
    return v;
  }
  std::string_view Rest() {
    const std::string_view v = rest_;
    rest_ = {};
    return v;
  }
  bool ok() const { return ok_; }

 private:
  template <typename T>
  T Short() {
    ok_ = false;
    return T{};
  }
  std::string_view rest_;
  bool ok_ = true;
};

class Parser {
 public:
  Parser(const std::string& name, const McapLimits& limits, McapContents* out)
      : name_(name), limits_(limits), out_(out) {}

  Status File(std::string_view bytes);

 private:
  // Parses the records of `bytes` (at file offset `base`, or inside the chunk at `base`).
  // Stops after a Data End or Footer record outside chunks and sets *data_end to its offset.
  Status Records(std::string_view bytes, uint64_t base, bool in_chunk, uint64_t* data_end);
  Status Record(uint8_t op, std::string_view content, uint64_t offset, bool in_chunk);
  Status Chunk(std::string_view content, uint64_t offset);
  Result<std::string> Decompress(std::string_view compression, std::string_view data, uint64_t size,
                                 uint64_t offset);
  Status Footer(std::string_view bytes, uint64_t footer_at);
  Status Error(uint64_t offset, uint8_t op, const std::string& what) const {
    return Status::DataLoss(
        fmt::format("{}: record at byte {} (opcode 0x{:02x}): {}", name_, offset, op, what));
  }

  const std::string& name_;
  const McapLimits& limits_;
  McapContents* out_;
};

Status Parser::File(std::string_view bytes) {
  if (!LooksLikeMcap(bytes)) {
    return Status::DataLoss(name_ + ": not an MCAP file (no magic \\x89MCAP0\\r\\n at byte 0)");
  }
  uint64_t data_end = 0;
  if (Status s = Records(bytes.substr(kMagic.size()), kMagic.size(), false, &data_end); !s.ok())
    return s;
  if (bytes.size() < kMagic.size() * 2 + kRecordHeader + kFooterContent ||
      bytes.substr(bytes.size() - kMagic.size()) != kMagic) {
    return Status::DataLoss(
        fmt::format("{}: truncated: no closing magic after the footer (the file ends at byte {})",
                    name_, bytes.size()));
  }
  return Footer(bytes, bytes.size() - kMagic.size() - kRecordHeader - kFooterContent);
}

Status Parser::Footer(std::string_view bytes, uint64_t at) {
  if (static_cast<uint8_t>(bytes[at]) != kFooter ||
      LoadLE<uint64_t>(bytes.data() + at + 1) != kFooterContent) {
    return Status::DataLoss(
        fmt::format("{}: no Footer record at byte {} before the closing magic", name_, at));
  }
  Fields f(bytes.substr(at + kRecordHeader, kFooterContent));
  const uint64_t summary_start = f.Int<uint64_t>();
  f.Int<uint64_t>();  // summary_offset_start
  const uint32_t summary_crc = f.Int<uint32_t>();
  if (summary_start == 0 || summary_crc == 0 || !limits_.verify_crcs) return Status::Ok();
  if (summary_start > at) {
    return Error(at, kFooter, fmt::format("summary_start {} lies past the footer", summary_start));
  }
  const uint64_t covered = at + kRecordHeader + 16 - summary_start;
  if (const uint32_t crc = Crc32(bytes.substr(summary_start, covered)); crc != summary_crc) {
    return Error(
        at, kFooter,
        fmt::format("summary CRC mismatch (stored {:08x}, computed {:08x})", summary_crc, crc));
  }
  return Status::Ok();
}

Status Parser::Records(std::string_view bytes, uint64_t base, bool in_chunk, uint64_t* data_end) {
  size_t pos = 0;
  while (pos < bytes.size()) {
    const uint64_t offset = base + pos;
    if (bytes.size() - pos < kRecordHeader) {
      return Status::DataLoss(fmt::format("{}: truncated record header at byte {}", name_, offset));
    }
    const uint8_t op = static_cast<uint8_t>(bytes[pos]);
    const uint64_t length = LoadLE<uint64_t>(bytes.data() + pos + 1);
    if (length > bytes.size() - pos - kRecordHeader) {
      return Error(offset, op,
                   fmt::format("truncated: {} content bytes declared, {} left", length,
                               bytes.size() - pos - kRecordHeader));
    }
    const std::string_view content = bytes.substr(pos + kRecordHeader, length);
    if (!in_chunk && (op == kDataEnd || op == kFooter)) {
      *data_end = offset;
      if (op == kDataEnd) {
        const uint32_t stored = Fields(content).Int<uint32_t>();
        // The CRC covers every byte from the file's start to this record: the magic is `base`
        // bytes before `bytes`.
        const std::string_view covered(bytes.data() - base, offset);
        const bool check = stored != 0 && limits_.verify_crcs;
        if (const uint32_t crc = check ? Crc32(covered) : stored; crc != stored) {
          return Error(offset, op,
                       fmt::format("data section CRC mismatch (stored {:08x}, computed {:08x})",
                                   stored, crc));
        }
      }
      return Status::Ok();
    }
    if (Status s = Record(op, content, offset, in_chunk); !s.ok()) return s;
    pos += kRecordHeader + length;
  }
  if (in_chunk) return Status::Ok();
  return Status::DataLoss(
      fmt::format("{}: truncated: no Data End or Footer record (the file ends at byte {})", name_,
                  base + bytes.size()));
}

Status Parser::Record(uint8_t op, std::string_view content, uint64_t offset, bool in_chunk) {
  Fields f(content);
  switch (op) {
    case kHeader: {
      out_->profile = f.Prefixed();
      out_->library = f.Prefixed();
      break;
    }
    case kSchema: {
      McapSchema s;
      s.id = f.Int<uint16_t>();
      s.name = f.Prefixed();
      s.encoding = f.Prefixed();
      s.data = f.Prefixed();
      if (f.ok() && s.id == 0) return Error(offset, op, "schema id 0 is reserved");
      if (f.ok()) out_->schemas[s.id] = std::move(s);
      break;
    }
    case kChannel: {
      McapChannel c;
      c.id = f.Int<uint16_t>();
      c.schema_id = f.Int<uint16_t>();
      c.topic = f.Prefixed();
      c.message_encoding = f.Prefixed();
      f.Prefixed();  // metadata map: byte length, then pairs
      if (f.ok() && c.schema_id != 0 && !out_->schemas.contains(c.schema_id)) {
        return Error(offset, op,
                     fmt::format("channel {} ({}) names schema {}, not defined before it", c.id,
                                 c.topic, c.schema_id));
      }
      if (f.ok()) out_->channels[c.id] = std::move(c);
      break;
    }
    case kMessage: {
      McapMessage m;
      m.channel_id = f.Int<uint16_t>();
      m.sequence = f.Int<uint32_t>();
      m.log_time = f.Int<uint64_t>();
      m.publish_time = f.Int<uint64_t>();
      m.data = f.Rest();
      if (f.ok() && !out_->channels.contains(m.channel_id)) {
        return Error(offset, op,
                     fmt::format("message on channel {}, not defined before it", m.channel_id));
      }
      if (f.ok()) out_->messages.push_back(std::move(m));
      break;
    }
    case kChunk:
      if (in_chunk) return Error(offset, op, "a chunk inside a chunk");
      return Chunk(content, offset);
    default:
      break;  // indexes, attachments, metadata, statistics: not needed to read the messages
  }
  if (!f.ok()) return Error(offset, op, "a field runs past the record's end (missing field)");
  return Status::Ok();
}

Status Parser::Chunk(std::string_view content, uint64_t offset) {
  Fields f(content);
  f.Int<uint64_t>();  // message_start_time
  f.Int<uint64_t>();  // message_end_time
  const uint64_t size = f.Int<uint64_t>();
  const uint32_t stored_crc = f.Int<uint32_t>();
  const std::string_view compression = f.Prefixed();
  const std::string_view records = f.Prefixed(/*long_prefix=*/true);
  if (!f.ok()) return Error(offset, kChunk, "a field runs past the record's end (missing field)");
  Result<std::string> plain = Decompress(compression, records, size, offset);
  if (!plain.ok()) return plain.status();
  if (stored_crc != 0 && limits_.verify_crcs) {
    if (const uint32_t crc = Crc32(*plain); crc != stored_crc) {
      return Error(
          offset, kChunk,
          fmt::format("chunk CRC mismatch (stored {:08x}, computed {:08x})", stored_crc, crc));
    }
  }
  return Records(*plain, offset, /*in_chunk=*/true, nullptr);
}

Result<std::string> Parser::Decompress(std::string_view compression, std::string_view data,
                                       uint64_t size, uint64_t offset) {
  if (compression.empty()) {
    if (data.size() != size) {
      return Error(offset, kChunk,
                   fmt::format("{} record bytes, uncompressed_size says {}", data.size(), size));
    }
    return std::string(data);
  }
  if (compression != "lz4" && compression != "zstd") {
    return Error(offset, kChunk,
                 fmt::format("unknown compression '{}' (known: none, lz4, zstd)", compression));
  }
  if (size > limits_.max_chunk_bytes) {
    return Error(offset, kChunk, fmt::format("uncompressed_size {} over the limit", size));
  }
  std::string out(size, '\0');
  size_t produced = 0;
  bool good = false;
  if (compression == "zstd") {
    produced = ZSTD_decompress(out.data(), out.size(), data.data(), data.size());
    good = !ZSTD_isError(produced);
  } else {
    LZ4F_dctx* ctx = nullptr;
    if (!LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) {
      size_t out_size = out.size(), in_size = data.size();
      const size_t r = LZ4F_decompress(ctx, out.data(), &out_size, data.data(), &in_size, nullptr);
      // 0 means the frame ended; all of the input must have been one frame.
      good = !LZ4F_isError(r) && r == 0 && in_size == data.size();
      produced = out_size;
    }
    LZ4F_freeDecompressionContext(ctx);
  }
  if (!good || produced != size) {
    return Error(offset, kChunk,
                 fmt::format("{} data does not decompress to uncompressed_size {} bytes",
                             compression, size));
  }
  return out;
}

}  // namespace

bool LooksLikeMcap(std::string_view bytes) { return bytes.substr(0, kMagic.size()) == kMagic; }

Result<McapContents> ParseMcap(std::string_view bytes, const std::string& name,
                               const McapLimits& limits) {
  McapContents out;
  Parser parser(name, limits, &out);
  if (Status s = parser.File(bytes); !s.ok()) return s;
  return out;
}

Result<McapContents> ReadMcapFile(const std::string& path, const McapLimits& limits) {
  Result<std::string> bytes = internal::ReadWholeFile(path);
  if (!bytes.ok()) return bytes.status();
  return ParseMcap(*bytes, path, limits);
}

}  // namespace bgkmap::io
