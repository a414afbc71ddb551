// The cluster key (cluster/cluster_trust.h): what file it accepts, that its errors name the file
// and never the secret, and that an HMAC binds every field and its boundaries.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <string>

#include "cluster/cluster_trust.h"
#include "test_support.h"

namespace bgkmap::cluster {
namespace {

std::string WriteKey(const testing::TempDir& dir, const std::string& name,
                     const std::string& secret, mode_t mode) {
  const std::string path = dir.Sub(name);
  std::ofstream(path, std::ios::binary) << secret;
  chmod(path.c_str(), mode);
  return path;
}

TEST(ClusterKeyTest, AcceptsAnOwnersFileOfAtLeast32Bytes) {
  testing::TempDir dir("bgkmap_cluster_key");
  const std::string secret(31, 's');
  Result<std::unique_ptr<ClusterTrust>> short_key =
      ClusterTrust::Open(WriteKey(dir, "short", secret + "\n", 0600));
  ASSERT_FALSE(short_key.ok());
  EXPECT_NE(short_key.status().message().find("holds 31 bytes, at least 32"), std::string::npos)
      << short_key.status().message();
  EXPECT_EQ(short_key.status().message().find(secret), std::string::npos) << "the secret shows";

  const std::string good = "0123456789abcdef0123456789abcdef";
  Result<std::unique_ptr<ClusterTrust>> open_to_all =
      ClusterTrust::Open(WriteKey(dir, "shared", good, 0644));
  ASSERT_FALSE(open_to_all.ok());
  EXPECT_NE(open_to_all.status().message().find("chmod 600"), std::string::npos);
  EXPECT_FALSE(ClusterTrust::Open(dir.Sub("missing")).ok());

  // A trailing newline (openssl rand -hex 32 > file) is not part of the secret.
  Result<std::unique_ptr<ClusterTrust>> a = ClusterTrust::Open(WriteKey(dir, "a", good, 0600));
  Result<std::unique_ptr<ClusterTrust>> b =
      ClusterTrust::Open(WriteKey(dir, "b", good + "\n", 0400));
  ASSERT_TRUE(a.ok()) << a.status().message();
  ASSERT_TRUE(b.ok()) << b.status().message();
  EXPECT_TRUE((*a)->keyed());
  EXPECT_EQ((*a)->Sign({"x", "y"}), (*b)->Sign({"x", "y"}));
}

TEST(ClusterKeyTest, AnHmacBindsEveryFieldAndItsBoundaries) {
  testing::TempDir dir("bgkmap_cluster_key");
  Result<std::unique_ptr<ClusterTrust>> key =
      ClusterTrust::Open(WriteKey(dir, "k", std::string(40, 'k'), 0600));
  Result<std::unique_ptr<ClusterTrust>> other =
      ClusterTrust::Open(WriteKey(dir, "o", std::string(40, 'o'), 0600));
  ASSERT_TRUE(key.ok() && other.ok());
  const std::string mac = (*key)->Sign({"ab", "c"});
  EXPECT_EQ(mac.size(), 64u);  // SHA-256, hex
  EXPECT_TRUE((*key)->Verify(mac, {"ab", "c"}));
  EXPECT_FALSE((*key)->Verify(mac, {"a", "bc"}));
  EXPECT_FALSE((*key)->Verify(mac, {"ab", "c", ""}));
  EXPECT_FALSE((*key)->Verify(mac.substr(1), {"ab", "c"}));
  EXPECT_FALSE((*other)->Verify(mac, {"ab", "c"}));
  // Without a key nothing is signed and everything passes (cluster.insecure: true).
  const std::unique_ptr<ClusterTrust> open = ClusterTrust::Insecure();
  EXPECT_EQ(open->Sign({"ab", "c"}), "");
  EXPECT_TRUE(open->Verify("", {"ab", "c"}));
  // Refusals are counted per kind.
  (*key)->Refuse(Untrusted::kTileReply, "test");
  (*key)->Refuse(Untrusted::kTileReply, "test");
  EXPECT_EQ((*key)->refused(Untrusted::kTileReply), 2u);
  EXPECT_EQ((*key)->refused(Untrusted::kLogEntry), 0u);
}

TEST(ClusterKeyTest, StoredInTimeAllowsTheDelayAndTheSkewOnly) {
  const int64_t s = 1'000'000'000'000'000'000;
  const int64_t sec = 1'000'000'000;
  const auto delay = std::chrono::seconds(60);
  EXPECT_TRUE(ClusterTrust::StoredInTime(s, s + 1, delay));
  EXPECT_TRUE(ClusterTrust::StoredInTime(s, s + 89 * sec, delay));
  EXPECT_FALSE(ClusterTrust::StoredInTime(s, s + 91 * sec, delay));  // a copy, later
  EXPECT_TRUE(ClusterTrust::StoredInTime(s, s - 29 * sec, delay));   // the server's clock behind
  EXPECT_FALSE(ClusterTrust::StoredInTime(s, s - 31 * sec, delay));
}

}  // namespace
}  // namespace bgkmap::cluster
