// A retained scan's points are stored once: its log record keeps the prepared scan's headers and
// a CRC of its cells, and reading it prepares the raw scan kept beside it again (docs/storage.md,
// "Raw points stored once").
#include <gtest/gtest.h>

#include <bit>
#include <cstring>

#include "bgkmap/storage/log_record.h"
#include "bgkmap/storage/recovery.h"
#include "store_test_util.h"

namespace bgkmap::storage {
namespace {

using testing::MakeRawScan;
using testing::SmallParams;
using testing::TempDir;

StoreOptions WithRetention(bool retain) {
  StoreOptions o;
  o.durability = Durability::kPeriodic;
  if (retain) o.retention.max_bytes = uint64_t{1} << 30;
  return o;
}

LogRecord ScanRecord(const MapParams& params, uint64_t version, const RawScan& source) {
  Result<PreparedScan> prepared = PrepareScan(params, source.points, source.pose);
  EXPECT_TRUE(prepared.ok()) << prepared.status().ToString();
  prepared->stamp_ns = 5'000'000'000LL + static_cast<int64_t>(version);
  const int64_t stamp = prepared->stamp_ns;
  LogRecord record = LogRecord::Scan(version, "rover", version,
                                     std::make_shared<const PreparedScan>(*prepared), stamp);
  record.raw_scan = std::make_shared<const RawScan>(source);
  return record;
}

std::vector<LogRecord> ReadAll(const TileStore& store, ScanLog::LogRead mode) {
  std::vector<LogRecord> out;
  Status s = store.log().ForEach(
      0,
      [&](uint64_t, Result<LogRecord> record) -> Status {
        EXPECT_TRUE(record.ok()) << record.status().ToString();
        if (record.ok()) out.push_back(std::move(*record));
        return Status::Ok();
      },
      mode);
  EXPECT_TRUE(s.ok()) << s.ToString();
  return out;
}

void ExpectSameCells(const PreparedScan& a, const PreparedScan& b) {
  ASSERT_EQ(a.cells.size(), b.cells.size());
  ASSERT_FALSE(a.cells.empty());
  for (size_t i = 0; i < a.cells.size(); ++i) {
    EXPECT_EQ(a.cells[i].cell, b.cells[i].cell);
    EXPECT_EQ(std::bit_cast<uint64_t>(a.cells[i].y), std::bit_cast<uint64_t>(b.cells[i].y));
    EXPECT_EQ(a.cells[i].span_mm, b.cells[i].span_mm);
  }
}

TEST(RetainedScanLog, ARetainedScanIsLoggedWithoutItsCellsAndReadBackWhole) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto store = std::move(TileStore::Open(dir.path(), WithRetention(true), params)).value();
  const LogRecord record = ScanRecord(params, 1, MakeRawScan(0, 3));
  ASSERT_TRUE(store->log().Append(record).ok());

  // The record alone is its headers: a few tile keys and the CRC, not ~10 bytes per cell.
  const size_t whole_bytes = EncodeLogRecord(record).size();
  Result<LogStats> stats = store->log().Stats();
  ASSERT_TRUE(stats.ok());
  EXPECT_LT(stats->bytes * 4, whole_bytes) << stats->bytes << " of " << whole_bytes;

  const std::vector<LogRecord> whole = ReadAll(*store, ScanLog::LogRead::kWhole);
  ASSERT_EQ(whole.size(), 1u);
  EXPECT_FALSE(whole[0].cells_in_source);
  ExpectSameCells(*whole[0].scan, *record.scan);
  EXPECT_EQ(whole[0].scan->stamp_ns, record.scan->stamp_ns);
  EXPECT_EQ(whole[0].scan->write_tiles, record.scan->write_tiles);

