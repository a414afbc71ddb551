// Writes MCAP files (https://mcap.dev/spec): Header "ros2" profile, then each message in a chunk
// of its own (zstd-compressed, or uncompressed) with its CRC and message index, Data End with
// the data section's CRC, and a summary (schemas, channels, statistics, chunk indexes and summary
// offsets) with the footer's summary CRC, so that both streaming readers and indexed readers
// (seeking through the summary) read it. The inverse of mcap_reader.h.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "bgkmap/core/status.h"

namespace bgkmap::io {

class McapWriter {
 public:
  explicit McapWriter(bool compress = true);

  // Returns the schema's id. `encoding` is "ros2msg" for ROS 2 message definitions.
  uint16_t AddSchema(const std::string& name, const std::string& encoding, const std::string& data);
  // Returns the channel's id; message encoding "cdr".
  uint16_t AddChannel(uint16_t schema_id, const std::string& topic);
  void AddMessage(uint16_t channel_id, uint64_t log_time_ns, std::string data);

  // The whole file, summary and footer included.
  std::string Finish() const;
  Status WriteFile(const std::string& path) const;

  // Where a chunk of one message lies, for the summary's Chunk Index record.
  struct ChunkIndex {
    uint64_t time, start, length, index_start, index_length, compressed, uncompressed;
    uint16_t channel;
    std::string compression;
  };

 private:
  struct Schema {
    uint16_t id;
    std::string name, encoding, data;
  };
  struct Channel {
    uint16_t id, schema_id;
    std::string topic;
  };
  struct Message {
    uint16_t channel_id;
    uint64_t log_time;
    std::string data;
  };
  ChunkIndex WriteChunk(std::string& s, const Message& m, uint32_t sequence) const;
  void WriteSummary(std::string& s, const std::vector<ChunkIndex>& chunks,
                    const std::map<uint16_t, uint64_t>& counts) const;
  void StatisticsRecord(std::string& s, const std::vector<ChunkIndex>& chunks,
                        const std::map<uint16_t, uint64_t>& counts) const;

  bool compress_;
  std::vector<Schema> schemas_;
  std::vector<Channel> channels_;
  std::vector<Message> messages_;
};

}  // namespace bgkmap::io
