// TokenTable without a server: the tokens file as read (digests, roles, robots, per-token
// limits), what each malformed entry is refused with, Authenticate's answers, and reloads that
// keep the old tokens on a bad file and a token's usage counters across a good one.
#include "auth/token_table.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace bgkmap {
namespace {

class TokenTableTest : public ::testing::Test {
 protected:
  TokenTableTest()
      : path_((std::filesystem::temp_directory_path() /
               ("bgkmap_tokens_" + std::to_string(getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".yaml"))
                  .string()) {}
  ~TokenTableTest() override { std::filesystem::remove(path_); }

  void Write(const std::string& text) { std::ofstream(path_) << text; }
  // A tokens file entry for `token` (its digest) with `rest` (more YAML flow keys).
  static std::string Entry(const std::string& name, const std::string& token,
                           const std::string& role, const std::string& rest = "") {
    return "  - {name: " + name + ", sha256: " + Sha256Hex(token) + ", role: " + role +
           (rest.empty() ? "" : ", " + rest) + "}\n";
  }
  Result<std::unique_ptr<TokenTable>> Load() { return TokenTable::Load(path_, {2, 3, 4, 5}); }
  // The message of a file that does not load.
  std::string Refusal(const std::string& text) {
    Write(text);
    Result<std::unique_ptr<TokenTable>> t = Load();
    EXPECT_FALSE(t.ok()) << text;
    return t.ok() ? "" : t.status().message();
  }

  const std::string path_;
};

TEST_F(TokenTableTest, Sha256HexIsTheStandardDigest) {
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST_F(TokenTableTest, TokensAreFoundByTheirDigestWithRoleRobotsAndLimits) {
  Write("tokens:\n" + Entry("r1", "robot-secret", "robot", "robots: [a, b], max_queries: 7") +
        Entry("plan", "planner-secret", "planner", "max_watchers: 8, max_event_streams: 9") +
        Entry("ops", "admin-secret", "admin"));
  Result<std::unique_ptr<TokenTable>> table = Load();
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  EXPECT_EQ((*table)->size(), 3u);
  std::string why;
  PrincipalRef robot = (*table)->Authenticate("Bearer robot-secret", &why);
  ASSERT_NE(robot, nullptr) << why;
  EXPECT_EQ(robot->name, "r1");
  EXPECT_EQ(robot->role, Role::kRobot);
  EXPECT_EQ(robot->robots, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(robot->max_queries, 7u);         // its own
  EXPECT_EQ(robot->max_ingest_streams, 3u);  // the default
  EXPECT_TRUE(robot->MayIngestAs("a"));
  EXPECT_FALSE(robot->MayIngestAs("c"));
  // The scheme is case-insensitive, the token is not.
  PrincipalRef planner = (*table)->Authenticate("bearer planner-secret", &why);
  ASSERT_NE(planner, nullptr) << why;
  EXPECT_EQ(planner->role, Role::kPlanner);
  EXPECT_EQ(planner->max_queries, 2u);
  EXPECT_EQ(planner->max_watchers, 8u);       // its own
  EXPECT_EQ(planner->max_event_streams, 9u);  // its own
  EXPECT_EQ(robot->max_watchers, 4u);         // the defaults
  EXPECT_EQ(robot->max_event_streams, 5u);
  EXPECT_FALSE(planner->MayIngestAs("a"));
  EXPECT_EQ((*table)->Authenticate("Bearer ADMIN-SECRET", &why), nullptr);
  PrincipalRef admin = (*table)->Authenticate("Bearer admin-secret", &why);
  ASSERT_NE(admin, nullptr) << why;
  EXPECT_TRUE(admin->Has(Right::kAdmin));
  EXPECT_FALSE(planner->Has(Right::kAdmin));
}

TEST_F(TokenTableTest, AuthenticateSaysWhyItRefuses) {
  Write("tokens:\n" + Entry("ops", "admin-secret", "admin"));
  Result<std::unique_ptr<TokenTable>> table = Load();
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  std::string why;
  EXPECT_EQ((*table)->Authenticate("", &why), nullptr);
  EXPECT_EQ(why, "no token: send the metadata 'authorization: Bearer <token>'");
  EXPECT_EQ((*table)->Authenticate("Basic admin-secret", &why), nullptr);
  EXPECT_EQ(why, "the 'authorization' metadata is not 'Bearer <token>'");
  EXPECT_EQ((*table)->Authenticate("Bearer ", &why), nullptr);
  EXPECT_EQ(why, "the 'authorization' metadata is not 'Bearer <token>'");
  EXPECT_EQ((*table)->Authenticate("Bearer guess", &why), nullptr);
  EXPECT_EQ(why, "unknown token");
}

TEST_F(TokenTableTest, EachMalformedEntryIsRefusedNamingTheFileAndTheEntry) {
  const std::string at = path_ + ": tokens[1]";
  const std::string good = Entry("ops", "admin-secret", "admin");
  struct Case {
    std::string entry;
    std::string message;
  };
  const Case cases[] = {
      {Entry("x", "t", "admin", "colour: red"), at + ".colour: unknown key"},
      {Entry("bad name", "t", "admin"), at + ".name: 'bad name' must be 1..128 of [A-Za-z0-9._-]"},
      {Entry("ops", "t", "admin"), at + ".name: 'ops' is listed twice"},
      {"  - {name: x, sha256: abc, role: admin}\n", at + ".sha256: expected 64 hex digits"},
      {Entry("x", "t", "pilot"), at + ".role: 'pilot' is not one of robot|planner|admin"},
      {Entry("x", "t", "planner", "robots: [a]"),
       at + ".robots: only a robot token lists robot ids"},
      {Entry("x", "t", "robot"), at + ".robots: a robot token lists the ids it ingests as"},
      {Entry("x", "t", "admin", "max_queries: 0"), at + ".max_queries: must be in 1..1000000"},
      {Entry("x", "t", "admin", "max_ingest_streams: many"),
       at + ".max_ingest_streams: not a number"},
      {Entry("x", "t", "admin", "max_watchers: 0"), at + ".max_watchers: must be in 1..1000000"},
      {Entry("x", "t", "admin", "max_event_streams: [1]"), at + ".max_event_streams: not a number"},
      {Entry("x", "admin-secret", "admin"), at + ".sha256: the same digest as another token"},
      {"  - just a string\n", at + ": expected a mapping"},
  };
  for (const Case& c : cases) {
    const std::string message = Refusal("tokens:\n" + good + c.entry);
    EXPECT_EQ(message.rfind(c.message, 0), 0u) << "entry " << c.entry << " gave: " << message;
  }
  EXPECT_EQ(Refusal("tokens: [unclosed").rfind(path_ + ": not YAML: ", 0), 0u);
  EXPECT_EQ(Refusal("users: []\n"), path_ + ": expected 'tokens:' holding a list");
  std::filesystem::remove(path_);
  EXPECT_EQ(Load().status().message(), path_ + ": cannot read");
}

TEST_F(TokenTableTest, AReloadKeepsTheOldTokensOnABadFileAndTheUsageAcrossAGoodOne) {
  Write("tokens:\n" + Entry("ops", "admin-secret", "admin"));
  Result<std::unique_ptr<TokenTable>> table = Load();
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  std::string why;
  PrincipalRef before = (*table)->Authenticate("Bearer admin-secret", &why);
  ASSERT_NE(before, nullptr);
  before->usage->queries.fetch_add(1);  // a query running across the reload

  Write("tokens: [broken\n");
  EXPECT_FALSE((*table)->Reload().ok());
  EXPECT_NE((*table)->Authenticate("Bearer admin-secret", &why), nullptr) << "the old tokens stay";

  Write("tokens:\n" + Entry("ops", "new-secret", "admin") + Entry("plan", "p", "planner"));
  ASSERT_TRUE((*table)->Reload().ok());
  EXPECT_EQ((*table)->size(), 2u);
  EXPECT_EQ((*table)->Authenticate("Bearer admin-secret", &why), nullptr);
  PrincipalRef after = (*table)->Authenticate("Bearer new-secret", &why);
  ASSERT_NE(after, nullptr) << why;
  EXPECT_EQ(after->usage, before->usage) << "the token's counters are the same object";
  EXPECT_EQ(after->usage->queries.load(), 1u);
}

}  // namespace
}  // namespace bgkmap
