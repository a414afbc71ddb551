#include "bgkmap/storage/log_record.h"

#include <gtest/gtest.h>

#include <bit>
#include <random>

#include "bgkmap/storage/crc32c.h"

namespace bgkmap::storage {
namespace {

std::shared_ptr<PreparedScan> RandomScan(unsigned seed, int cells) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> coord(-100000, 100000);
  std::normal_distribution<double> z(-1.7, 0.4);
  auto scan = std::make_shared<PreparedScan>();
  std::uniform_int_distribution<int> span(0, 1200);
  for (int i = 0; i < cells; ++i) {
    scan->cells.push_back({{coord(rng), coord(rng)}, z(rng), static_cast<uint16_t>(span(rng))});
  }
  std::sort(scan->cells.begin(), scan->cells.end(),
            [](const ObservedCell& a, const ObservedCell& b) { return a.cell < b.cell; });
  scan->counts = {1000, 900, 1, 2, 3, 94};
  scan->write_tiles = {{-3, 4}, {-3, 5}, {2, -1}};
  scan->read_tiles = {{-4, 4}, {INT32_MIN / 64, INT32_MAX / 64}};
  scan->sensor_z = 1.9;
  return scan;
}

void ExpectSameScan(const PreparedScan& a, const PreparedScan& b) {
  ASSERT_EQ(a.cells.size(), b.cells.size());
  for (size_t i = 0; i < a.cells.size(); ++i) {
    EXPECT_EQ(a.cells[i].cell, b.cells[i].cell);
    EXPECT_EQ(std::bit_cast<uint64_t>(a.cells[i].y), std::bit_cast<uint64_t>(b.cells[i].y));
    EXPECT_EQ(a.cells[i].span_mm, b.cells[i].span_mm);
  }
  EXPECT_EQ(a.write_tiles, b.write_tiles);
  EXPECT_EQ(a.read_tiles, b.read_tiles);
  EXPECT_EQ(a.counts.input, b.counts.input);
  EXPECT_EQ(a.counts.dropped_out_of_bounds, b.counts.dropped_out_of_bounds);
  EXPECT_EQ(std::bit_cast<uint64_t>(a.sensor_z), std::bit_cast<uint64_t>(b.sensor_z));
}

TEST(LogRecordTest, ScanRoundTripsExactly) {
  for (unsigned seed = 0; seed < 5; ++seed) {
    const auto scan = RandomScan(seed, 500 * static_cast<int>(seed));
    const LogRecord in = LogRecord::Scan(1234567 + seed, "robot-" + std::to_string(seed), 99 + seed,
                                         scan, -5'000'000'000LL);
    Result<LogRecord> out = DecodeLogRecord(EncodeLogRecord(in));
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    EXPECT_EQ(out->type, LogRecord::Type::kScan);
    EXPECT_EQ(out->version, in.version);
    EXPECT_EQ(out->robot_id, in.robot_id);
    EXPECT_EQ(out->sequence, in.sequence);
    EXPECT_EQ(out->stamp_ns, in.stamp_ns);
    // The scan carries it: a replay forgets with the map time the first run used.
    EXPECT_EQ(out->scan->stamp_ns, in.stamp_ns);
    ExpectSameScan(*in.scan, *out->scan);
  }
}

// Format >= 4: a scan whose cells are kept in its raw scan is its headers and the cells' CRC.
TEST(LogRecordTest, AScanWithItsCellsInItsSourceKeepsHeadersAndCrc) {
  const auto scan = RandomScan(3, 800);
  LogRecord in = LogRecord::Scan(77, "rover", 5, scan, 123);
  in.cells_in_source = true;
  in.cells_crc = LoggedCellsCrc(*scan);
  const std::string bytes = EncodeLogRecord(in);
  EXPECT_LT(bytes.size(), 100u);  // the 800 cells would be ~8 KB
  Result<LogRecord> out = DecodeLogRecord(bytes);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_TRUE(out->cells_in_source);
  EXPECT_EQ(out->cells_crc, in.cells_crc);
  EXPECT_TRUE(out->scan->cells.empty());
  EXPECT_EQ(out->scan->write_tiles, scan->write_tiles);
  EXPECT_EQ(out->scan->read_tiles, scan->read_tiles);
  EXPECT_EQ(out->scan->counts.kept, scan->counts.kept);
  // The CRC is of the cells: another cell's height or span changes it.
  auto other = std::make_shared<PreparedScan>(*scan);
  other->cells[400].y += 1e-9;
  EXPECT_NE(LoggedCellsCrc(*other), in.cells_crc);
  other = std::make_shared<PreparedScan>(*scan);
  ++other->cells[400].span_mm;
  EXPECT_NE(LoggedCellsCrc(*other), in.cells_crc);
  // Format 4 kept no spans: its CRC is of the cells without them (scan_log.cc replays such a
  // record with spans 0).
  EXPECT_EQ(LoggedCellsCrc(*other, 4), LoggedCellsCrc(*scan, 4));
}

// A record of format 4 (before spans were kept), written as that build wrote it: the format-5
// encoding without its spans. It decodes with every span 0, as it was integrated.
TEST(LogRecordTest, AFormat4ScanDecodesWithoutSpans) {
  auto scan = std::make_shared<PreparedScan>();
  for (int x = 0; x < 3; ++x) scan->cells.push_back({{x, 0}, 0.25 * x, 0});
  const std::string v5 = EncodeLogRecord(LogRecord::Scan(8, "r", 2, scan));
  // The spans are the last 3 bytes before the CRC (one varint 0 each).
  std::string v4 = v5.substr(0, v5.size() - 4 - 3);
  ASSERT_EQ(v5.substr(v5.size() - 7, 3), std::string(3, '\0'));
  v4[0] = 4;
  const uint32_t crc = Crc32c(v4);
  v4.append(reinterpret_cast<const char*>(&crc), 4);
  Result<LogRecord> out = DecodeLogRecord(v4);
  ASSERT_TRUE(out.ok()) << out.status().ToString();
  EXPECT_EQ(out->format, 4);
  ASSERT_EQ(out->scan->cells.size(), 3u);
  for (const ObservedCell& c : out->scan->cells) EXPECT_EQ(c.span_mm, 0);
  EXPECT_EQ(out->scan->cells[2].y, 0.5);
  EXPECT_EQ(DecodeLogRecord(v5)->format, kLogRecordFormat);
}

TEST(LogRecordTest, ClearRoundTrips) {
  const CellBox box{{-5, INT32_MIN}, {INT32_MAX, 7}};
  Result<LogRecord> out = DecodeLogRecord(EncodeLogRecord(LogRecord::Clear(42, box)));
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->type, LogRecord::Type::kClear);
  EXPECT_EQ(out->version, 42u);
  EXPECT_EQ(out->clear_box, box);
}

TEST(LogRecordTest, DenseScanCostsElevenBytesPerCell) {
  auto scan = std::make_shared<PreparedScan>();
  for (int x = 0; x < 100; ++x) {
    for (int y = 0; y < 100; ++y) scan->cells.push_back({{x, y}, -1.5 + 0.001 * x});
  }
  const std::string bytes = EncodeLogRecord(LogRecord::Scan(1, "r", 1, scan));
  EXPECT_LE(bytes.size(), 200u + 11u * scan->cells.size());  // + row jumps
}

TEST(LogRecordTest, EveryFlippedByteIsDataLoss) {
  const std::string good = EncodeLogRecord(LogRecord::Scan(9, "r1", 3, RandomScan(7, 20)));
  for (size_t i = 0; i < good.size(); ++i) {
    std::string bad = good;
    bad[i] = static_cast<char>(bad[i] ^ 0x01);
    const auto decoded = DecodeLogRecord(bad);
    ASSERT_FALSE(decoded.ok()) << "flip at byte " << i;
    EXPECT_EQ(decoded.status().code(), Status::Code::kDataLoss);
  }
  EXPECT_FALSE(DecodeLogRecord(good.substr(0, good.size() - 1)).ok());
}

// Found by log_record_fuzzer: a tile key delta of -2^63 overflowed int64 when added to the
// previous coordinate (UBSan: signed integer overflow; the result was refused anyway, so only the
// sanitizers see the difference). A delta beyond +-2^32 is malformed.
TEST(LogRecordTest, CoordinateDeltaBeyondInt32StepsIsMalformed) {
  // A first tile at x = -1 or +1 (zigzag varints 1, 2), then a step of -2^63, 2^63 - 1 or
  // 2^32 + 1 from there: the first two overflowed int64 before the fix.
  const std::pair<char, std::string> cases[] = {
      {'\x01', std::string("\xff\xff\xff\xff\xff\xff\xff\xff\xff\x01")},
      {'\x02', std::string("\xfe\xff\xff\xff\xff\xff\xff\xff\xff\x01")},
      {'\x02', std::string("\x82\x80\x80\x80\x20")}};
  for (const auto& [first_x, delta] : cases) {
    std::string bytes("\x01\x01\x07\x01r\x03\x00", 7);  // format, scan, version, "r", seq, stamp
    bytes += std::string(6, '\0');                      // point counts
    bytes += std::string(8, '\0');                      // sensor_z
    bytes += '\x02';                                    // two write tiles: x and y deltas
    bytes += std::string(1, first_x) + '\0' + delta + '\0';
    bytes += std::string(3, '\0');  // no read tiles, no cells
    const uint32_t crc = Crc32c(bytes);
    bytes.append(reinterpret_cast<const char*>(&crc), 4);
    const auto decoded = DecodeLogRecord(bytes);
    ASSERT_FALSE(decoded.ok());
    EXPECT_EQ(decoded.status().code(), Status::Code::kDataLoss);
  }
  // The largest real step, INT32_MIN to INT32_MAX, still decodes.
  auto scan = std::make_shared<PreparedScan>();
  scan->write_tiles = {{INT32_MIN, INT32_MAX}, {INT32_MAX, INT32_MIN}};
  const auto decoded = DecodeLogRecord(EncodeLogRecord(LogRecord::Scan(1, "r", 1, scan)));
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->scan->write_tiles, scan->write_tiles);
}

}  // namespace
}  // namespace bgkmap::storage
