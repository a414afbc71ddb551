#include "bgkmap/io/mcap_writer.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <functional>
#include <map>
#include <tuple>

#include "binary_file.h"

namespace bgkmap::io {

using ChunkIndex = McapWriter::ChunkIndex;

namespace {

constexpr std::string_view kMagic("\x89MCAP0\r\n", 8);

enum Opcode : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Little-endian fields appended to a string.
struct Out {
  std::string& s;
  template <typename T>
  void Int(T v) {
    for (size_t i = 0; i < sizeof(T); ++i) s.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
  }
  void Str(std::string_view v) {
    Int<uint32_t>(static_cast<uint32_t>(v.size()));
    s.append(v);
  }
  void LongBytes(std::string_view v) {
    Int<uint64_t>(v.size());
    s.append(v);
  }
};

// Appends one record: opcode, content length, then what `fill` writes.
void Record(std::string& s, uint8_t op, const std::function<void(Out&)>& fill) {
  s.push_back(static_cast<char>(op));
  const size_t length_at = s.size();
  s.append(8, '\0');
  Out out{s};
  fill(out);
  uint64_t length = s.size() - length_at - 8;
  for (size_t i = 0; i < 8; ++i) s[length_at + i] = static_cast<char>((length >> (8 * i)) & 0xFF);
}

uint32_t Crc32(std::string_view bytes) {
  return static_cast<uint32_t>(crc32(crc32(0L, Z_NULL, 0),
                                     reinterpret_cast<const Bytef*>(bytes.data()),
                                     static_cast<uInt>(bytes.size())));
}

std::string Zstd(const std::string& in) {
  std::string out(ZSTD_compressBound(in.size()), '\0');
  const size_t n = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), 3);
  out.resize(ZSTD_isError(n) ? 0 : n);
  return out;
}

}  // namespace

McapWriter::McapWriter(bool compress) : compress_(compress) {}

uint16_t McapWriter::AddSchema(const std::string& name, const std::string& encoding,
                               const std::string& data) {
  const auto id = static_cast<uint16_t>(schemas_.size() + 1);
  schemas_.push_back({id, name, encoding, data});
  return id;
}

uint16_t McapWriter::AddChannel(uint16_t schema_id, const std::string& topic) {
  const auto id = static_cast<uint16_t>(channels_.size() + 1);
  channels_.push_back({id, schema_id, topic});
  return id;
}

void McapWriter::AddMessage(uint16_t channel_id, uint64_t log_time_ns, std::string data) {
  messages_.push_back({channel_id, log_time_ns, std::move(data)});
}

namespace {

void SchemaRecord(std::string& s, uint16_t id, const std::string& name, const std::string& encoding,
                  const std::string& data) {
  Record(s, kSchema, [&](Out& o) {
    o.Int<uint16_t>(id);
    o.Str(name);
    o.Str(encoding);
    o.Str(data);
  });
}

void ChannelRecord(std::string& s, uint16_t id, uint16_t schema_id, const std::string& topic) {
  Record(s, kChannel, [&](Out& o) {
    o.Int<uint16_t>(id);
    o.Int<uint16_t>(schema_id);
    o.Str(topic);
    o.Str("cdr");
    o.Int<uint32_t>(0);  // no metadata
  });
}

void ChunkIndexRecord(std::string& s, const ChunkIndex& c) {
  Record(s, kChunkIndex, [&](Out& o) {
    o.Int<uint64_t>(c.time);
    o.Int<uint64_t>(c.time);
    o.Int<uint64_t>(c.start);
    o.Int<uint64_t>(c.length);
    o.Int<uint32_t>(10);  // message_index_offsets: one channel
    o.Int<uint16_t>(c.channel);
    o.Int<uint64_t>(c.index_start);
    o.Int<uint64_t>(c.index_length);
    o.Str(c.compression);
    o.Int<uint64_t>(c.compressed);
    o.Int<uint64_t>(c.uncompressed);
  });
}

}  // namespace

ChunkIndex McapWriter::WriteChunk(std::string& s, const Message& m, uint32_t sequence) const {
  std::string plain;
  Record(plain, kMessage, [&](Out& o) {
    o.Int<uint16_t>(m.channel_id);
    o.Int<uint32_t>(sequence);
    o.Int<uint64_t>(m.log_time);
    o.Int<uint64_t>(m.log_time);
    o.s.append(m.data);
  });
  const std::string packed = compress_ ? Zstd(plain) : plain;
  ChunkIndex c{m.log_time,
               s.size(),
               0,
               0,
               0,
               packed.size(),
               plain.size(),
               m.channel_id,
               compress_ ? "zstd" : ""};
  Record(s, kChunk, [&](Out& o) {
    o.Int<uint64_t>(m.log_time);
    o.Int<uint64_t>(m.log_time);
    o.Int<uint64_t>(plain.size());
    o.Int<uint32_t>(Crc32(plain));
    o.Str(c.compression);
    o.LongBytes(packed);
  });
  c.length = s.size() - c.start;
  c.index_start = s.size();
  Record(s, kMessageIndex, [&](Out& o) {
    o.Int<uint16_t>(m.channel_id);
    o.Int<uint32_t>(16);
    o.Int<uint64_t>(m.log_time);
    o.Int<uint64_t>(0);  // the message's offset in the uncompressed chunk
  });
  c.index_length = s.size() - c.index_start;
  return c;
}

