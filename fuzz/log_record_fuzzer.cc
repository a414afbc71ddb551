// DecodeLogRecord on arbitrary bytes (its trailing CRC-32C restored, fuzz_input.h): never
// crashes, and whatever decodes re-encodes to bytes that decode and re-encode to themselves.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "bgkmap/storage/log_record.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace bgkmap;
  std::string encoded(reinterpret_cast<const char*>(data), size);
  fuzz::FixTrailingCrc(encoded.data(), encoded.size());

  Result<storage::LogRecord> record = storage::DecodeLogRecord(encoded);
  if (!record.ok()) return 0;
  const std::string again = storage::EncodeLogRecord(*record);
  Result<storage::LogRecord> back = storage::DecodeLogRecord(again);
  if (!back.ok() || storage::EncodeLogRecord(*back) != again) std::abort();
  return 0;
}
