// The Prometheus endpoint (server.metrics_address): scraped with a plain socket, the exposition
// parses, every sample has its HELP and TYPE, and the values equal Info's after ingesting the
// street scans; a tile corrupted on disk shows as corrupt-tile metrics after a restart; only GET
// /metrics is served; malformed, oversized and idle clients neither crash nor block it; a bad
// address stops bgkmapd with one line naming the key.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/server/server_config.h"
#include "bgkmapd_process.h"
#include "stored_tile_damage.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

ServerConfig MetricsConfig(const std::string& data_dir = "") {
  ServerConfig c = TestConfig();
  c.metrics_address = "127.0.0.1:0";
  c.storage.data_dir = data_dir;
  return c;
}

// A connected loopback socket with a receive timeout, closed on destruction.
class Socket {
 public:
  explicit Socket(int port) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    timeval timeout{15, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  ~Socket() { close(fd_); }
  bool connected() const { return connected_; }
  bool Send(const std::string& bytes) {
    size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<size_t>(n);
    }
    return true;
  }
  // Everything until the peer closes (or the receive timeout: then nullopt).
  std::optional<std::string> ReadToEnd() {
    std::string out;
    char buf[4096];
    for (;;) {
      const ssize_t n = recv(fd_, buf, sizeof buf, 0);
      if (n == 0) return out;
      if (n < 0) return errno == ECONNRESET ? std::optional<std::string>(out) : std::nullopt;
      out.append(buf, static_cast<size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  bool connected_ = false;
};

struct HttpReply {
  int status = 0;  // 0: no response
  std::string headers;
  std::string body;
};

// Sends `request` as is and reads the reply (the server closes after one).
HttpReply Exchange(int port, const std::string& request) {
  Socket s(port);
  EXPECT_TRUE(s.connected());
  HttpReply reply;
  if (!s.Send(request)) return reply;
  std::optional<std::string> raw = s.ReadToEnd();
  if (!raw) return reply;
  const size_t end = raw->find("\r\n\r\n");
  if (raw->rfind("HTTP/1.", 0) != 0 || end == std::string::npos) return reply;
  reply.status = std::stoi(raw->substr(9, 3));
  reply.headers = raw->substr(0, end);
  reply.body = raw->substr(end + 4);
  return reply;
}

HttpReply Get(int port, const std::string& path = "/metrics") {
  return Exchange(port, "GET " + path + " HTTP/1.1\r\nHost: localhost\r\n\r\n");
}

// A parsed exposition: samples by their series ("name" or "name{labels}" as written).
struct Exposition {
  std::map<std::string, uint64_t> samples;
  std::map<std::string, double> sums;        // histograms' _sum series (seconds)
  std::map<std::string, std::string> types;  // family -> counter|gauge|histogram
};

// The family a sample belongs to: its name, or a histogram's name without _bucket, _sum, _count.
std::string FamilyOf(const Exposition& e, const std::string& name) {
  if (e.types.count(name)) return name;
  for (const char* suffix : {"_bucket", "_sum", "_count"}) {
    if (!name.ends_with(suffix)) continue;
    const std::string family = name.substr(0, name.size() - std::strlen(suffix));
    auto it = e.types.find(family);
    if (it != e.types.end() && it->second == "histogram") return family;
  }
  return "";
}

// Parses the text format strictly enough to catch what a Prometheus server would refuse: every
// sample's family has HELP and TYPE lines before it, counters end in _total, values are
// integers (a histogram's _sum a decimal), series are unique.
::testing::AssertionResult Parse(const std::string& text, Exposition* out) {
  std::set<std::string> helped;
  size_t at = 0;
  while (at < text.size()) {
    const size_t eol = text.find('\n', at);
    if (eol == std::string::npos) return ::testing::AssertionFailure() << "no final line feed";
    const std::string line = text.substr(at, eol - at);
    at = eol + 1;
    std::smatch m;
    if (std::regex_match(line, m, std::regex("# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) .+"))) {
      helped.insert(m[1]);
      continue;
    }
    if (std::regex_match(
            line, m, std::regex("# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram)"))) {
      if (!helped.count(m[1])) return ::testing::AssertionFailure() << "TYPE before HELP: " << line;
      if (!out->types.emplace(m[1], m[2]).second) {
        return ::testing::AssertionFailure() << "family twice: " << line;
      }
      if (m[2] == "counter" && !std::string(m[1]).ends_with("_total")) {
        return ::testing::AssertionFailure() << "counter without _total: " << line;
      }
      continue;
    }
    // name, optional {labels} (values quoted, with \\, \" and \n escapes), space, value.
    size_t i = 0;
    while (i < line.size() && line[i] != '{' && line[i] != ' ') ++i;
    const std::string name = line.substr(0, i);
    if (i < line.size() && line[i] == '{') {
      bool quoted = false;
      for (++i; i < line.size() && (quoted || line[i] != '}'); ++i) {
        if (quoted && line[i] == '\\') {
          ++i;
        } else if (line[i] == '"') {
          quoted = !quoted;
        }
      }
      ++i;
    }
    if (i >= line.size() || line[i] != ' ') {
      return ::testing::AssertionFailure() << "bad sample line: " << line;
    }
    const std::string series = line.substr(0, i);
    const std::string value = line.substr(i + 1);
    const std::string family = FamilyOf(*out, name);
    if (family.empty()) return ::testing::AssertionFailure() << "sample without TYPE: " << line;
    if (family != name && name.ends_with("_sum")) {
      if (!std::regex_match(value, std::regex("[0-9]+(\\.[0-9]+)?"))) {
        return ::testing::AssertionFailure() << "not a decimal: " << line;
      }
      if (!out->sums.emplace(series, std::stod(value)).second) {
        return ::testing::AssertionFailure() << "series twice: " << line;
      }
      continue;
    }
    if (!std::regex_match(value, std::regex("[0-9]+"))) {
      return ::testing::AssertionFailure() << "not an integer: " << line;
    }
    if (!out->samples.emplace(series, std::stoull(value)).second) {
      return ::testing::AssertionFailure() << "series twice: " << line;
    }
  }
  return ::testing::AssertionSuccess();
}

Exposition Scrape(int port) {
  const HttpReply reply = Get(port);
  EXPECT_EQ(reply.status, 200) << reply.headers;
  EXPECT_NE(reply.headers.find("Content-Type: text/plain; version=0.0.4"), std::string::npos)
      << reply.headers;
  Exposition e;
  EXPECT_TRUE(Parse(reply.body, &e)) << reply.body;
  return e;
}

// Value of one series; fails the test if it is missing.
uint64_t Value(const Exposition& e, const std::string& series) {
  auto it = e.samples.find(series);
  EXPECT_NE(it, e.samples.end()) << series;
  return it == e.samples.end() ? ~uint64_t{0} : it->second;
}

void Ingest(Client& client, const std::vector<OwnedScan>& scans) {
  std::vector<ScanData> data;
  for (const OwnedScan& s : scans) data.push_back(s.Data());
  RpcResult<std::vector<ScanAck>> acks = client.IngestAll(data);
  ASSERT_TRUE(acks.ok()) << acks.status().ToString();
}

// A robot id that needs the escapes of the format a robot id can reach: a quote and a backslash.
// (A newline, the third, is refused in robot ids since issue 12: control characters could forge
// log lines.)
const std::string kOddRobot = "be\"ta\\2";
const std::string kOddRobotLabel = "{robot=\"be\\\"ta\\\\2\"}";

TEST(MetricsTest, ScrapeEqualsInfo) {
  TempDir dir("bgkmap_metrics");
  ServerConfig config = MetricsConfig(dir.str());
  // No checkpoint while the test runs, so the store counters have values the test knows.
  config.storage.checkpoint_interval_s = 3600;
  ServerFixture fixture(config);
  const int port = fixture.server().http_port();
  ASSERT_GT(port, 0);
  ASSERT_NE(port, fixture.server().port());
  const std::vector<OwnedScan> alpha = SubScans("alpha", 4, 8);
  std::vector<OwnedScan> odd = SubScans(kOddRobot, 4, 3);
  Ingest(fixture.client(), alpha);
  Ingest(fixture.client(), odd);
  Ingest(fixture.client(), {odd.front()});  // a duplicate

  // One open watch; the ingest streams have ended. Both gauges settle asynchronously (a stream is
  // unregistered when the server finishes it), so scrape until they show, within a deadline.
  auto watch = fixture.client().Watch({{-1, -1, 1, 1}, {}, false}, [](const TileUpdate&) {});
  Exposition e;
  for (const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);;) {
    e = Scrape(port);
    const auto w = e.samples.find("bgkmap_watchers"), i = e.samples.find("bgkmap_ingest_streams");
    if ((w != e.samples.end() && w->second == 1 && i != e.samples.end() && i->second == 0) ||
        std::chrono::steady_clock::now() > deadline) {
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  RpcResult<MapInfo> info = fixture.client().Info();
  ASSERT_TRUE(info.ok());
  ASSERT_TRUE(info->storage.has_value());
  EXPECT_EQ(Value(e, "bgkmap_map_version"), info->map_version);
  EXPECT_EQ(Value(e, "bgkmap_map_version"), alpha.size() + odd.size());
  EXPECT_EQ(Value(e, "bgkmap_scans_applied_total"), info->scans_applied);
  EXPECT_EQ(Value(e, "bgkmap_map_tiles"), info->tile_count);
  EXPECT_EQ(Value(e, "bgkmap_map_known_cells"), info->known_cells);
  EXPECT_GT(info->known_cells, 0u);
  EXPECT_EQ(Value(e, "bgkmap_robots"), 2u);
  ASSERT_EQ(info->robots.size(), 2u);
  for (const RobotInfo& r : info->robots) {
    const std::string label = r.robot_id == "alpha" ? "{robot=\"alpha\"}" : kOddRobotLabel;
    EXPECT_EQ(Value(e, "bgkmap_robot_scans_applied_total" + label), r.scans_applied);
    EXPECT_EQ(Value(e, "bgkmap_robot_scans_duplicate_total" + label), r.scans_duplicate);
    EXPECT_EQ(Value(e, "bgkmap_robot_scans_rejected_total" + label), r.scans_rejected);
    EXPECT_EQ(Value(e, "bgkmap_robot_points_kept_total" + label), r.points_kept);
    EXPECT_EQ(Value(e, "bgkmap_robot_last_sequence" + label), r.last_sequence);
  }
  EXPECT_EQ(Value(e, "bgkmap_robot_scans_applied_total{robot=\"alpha\"}"), alpha.size());
  EXPECT_EQ(Value(e, "bgkmap_robot_scans_duplicate_total" + kOddRobotLabel), 1u);
  EXPECT_EQ(e.types.at("bgkmap_map_version"), "gauge");
  EXPECT_EQ(e.types.at("bgkmap_scans_applied_total"), "counter");

  // The store's side.
  EXPECT_EQ(Value(e, "bgkmap_store_checkpoint_version"), info->storage->checkpoint_version);
  EXPECT_EQ(Value(e, "bgkmap_store_corrupt_tiles"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_corrupt_tiles_found_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_corrupt_log_records_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_write_failed"), 0u);
  // The free-space reserve (default 64 MB): not reached, and what Info says.
  EXPECT_EQ(Value(e, "bgkmap_store_writes_paused_for_space"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_read_only"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_free_space_reserve_bytes"), uint64_t{64} << 20);
  EXPECT_EQ(Value(e, "bgkmap_store_free_space_reserve_bytes"),
            info->storage->free_space_reserve_bytes);
  EXPECT_GT(Value(e, "bgkmap_store_free_bytes"), uint64_t{64} << 20);
  EXPECT_EQ(Value(e, "bgkmap_store_writes_refused_for_space_total"), 0u);
  EXPECT_FALSE(info->storage->writes_paused_for_space);
  EXPECT_EQ(info->storage->writes_paused_reason, "");
  EXPECT_EQ(Value(e, "bgkmap_store_write_errors_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_log_records_appended_total"), alpha.size() + odd.size());
  EXPECT_GT(Value(e, "bgkmap_store_log_appended_bytes_total"), 0u);
  EXPECT_GT(Value(e, "bgkmap_store_disk_bytes"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_map_resident_tiles"), info->storage->resident_tiles);
  EXPECT_EQ(Value(e, "bgkmap_map_resident_bytes"), info->storage->resident_bytes);
  EXPECT_EQ(Value(e, "bgkmap_map_memory_limit_bytes"), 0u);
  // Values the test knows, not only presence. A fresh store, no checkpoint yet (interval 1 h), no
  // memory bound: nothing was written to or read back from the tile store, nothing deleted or
  // evicted, and every tile of the map changed since the (absent) last checkpoint.
  // Mutations checked (server/src/metrics.cc), each failing a line below while the old presence
  // check passed: bgkmap_store_dirty_tiles written from s.corrupt_tiles; bgkmap_watchers from
  // m.ingest_streams; bgkmap_store_tile_sst_bytes from s.usage.total_bytes. (Swapping two of the
  // counters that are 0 here, e.g. tiles_loaded and tiles_written, is not caught.)
  EXPECT_EQ(info->storage->checkpoint_version, 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_checkpoints_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_tiles_written_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_tiles_deleted_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_tiles_loaded_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_store_dirty_tiles"), info->tile_count);
  EXPECT_EQ(Value(e, "bgkmap_map_tiles_loaded_total"), info->storage->tiles_loaded);
  EXPECT_EQ(Value(e, "bgkmap_map_tiles_loaded_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_map_tiles_evicted_total"), info->storage->tiles_evicted);
  EXPECT_EQ(Value(e, "bgkmap_map_tiles_evicted_total"), 0u);
  EXPECT_EQ(Value(e, "bgkmap_ingest_streams"), 0u);  // every IngestAll above has finished
  EXPECT_EQ(Value(e, "bgkmap_watchers"), 1u);        // the one watch opened above
  // SST sizes: the store's SST files on disk bound them (RocksDB may also keep the default
  // column family's), and the store's whole directory bounds those.
  uint64_t sst_on_disk = 0;
  for (const auto& f : std::filesystem::recursive_directory_iterator(dir.str())) {
    if (f.is_regular_file() && f.path().extension() == ".sst") sst_on_disk += f.file_size();
  }
  EXPECT_LE(Value(e, "bgkmap_store_tile_sst_bytes") + Value(e, "bgkmap_store_log_sst_bytes"),
            sst_on_disk);
  EXPECT_LE(sst_on_disk, Value(e, "bgkmap_store_disk_bytes"));
  EXPECT_GT(Value(e, "process_resident_memory_bytes"), 10u << 20);
  EXPECT_EQ(e.samples.count("bgkmap_build_info{version=\"" + info->server_version + "\"}"), 1u);

  // A later change shows at the next scrape.
  RpcResult<ClearResult> cleared = fixture.client().ClearRegion({-1, -1, 1, 1});
  ASSERT_TRUE(cleared.ok());
  EXPECT_EQ(Value(Scrape(port), "bgkmap_map_version"), info->map_version + 1);
}

// The phases' histograms count exactly the requests answered (a refused query is not timed),
// their buckets are cumulative up to +Inf = count, and their sums are real durations.
TEST(MetricsTest, RequestPhasesAreTimed) {
  ServerFixture fixture(MetricsConfig());
  const int port = fixture.server().http_port();
  const auto count = [](const Exposition& e, const std::string& phase) {
    return Value(e, "bgkmap_request_phase_seconds_count{phase=\"" + phase + "\"}");
  };
  const Exposition before = Scrape(port);
  EXPECT_EQ(before.types.at("bgkmap_request_phase_seconds"), "histogram");
  for (const char* phase : {"region_read", "region_stream", "points", "check_path", "scan"}) {
    EXPECT_EQ(count(before, phase), 0u) << phase;
  }

  const std::vector<OwnedScan> scans = SubScans("alpha", 3, 8);
  Ingest(fixture.client(), scans);
  ASSERT_TRUE(fixture.client().QueryRegion({{-5, -5, 5, 5}, {}, 1}).ok());
  const std::vector<std::array<double, 2>> two = {{0.0, 0.0}, {1.0, 1.0}}, one = {{2.0, 0.0}};
  RpcResult<PointValues> points = fixture.client().QueryPoints(two);
  ASSERT_TRUE(points.ok()) << points.status().ToString();
  ASSERT_TRUE(fixture.client().QueryPoints(one).ok());
  PathQuery path;
  path.poses = {{0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};
  path.radius = 0.3;
  path.max_unknown_fraction = 1.0;
  ASSERT_TRUE(fixture.client().CheckPath(path).ok());
  // Refused before any work: not timed.
  EXPECT_FALSE(fixture.client().QueryRegion({{5, 5, -5, -5}, {}, 1}).ok());

  // Every phase is recorded before its answer goes out, so the scrape sees them all.
  const Exposition e = Scrape(port);
  EXPECT_EQ(count(e, "scan"), scans.size());
  EXPECT_EQ(count(e, "region_read"), 1u);
  EXPECT_EQ(count(e, "region_stream"), 1u);
  EXPECT_EQ(count(e, "points"), 2u);
  EXPECT_EQ(count(e, "check_path"), 1u);
  for (const char* phase : {"region_read", "region_stream", "points", "check_path", "scan"}) {
    const std::string label = std::string("phase=\"") + phase + "\"";
    uint64_t previous = 0;
    for (const char* le : {"0.0005", "0.001", "0.002", "0.005", "0.01", "0.02", "0.05", "0.1",
                           "0.2", "0.5", "1", "2", "5", "10", "+Inf"}) {
      const uint64_t v =
          Value(e, "bgkmap_request_phase_seconds_bucket{" + label + ",le=\"" + le + "\"}");
      EXPECT_GE(v, previous) << phase << " le=" << le;
      previous = v;
    }
    EXPECT_EQ(previous, count(e, phase)) << phase;
    const double sum = e.sums.at("bgkmap_request_phase_seconds_sum{" + label + "}");
    EXPECT_GT(sum, 0.0) << phase;
    EXPECT_LT(sum, 60.0 * static_cast<double>(count(e, phase))) << phase;
  }
}

TEST(MetricsTest, InMemoryMapHasNoStoreMetrics) {
  ServerFixture fixture(MetricsConfig());
  Ingest(fixture.client(), SubScans("alpha", 4, 2));
  const Exposition e = Scrape(fixture.server().http_port());
  EXPECT_EQ(Value(e, "bgkmap_map_version"), 2u);
  ASSERT_GT(e.samples.size(), 5u);  // the loop below checks real series, not an empty scrape
  for (const auto& [series, value] : e.samples) {
    EXPECT_FALSE(series.starts_with("bgkmap_store_")) << series;
  }
}

TEST(MetricsTest, OffByDefault) {
  ServerFixture fixture;
  EXPECT_EQ(fixture.server().http_port(), 0);
}

TEST(MetricsTest, CorruptStoredTileIsCounted) {
  TempDir dir("bgkmap_metrics");
  {
    ServerFixture fixture(MetricsConfig(dir.str()));
    Ingest(fixture.client(), SubScans("alpha", 4, 3));
  }  // the last checkpoint writes every tile
  {
    ServerFixture fixture(MetricsConfig(dir.str()));
    const Exposition e = Scrape(fixture.server().http_port());
    EXPECT_EQ(Value(e, "bgkmap_store_corrupt_tiles"), 0u);
    EXPECT_EQ(Value(e, "bgkmap_store_corrupt_tiles_found_total"), 0u);
  }
  CorruptStoredTile(dir.str());
  ServerFixture fixture(MetricsConfig(dir.str()));
  // storage.verify_on_start reads every stored tile in the background.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  Exposition e;
  do {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    e = Scrape(fixture.server().http_port());
  } while (Value(e, "bgkmap_store_corrupt_tiles") == 0 &&
           std::chrono::steady_clock::now() < deadline);
  EXPECT_EQ(Value(e, "bgkmap_store_corrupt_tiles"), 1u);
  EXPECT_EQ(Value(e, "bgkmap_store_corrupt_tiles_found_total"), 1u);
  RpcResult<MapInfo> info = fixture.client().Info();
  ASSERT_TRUE(info.ok() && info->storage.has_value());
  EXPECT_EQ(info->storage->corrupt_tiles, 1u);
}

TEST(MetricsTest, OnlyGetMetricsIsServed) {
  ServerFixture fixture(MetricsConfig());
  const int port = fixture.server().http_port();
  // "/" is the web map's page (web_map_test.cc); a web route keeps the connection unless told.
  EXPECT_EQ(Exchange(port, "GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").status, 200);
  EXPECT_EQ(Get(port, "/nothing").status, 404);
  EXPECT_EQ(Get(port, "/metricsx").status, 404);
  EXPECT_EQ(Get(port, "/metrics/").status, 404);
  EXPECT_EQ(Get(port, "/metrics?name[]=x").status, 200);
  const HttpReply post =
      Exchange(port, "POST /metrics HTTP/1.1\r\nHost: x\r\nContent-Length: 3\r\n\r\nabc");
  EXPECT_EQ(post.status, 405);
  EXPECT_NE(post.headers.find("Allow: GET"), std::string::npos) << post.headers;
  EXPECT_EQ(Exchange(port, "HEAD /metrics HTTP/1.1\r\nHost: x\r\n\r\n").status, 405);
  EXPECT_EQ(Exchange(port, "GET /metrics HTTP/1.0\r\n\r\n").status, 200);
}

TEST(MetricsTest, BadClientsNeitherCrashNorBlockIt) {
  ServerFixture fixture(MetricsConfig());
  const int port = fixture.server().http_port();
  // An idle connection and a half-sent request stay open while others are answered.
  Socket idle(port);
  Socket half(port);
  ASSERT_TRUE(idle.connected() && half.connected());
  ASSERT_TRUE(half.Send("GET /metr"));
  EXPECT_EQ(Exchange(port, "NOT HTTP AT ALL\r\n\r\n").status, 400);
  EXPECT_EQ(Exchange(port, std::string("GET /metrics HTTP/1.1\r\n\0\x01\x02\r\n\r\n", 30)).status,
            400);
  EXPECT_EQ(
      Exchange(port, "GET /metrics HTTP/1.1\r\nX-Big: " + std::string(20000, 'a') + "\r\n\r\n")
          .status,
      431);
  EXPECT_EQ(Exchange(port, "GET /metrics HTTP/1.1\r\nContent-Length: 100000\r\n\r\n").status, 413);
  {
    Socket gone(port);  // connects and disappears mid-request
    EXPECT_TRUE(gone.Send("GET /metrics HTTP/1.1\r\nHo"));
  }
  // More connections than the endpoint keeps open: the extra ones are closed, nothing waits.
  std::vector<std::unique_ptr<Socket>> crowd;
  for (int i = 0; i < 12; ++i) crowd.push_back(std::make_unique<Socket>(port));
  crowd.clear();
  // The endpoint notices the closed ones in its own time: poll until a scrape is answered again
  // (a generous deadline, no fixed sleep).
  const auto answered_by = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (Get(port).status != 200 && std::chrono::steady_clock::now() < answered_by) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  Scrape(port);
  EXPECT_TRUE(fixture.client().Info().ok());
  // The slow ones are dropped at the read timeout (5 s).
  const auto t0 = std::chrono::steady_clock::now();
  std::optional<std::string> rest = idle.ReadToEnd();
  ASSERT_TRUE(rest.has_value()) << "the idle connection was not closed";
  EXPECT_EQ(*rest, "");
  // Closed by the endpoint's 5 s timeout, not by this socket's 15 s one (ReadToEnd would return
  // nullopt): a bound between the two, generous for busy machines.
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(14));
  rest = half.ReadToEnd();
  ASSERT_TRUE(rest.has_value());
  EXPECT_EQ(*rest, "");
  Scrape(port);
}

TEST(MetricsTest, ShutdownWithOpenConnectionsIsClean) {
  ServerFixture fixture(MetricsConfig());
  const int port = fixture.server().http_port();
  Socket idle(port);
  ASSERT_TRUE(idle.connected());
  Scrape(port);
  fixture.server().Shutdown();
  EXPECT_TRUE(idle.ReadToEnd().has_value());  // closed by the shutdown
  EXPECT_FALSE(Socket(port).connected());
}

TEST(MetricsConfigTest, AddressIsCheckedAndNamesTheKey) {
  for (const char* good : {"127.0.0.1:0", "0.0.0.0:9100", "localhost:9100", "[::1]:9100"}) {
    ServerConfig c;
    EXPECT_TRUE(ApplyConfigOverride(c, std::string("server.metrics_address=\"") + good + "\"").ok())
        << good;
    EXPECT_EQ(c.metrics_address, good);
  }
  for (const char* bad : {"9100", ":9100", "127.0.0.1:", "127.0.0.1:99999", "127.0.0.1:91x",
                          "::1:9100", "host name:1"}) {
    ServerConfig c;
    const Status s = ApplyConfigOverride(c, std::string("server.metrics_address=\"") + bad + "\"");
    ASSERT_FALSE(s.ok()) << bad;
    EXPECT_EQ(s.message().rfind("server.metrics_address: ", 0), 0u) << s.message();
    EXPECT_NE(s.message().find(bad), std::string::npos) << s.message();
    EXPECT_EQ(c.metrics_address, "");
  }
  ServerConfig printed;
  printed.metrics_address = "127.0.0.1:9100";
  Result<ServerConfig> back = ServerConfigFromYaml(YAML::Load(ServerConfigToYaml(printed)));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->metrics_address, "127.0.0.1:9100");
}

TEST(MetricsConfigTest, AddressInUseFailsTheStart) {
  ServerFixture first(MetricsConfig());
  ServerConfig c = MetricsConfig();
  c.metrics_address = "127.0.0.1:" + std::to_string(first.server().http_port());
  Result<std::unique_ptr<MapServer>> second = MapServer::Start(c);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().message().rfind("server.metrics_address: cannot listen on", 0), 0u)
      << second.status().message();
}

TEST(MetricsProcessTest, FlagServesAndBadAddressExitsWithOneLine) {
  {
    BgkmapdProcess server({"--metrics", "127.0.0.1:0"});
    ASSERT_TRUE(server.started());
    const std::string line = server.WaitForLine("event=metrics_listening", 10);
    std::smatch m;
    ASSERT_TRUE(std::regex_search(line, m, std::regex("address=127.0.0.1:0 port=([0-9]+)")))
        << line;
    EXPECT_EQ(Value(Scrape(std::stoi(m[1])), "bgkmap_map_version"), 0u);
    server.Signal(SIGTERM);
    EXPECT_EQ(server.Wait(), 0);
  }
  {
    BgkmapdProcess server({"--metrics", "nonsense"});
    EXPECT_FALSE(server.started());
    EXPECT_NE(server.Wait(), 0);
    const std::vector<std::string> log = server.Log();
    ASSERT_EQ(log.size(), 1u);
    EXPECT_NE(log[0].find("server.metrics_address"), std::string::npos) << log[0];
  }
  {
    // A port in use: bound and listened on here.
    const int taken = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t size = sizeof addr;
    ASSERT_EQ(bind(taken, reinterpret_cast<sockaddr*>(&addr), size), 0);
    ASSERT_EQ(listen(taken, 1), 0);
    ASSERT_EQ(getsockname(taken, reinterpret_cast<sockaddr*>(&addr), &size), 0);
    BgkmapdProcess server({"--metrics", "127.0.0.1:" + std::to_string(ntohs(addr.sin_port))});
    close(taken);
    EXPECT_FALSE(server.started());
    EXPECT_EQ(server.Wait(), 1);
    EXPECT_NE(server.FindLine("event=start_failed reason=\"server.metrics_address: cannot listen"),
              "");
  }
}

}  // namespace
}  // namespace bgkmap::testing