  const std::vector<LogRecord> headers = ReadAll(*store, ScanLog::LogRead::kHeaders);
  ASSERT_EQ(headers.size(), 1u);
  EXPECT_TRUE(headers[0].cells_in_source);
  EXPECT_TRUE(headers[0].scan->cells.empty());
  EXPECT_EQ(headers[0].scan->write_tiles, record.scan->write_tiles);
  EXPECT_EQ(headers[0].scan->read_tiles, record.scan->read_tiles);
  EXPECT_EQ(headers[0].cells_crc, LoggedCellsCrc(*record.scan));
}

// A store written before spans were kept (record format 4): its records' CRCs are of cells
// without spans, and their scans were integrated without them, so they replay so.
TEST(RetainedScanLog, AFormat4RecordPreparesAgainWithoutSpans) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto store = std::move(TileStore::Open(dir.path(), WithRetention(true), params)).value();
  const LogRecord record = ScanRecord(params, 1, MakeRawScan(0, 3));
  ASSERT_TRUE(store->log().Append(record).ok());  // keeps the raw scan under version 1
  bool any_span = false;
  for (const ObservedCell& c : record.scan->cells) any_span |= c.span_mm > 0;
  ASSERT_TRUE(any_span) << "the scan must have cells of several points";

  LogRecord old = ReadAll(*store, ScanLog::LogRead::kHeaders).at(0);
  old.format = 4;
  old.cells_crc = LoggedCellsCrc(*record.scan, 4);
  Result<std::shared_ptr<const PreparedScan>> cells = store->log().LoadCells(1, old);
  ASSERT_TRUE(cells.ok()) << cells.status().ToString();
  ASSERT_EQ((*cells)->cells.size(), record.scan->cells.size());
  for (const ObservedCell& c : (*cells)->cells) EXPECT_EQ(c.span_mm, 0);
  // The same record as this build writes it prepares with its spans.
  LogRecord now = ReadAll(*store, ScanLog::LogRead::kHeaders).at(0);
  cells = store->log().LoadCells(1, now);
  ASSERT_TRUE(cells.ok()) << cells.status().ToString();
  ExpectSameCells(**cells, *record.scan);
}

TEST(RetainedScanLog, WithoutRetentionTheRecordKeepsItsCells) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto store = std::move(TileStore::Open(dir.path(), WithRetention(false), params)).value();
  const LogRecord record = ScanRecord(params, 1, MakeRawScan(0, 3));
  ASSERT_TRUE(store->log().Append(record).ok());
  const std::vector<LogRecord> headers = ReadAll(*store, ScanLog::LogRead::kHeaders);
  ASSERT_EQ(headers.size(), 1u);
  EXPECT_FALSE(headers[0].cells_in_source);
  ExpectSameCells(*headers[0].scan, *record.scan);
}

// A raw scan that does not prepare to the logged cells (here: kept with another pose than the
// cells were prepared with; in life, a build that prepares scans otherwise) is that record's
// DataLoss, never other cells replayed silently. Recovery reports it as a corrupt record.
TEST(RetainedScanLog, ARawScanThatPreparesToOtherCellsIsDataLoss) {
  TempDir dir;
  const MapParams params = SmallParams();
  auto store = std::move(TileStore::Open(dir.path(), WithRetention(true), params)).value();
  LogRecord good = ScanRecord(params, 1, MakeRawScan(0, 3));
  LogRecord bad = ScanRecord(params, 2, MakeRawScan(0, 4));
  auto moved = std::make_shared<RawScan>(*bad.raw_scan);
  moved->pose.translation.z() += 0.05;
  bad.raw_scan = moved;
  ASSERT_TRUE(store->log().Append(good).ok());
  ASSERT_TRUE(store->log().Append(bad).ok());

  std::vector<std::string> failures;
  int whole = 0;
  ASSERT_TRUE(store->log()
                  .ForEach(0,
                           [&](uint64_t, Result<LogRecord> record) -> Status {
                             if (record.ok()) {
                               ++whole;
                             } else {
                               failures.push_back(record.status().message());
                             }
                             return Status::Ok();
                           })
                  .ok());
  EXPECT_EQ(whole, 1);
  ASSERT_EQ(failures.size(), 1u);
  EXPECT_NE(failures[0].find("log record 2"), std::string::npos) << failures[0];
  EXPECT_NE(failures[0].find("prepares to other cells"), std::string::npos) << failures[0];

  auto map = testing::NewMap(params);
  Result<RecoveryReport> report = RecoverMap(*store, *map);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->scans_replayed, 1u);
  EXPECT_EQ(report->corrupt_records, std::vector<uint64_t>{2});
}

}  // namespace
}  // namespace bgkmap::storage
