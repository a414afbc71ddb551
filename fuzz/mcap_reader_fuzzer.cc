// ParseMcap on arbitrary bytes, with and without its CRC checks (a mutation almost never
// matches a CRC; without them the fuzzer reaches the records behind): never crashes, never
// allocates beyond the chunk limit; what it returns is consistent (every message's channel and
// every channel's schema were defined).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "bgkmap/io/mcap_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  for (bool crcs : {false, true}) {
    io::McapLimits limits;
    limits.max_chunk_bytes = 16 << 20;
    limits.verify_crcs = crcs;
    Result<io::McapContents> mcap = io::ParseMcap(bytes, "fuzz.mcap", limits);
    if (!mcap.ok()) continue;
    for (const io::McapMessage& m : mcap->messages) {
      if (!mcap->channels.contains(m.channel_id)) std::abort();
    }
    for (const auto& [id, c] : mcap->channels) {
      if (c.schema_id != 0 && !mcap->schemas.contains(c.schema_id)) std::abort();
    }
  }
  return 0;
}
