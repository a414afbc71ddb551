#include "bgkmap/io/rosbag2_sqlite.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <filesystem>
#include <memory>

namespace bgkmap::io {
namespace {

struct CloseDb {
  void operator()(sqlite3* db) const { sqlite3_close(db); }
};
struct FinalizeStmt {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};

std::string Text(sqlite3_stmt* s, int col) {
  const unsigned char* t = sqlite3_column_text(s, col);
  return t ? reinterpret_cast<const char*>(t) : "";
}

}  // namespace

Result<std::vector<RecordedMessage>> ReadRosbag2Sqlite(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Status::IoError(path + ": no such file");
  }
  sqlite3* raw = nullptr;
  const int opened = sqlite3_open_v2(path.c_str(), &raw, SQLITE_OPEN_READONLY, nullptr);
  std::unique_ptr<sqlite3, CloseDb> db(raw);
  if (opened != SQLITE_OK) {
    return Status::IoError(fmt::format("{}: cannot open ({})", path, sqlite3_errstr(opened)));
  }
  const char* sql =
      "SELECT topics.name, topics.type, topics.serialization_format, messages.data "
      "FROM messages JOIN topics ON messages.topic_id = topics.id "
      "ORDER BY messages.timestamp, messages.id";
  sqlite3_stmt* stmt_raw = nullptr;
  if (sqlite3_prepare_v2(db.get(), sql, -1, &stmt_raw, nullptr) != SQLITE_OK) {
    return Status::DataLoss(
        fmt::format("{}: not a rosbag2 SQLite database ({})", path, sqlite3_errmsg(db.get())));
  }
  std::unique_ptr<sqlite3_stmt, FinalizeStmt> stmt(stmt_raw);
  std::vector<RecordedMessage> out;
  int step;
  while ((step = sqlite3_step(stmt.get())) == SQLITE_ROW) {
    RecordedMessage m{Text(stmt.get(), 0), Text(stmt.get(), 1), Text(stmt.get(), 2), {}};
    const void* blob = sqlite3_column_blob(stmt.get(), 3);
    const int n = sqlite3_column_bytes(stmt.get(), 3);
    if (blob != nullptr && n > 0) m.data.assign(static_cast<const char*>(blob), n);
    out.push_back(std::move(m));
  }
  if (step != SQLITE_DONE) {
    return Status::DataLoss(
        fmt::format("{}: reading messages: {}", path, sqlite3_errmsg(db.get())));
  }
  return out;
}

}  // namespace bgkmap::io
