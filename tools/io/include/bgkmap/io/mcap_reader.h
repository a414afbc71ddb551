// A reader of MCAP files (https://mcap.dev/spec, version 0): the data section's records in file
// order, chunks uncompressed, "lz4" (LZ4 frame) or "zstd", with or without a summary section or
// message indexes (the data section is read front to back; indexes are not needed). Every CRC
// the file carries is checked: each chunk's uncompressed_crc, the Data End record's
// data_section_crc and the footer's summary_crc (a stored 0 means "not computed", as the spec
// says). Schemas, channels and messages are returned; attachments, metadata and indexes are
// skipped.
//
// The whole file is checked before anything is returned, so a caller that applies messages only
// after ReadMcap succeeds applies nothing of a bad file. Errors are one DataLoss line naming the
// file, the record's opcode and its byte offset.
#pragma once

#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

struct McapSchema {
  uint16_t id = 0;
  std::string name, encoding;  // e.g. "sensor_msgs/msg/PointCloud2", "ros2msg"
  std::string data;
};

struct McapChannel {
  uint16_t id = 0, schema_id = 0;
  std::string topic, message_encoding;  // e.g. "/points", "cdr"
};

struct McapMessage {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time = 0, publish_time = 0;  // nanoseconds
  std::string data;
};

struct McapContents {
  std::string profile, library;  // from the Header record
  std::map<uint16_t, McapSchema> schemas;
  std::map<uint16_t, McapChannel> channels;
  std::vector<McapMessage> messages;  // in file order
};

struct McapLimits {
  // A chunk claiming more uncompressed bytes than this is refused before any allocation.
  uint64_t max_chunk_bytes = uint64_t{1} << 32;
  // Off only for fuzzing: a mutated file almost never matches its CRCs, and what lies behind
  // them must be fuzzed too.
  bool verify_crcs = true;
};

// Parses a whole MCAP file held in memory; `name` prefixes errors.
Result<McapContents> ParseMcap(std::string_view bytes, const std::string& name,
                               const McapLimits& limits = {});

// Reads and parses the file at `path`.
Result<McapContents> ReadMcapFile(const std::string& path, const McapLimits& limits = {});

// True if `bytes` start with the MCAP magic.
bool LooksLikeMcap(std::string_view bytes);

}  // namespace bgkmap::io