void McapWriter::WriteSummary(std::string& s, const std::vector<ChunkIndex>& chunks,
                              const std::map<uint16_t, uint64_t>& counts) const {
  const uint64_t summary_start = s.size();
  std::vector<std::tuple<uint8_t, uint64_t, uint64_t>> groups;
  const auto group = [&](uint8_t op, const std::function<void()>& write) {
    const uint64_t at = s.size();
    write();
    if (s.size() > at) groups.emplace_back(op, at, s.size() - at);
  };
  group(kSchema, [&] {
    for (const Schema& x : schemas_) SchemaRecord(s, x.id, x.name, x.encoding, x.data);
  });
  group(kChannel, [&] {
    for (const Channel& x : channels_) ChannelRecord(s, x.id, x.schema_id, x.topic);
  });
  group(kStatistics, [&] { StatisticsRecord(s, chunks, counts); });
  group(kChunkIndex, [&] {
    for (const ChunkIndex& c : chunks) ChunkIndexRecord(s, c);
  });
  const uint64_t offsets_start = s.size();
  for (const auto& g : groups) {  // not a structured binding: clang 14 cannot capture those
    Record(s, kSummaryOffset, [&](Out& o) {
      o.Int<uint8_t>(std::get<0>(g));
      o.Int<uint64_t>(std::get<1>(g));
      o.Int<uint64_t>(std::get<2>(g));
    });
  }
  // The summary CRC covers the summary up to the footer's summary_crc field.
  s.push_back(static_cast<char>(kFooter));
  Out o{s};
  o.Int<uint64_t>(20);
  o.Int<uint64_t>(summary_start);
  o.Int<uint64_t>(offsets_start);
  o.Int<uint32_t>(Crc32(std::string_view(s).substr(summary_start)));
}

void McapWriter::StatisticsRecord(std::string& s, const std::vector<ChunkIndex>& chunks,
                                  const std::map<uint16_t, uint64_t>& counts) const {
  uint64_t start_time = UINT64_MAX, end_time = 0;
  for (const Message& m : messages_) {
    start_time = std::min(start_time, m.log_time);
    end_time = std::max(end_time, m.log_time);
  }
  Record(s, kStatistics, [&](Out& o) {
    o.Int<uint64_t>(messages_.size());
    o.Int<uint16_t>(static_cast<uint16_t>(schemas_.size()));
    o.Int<uint32_t>(static_cast<uint32_t>(channels_.size()));
    o.Int<uint32_t>(0);  // attachments
    o.Int<uint32_t>(0);  // metadata
    o.Int<uint32_t>(static_cast<uint32_t>(chunks.size()));
    o.Int<uint64_t>(messages_.empty() ? 0 : start_time);
    o.Int<uint64_t>(end_time);
    o.Int<uint32_t>(static_cast<uint32_t>(counts.size() * 10));
    for (const auto& [id, n] : counts) {
      o.Int<uint16_t>(id);
      o.Int<uint64_t>(n);
    }
  });
}

std::string McapWriter::Finish() const {
  std::string s(kMagic);
  Record(s, kHeader, [](Out& o) {
    o.Str("ros2");
    o.Str("bgkmap");
  });
  for (const Schema& x : schemas_) SchemaRecord(s, x.id, x.name, x.encoding, x.data);
  for (const Channel& x : channels_) ChannelRecord(s, x.id, x.schema_id, x.topic);
  std::vector<ChunkIndex> chunks;
  std::map<uint16_t, uint64_t> counts;
  for (const Message& m : messages_) {
    chunks.push_back(WriteChunk(s, m, static_cast<uint32_t>(counts[m.channel_id]++)));
  }
  const uint32_t data_crc = Crc32(s);
  Record(s, kDataEnd, [&](Out& o) { o.Int<uint32_t>(data_crc); });
  WriteSummary(s, chunks, counts);
  s.append(kMagic);
  return s;
}

Status McapWriter::WriteFile(const std::string& path) const {
  return internal::WriteWholeFile(path, Finish());
}

}  // namespace bgkmap::io
