// Who may hold the long-lived streams that tell about changes, gRPC's Watch and the web map's
// GET /events, and how many (issue 25, finding 6 and 4), against the real bgkmapd binary on
// loopback with a tokens file: a robot token may not read /events (as it may not Watch), a
// revoked token's /events streams end within a second, and one token holds at most its share of
// the Watch and /events slots.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <iostream>
#include <memory>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "auth/token_table.h"
#include "bgkmapd_process.h"
#include "loopback_http.h"
#include "test_support.h"

namespace bgkmap::testing {
namespace {

using Clock = std::chrono::steady_clock;

struct Token {
  std::string name, secret, role;
  std::string extra;  // more YAML of the entry ("robots: [r1]")
};

void WriteTokens(const std::string& path, const std::vector<Token>& tokens) {
  std::string yaml = "tokens:\n";
  for (const Token& t : tokens) {
    yaml += "  - {name: " + t.name + ", sha256: " + Sha256Hex(t.secret) + ", role: " + t.role +
            (t.extra.empty() ? "" : ", " + t.extra) + "}\n";
  }
  std::ofstream(path) << yaml;
}

std::string Bearer(const std::string& secret) { return "Authorization: Bearer " + secret + "\r\n"; }

OwnedScan ScanAs(const std::string& robot, uint64_t sequence) {
  OwnedScan s = StreetScans()[0];
  s.robot_id = robot;
  s.sequence = sequence;
  return s;
}

// bgkmapd with a tokens file (robot "lidar", planners "planner" and "viewer", admin "ops") and
// the web map on a free port; `args` adds settings.
class StreamAccess : public ::testing::Test {
 protected:
  void Start(const std::vector<Token>& tokens, std::vector<std::string> args = {}) {
    tokens_ = dir_.Sub("tokens.yaml");
    WriteTokens(tokens_, tokens);
    args.insert(args.end(),
                {"--http", "127.0.0.1:0", "--set", "server.auth.tokens_file=" + tokens_});
    server_ = std::make_unique<BgkmapdProcess>(args);
    ASSERT_TRUE(server_->started());
    const std::string line = server_->WaitForLine("event=web_map_listening", 10);
    std::smatch m;
    ASSERT_TRUE(std::regex_search(line, m, std::regex(":([0-9]+)/"))) << line;
    http_port_ = std::stoi(m[1]);
  }
  static std::vector<Token> Usual() {
    return {{"lidar", "robot-secret", "robot", "robots: [r1]"},
            {"planner", "planner-secret", "planner", ""},
            {"viewer", "viewer-secret", "planner", ""},
            {"ops", "admin-secret", "admin", ""}};
  }
  Client Connect(const std::string& secret) {
    ClientOptions o;
    o.timeout = std::chrono::seconds(10);
    o.token = secret;
    return Client(server_->target(), o);
  }
  // Opens /events as `secret` and reads its hello event; null if it did not come.
  std::unique_ptr<Socket> OpenEvents(const std::string& secret, std::string* buffer) {
    auto s = std::make_unique<Socket>(http_port_, 5);
    if (!s->Send("GET /events HTTP/1.1\r\nHost: x\r\n" + Bearer(secret) + "\r\n")) return nullptr;
    if (!ReadEvent(*s, buffer, "hello", 5).has_value()) return nullptr;
    return s;
  }

  TempDir dir_{"bgkmap_stream_access"};
  std::string tokens_;
  std::unique_ptr<BgkmapdProcess> server_;
  int http_port_ = 0;
};

// Finding 6: a robot token read /events, the HTTP twin of the Watch it is denied over gRPC. Now
// 403 with one line naming the token, its role and the right, as gRPC's PERMISSION_DENIED does;
// the robot still reads the map's other routes (it may query), and a planner's stream opens.
// Mutation caught: WebRoutes::Handle opening /events without checking Right::kWatch (200).
TEST_F(StreamAccess, ARobotTokenMayNotReadEvents) {
  Start(Usual());
  const Reply robot = Get(http_port_, "/events", "GET", Bearer("robot-secret"));
  EXPECT_EQ(robot.status, 403) << robot.headers;
  EXPECT_NE(robot.body.find("token 'lidar' has role robot, which may not watch"), std::string::npos)
      << robot.body;
  EXPECT_EQ(robot.body.find('\n'), robot.body.size() - 1) << "one line: " << robot.body;
  EXPECT_EQ(Get(http_port_, "/map.json", "GET", Bearer("robot-secret")).status, 200);
  // The login cookie is judged the same way as the header.
  const Reply cookie = Get(http_port_, "/events", "GET", "Cookie: bgkmap_token=robot-secret\r\n");
  EXPECT_EQ(cookie.status, 403) << cookie.headers;
  std::string buffer;
  EXPECT_NE(OpenEvents("planner-secret", &buffer), nullptr);
  // The gRPC twin, for comparison: the same token's Watch is PERMISSION_DENIED.
  Client robot_client = Connect("robot-secret");
  std::unique_ptr<WatchSubscription> watch =
      robot_client.Watch({{-10, -10, 10, 10}, {}, false}, [](const TileUpdate&) {});
  EXPECT_EQ(watch->Wait().code(), RpcCode::kPermissionDenied);
}

// Finding 4, its HTTP part: after SIGHUP removed a token, its open /events streams kept going.
// They now end within the streams' check period (a second); a token that stays keeps its stream.
// Mutation caught: EventStreams' pinger not closing the sessions of revoked principals (the
// planner's stream stays open until the 15 s ping and beyond).
TEST_F(StreamAccess, RevokingATokenEndsItsEventStreamsWithinASecond) {
  Start(Usual());
  std::string planner_buffer, ops_buffer;
  std::unique_ptr<Socket> planner = OpenEvents("planner-secret", &planner_buffer);
  ASSERT_NE(planner, nullptr) << planner_buffer;
  std::unique_ptr<Socket> ops = OpenEvents("admin-secret", &ops_buffer);
  ASSERT_NE(ops, nullptr) << ops_buffer;

  WriteTokens(tokens_, {{"ops", "admin-secret", "admin", ""}});  // "planner" goes
  const auto signalled = Clock::now();
  server_->Signal(SIGHUP);
  // The stream ends: the socket reads to its close (pings are comments, every 15 s). A read
  // that times out (5 s) also ends the loop: the time bound below tells the two apart.
  bool closed = false;
  while (!closed && Clock::now() - signalled < std::chrono::seconds(5)) {
    closed = !planner->ReadSome(&planner_buffer);
  }
  const auto ended = Clock::now() - signalled;
  ASSERT_FALSE(server_->WaitForLine("event=tokens_reloaded", 10).empty());
  EXPECT_TRUE(closed);
  std::cout << "the revoked token's /events stream ended "
            << std::chrono::duration_cast<std::chrono::milliseconds>(ended).count()
            << " ms after SIGHUP\n";
  EXPECT_LT(ended, std::chrono::seconds(3));  // one period plus the reload, on a loaded machine
  // Its reconnection is refused: the token is gone.
  EXPECT_EQ(Get(http_port_, "/events", "GET", Bearer("planner-secret")).status, 401);
  // The admin's stream, whose token stays, still tells about a new scan.
  ASSERT_TRUE(Connect("admin-secret").Insert(ScanAs("r9", 1).Data()).ok());
  EXPECT_TRUE(ReadEvent(*ops, &ops_buffer, "tiles", 5).has_value()) << ops_buffer;
}

// Finding 6: the 16 /events slots were global, so one token could take them all. A token holds
// at most server.auth.max_event_streams_per_token (default a quarter of the 16): the next is 429
// naming the setting, another token's stream opens, and a closed stream gives its slot back.
// Mutation caught: EventStreams::Open without the token's slot (the third stream opens: 200).
TEST_F(StreamAccess, OneTokenHoldsAtMostItsShareOfEventStreams) {
  Start(Usual(), {"--set", "server.auth.max_event_streams_per_token=2"});
  std::string b1, b2, b3;
  std::unique_ptr<Socket> first = OpenEvents("planner-secret", &b1);
  ASSERT_NE(first, nullptr) << b1;
  std::unique_ptr<Socket> second = OpenEvents("planner-secret", &b2);
  ASSERT_NE(second, nullptr) << b2;
  const Reply third = Get(http_port_, "/events", "GET", Bearer("planner-secret"));
  EXPECT_EQ(third.status, 429) << third.headers;
  EXPECT_NE(third.body.find("token 'planner' already holds its limit of 2 open event streams "
                            "(server.auth.max_event_streams_per_token"),
            std::string::npos)
      << third.body;
  EXPECT_NE(third.headers.find("Retry-After: "), std::string::npos) << third.headers;
  EXPECT_NE(OpenEvents("viewer-secret", &b3), nullptr) << "another token was held back";

  second.reset();  // its slot comes back once the server sees the close
  int status = 0;
  const auto deadline = Clock::now() + std::chrono::seconds(5);
  std::unique_ptr<Socket> again;
  while (Clock::now() < deadline && again == nullptr) {
    std::string b;
    again = OpenEvents("planner-secret", &b);
    if (again == nullptr) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_NE(again, nullptr) << status;
}

// Finding 6: the 64 Watch slots (server.max_watchers) were global. A token holds at most its
// entry's max_watchers (or server.auth.max_watchers_per_token, default a quarter): the next Watch
// is RESOURCE_EXHAUSTED naming the setting; another token's opens; a cancelled watch frees one.
// Mutation caught: WatchStream admitted without the token's Permit (the second watch stays open).
TEST_F(StreamAccess, OneTokenHoldsAtMostItsShareOfWatches) {
  std::vector<Token> tokens = Usual();
  tokens[1].extra = "max_watchers: 1";
  Start(tokens);
  Client planner = Connect("planner-secret");
  Client viewer = Connect("viewer-secret");
  Client ops = Connect("admin-secret");
  std::atomic<int> first_updates{0}, viewer_updates{0};
  std::unique_ptr<WatchSubscription> first =
      planner.Watch({{-10, -10, 10, 10}, {}, false}, [&](const TileUpdate&) { ++first_updates; });
  std::unique_ptr<WatchSubscription> other =
      viewer.Watch({{-10, -10, 10, 10}, {}, false}, [&](const TileUpdate&) { ++viewer_updates; });
  // Both are open on the server once each has seen a change.
  ASSERT_TRUE(ops.Insert(ScanAs("r9", 1).Data()).ok());
  for (int i = 0; i < 400 && (first_updates.load() == 0 || viewer_updates.load() == 0); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ASSERT_GT(first_updates.load(), 0);
  ASSERT_GT(viewer_updates.load(), 0) << "another token's watch was held back";

  std::unique_ptr<WatchSubscription> second =
      planner.Watch({{-10, -10, 10, 10}, {}, false}, [](const TileUpdate&) {});
  // Refused at once; a watch still open after 5 s was admitted (cancelled here, not waited on).
  RpcStatus refused;
  std::atomic<bool> ended{false};
  std::thread waiter([&] {
    refused = second->Wait();
    ended = true;
  });
  for (int i = 0; i < 200 && !ended.load(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  const bool refused_at_once = ended.load();
  if (!refused_at_once) second->Cancel();
  waiter.join();
  ASSERT_TRUE(refused_at_once) << "the token's second watch was admitted";
  EXPECT_EQ(refused.code(), RpcCode::kResourceExhausted) << refused.ToString();
  EXPECT_NE(refused.message().find("token 'planner' already holds its limit of 1 open watches "
                                   "(server.auth.max_watchers_per_token"),
            std::string::npos)
      << refused.message();

  first->Cancel();
  (void)first->Wait();
  // The slot comes back once the server has finished the cancelled call.
  bool reopened = false;
  for (int i = 0; i < 100 && !reopened; ++i) {
    std::atomic<int> updates{0};
    std::unique_ptr<WatchSubscription> again =
        planner.Watch({{-10, -10, 10, 10}, {}, false}, [&](const TileUpdate&) { ++updates; });
    ASSERT_TRUE(ops.Insert(ScanAs("r9", 2 + i).Data()).ok());
    for (int j = 0; j < 200 && updates.load() == 0; ++j) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    reopened = updates.load() > 0;
    again->Cancel();
  }
  EXPECT_TRUE(reopened);
}

TEST(StreamAccessConfig, StreamSlotsPerTokenDefaultToAQuarterOfTheGlobalOnes) {
  ServerConfig c;
  c.limits.max_watchers = 64;
  EXPECT_EQ(WatchersPerToken(c), 16u);
  EXPECT_EQ(EventStreamsPerToken(c), 4u);  // of the 16 /events slots
  c.limits.max_watchers = 2;
  EXPECT_EQ(WatchersPerToken(c), 1u);
  c.auth.max_watchers_per_token = 5;
  c.auth.max_event_streams_per_token = 7;
  EXPECT_EQ(WatchersPerToken(c), 5u);
  EXPECT_EQ(EventStreamsPerToken(c), 7u);
}

}  // namespace
}  // namespace bgkmap::testing
