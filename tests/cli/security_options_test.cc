// The client commands' TLS and token options against a bgkmapd with mutual TLS and tokens:
// --tls-ca, --tls-cert, --tls-key, --token-file and $BGKMAP_TOKEN; bad options are usage errors.
#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>

#include "bgkmapd_process.h"
#include "cli_runner.h"
#include "test_pki.h"

namespace bgkmap {
namespace {

std::string Sha256Hex(const std::string& text) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_Digest(text.data(), text.size(), digest, &length, EVP_sha256(), nullptr);
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    static constexpr char kHex[] = "0123456789abcdef";
    hex += kHex[digest[i] >> 4];
    hex += kHex[digest[i] & 15];
  }
  return hex;
}

class SecurityOptionsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/bgkmap_cli_tls_XXXXXX";
    ASSERT_NE(mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    ASSERT_TRUE(testing::MakeTestPki(dir_));
    std::ofstream(Path("tokens.yaml"))
        << "tokens:\n"
        << "  - {name: ops, sha256: " << Sha256Hex("admin-secret") << ", role: admin}\n"
        << "  - {name: planner, sha256: " << Sha256Hex("planner-secret") << ", role: planner}\n";
    std::ofstream(Path("admin.token")) << "admin-secret\n";  // as `echo` writes it
    server_ = std::make_unique<testing::BgkmapdProcess>(
        std::vector<std::string>{"--set", "server.tls.cert_file=" + Path("server.pem"), "--set",
                                 "server.tls.key_file=" + Path("server.key"), "--set",
                                 "server.tls.client_ca_file=" + Path("ca.pem"), "--set",
                                 "server.auth.tokens_file=" + Path("tokens.yaml")});
    ASSERT_TRUE(server_->started());
  }
  void TearDown() override {
    server_.reset();
    std::filesystem::remove_all(dir_);
  }
  std::string Path(const std::string& name) const { return dir_ + "/" + name; }
  // --server and every TLS option.
  std::string Tls() const {
    return " --server " + server_->target() + " --tls-ca " + Path("ca.pem") + " --tls-cert " +
           Path("client.pem") + " --tls-key " + Path("client.key");
  }

  std::string dir_;
  std::unique_ptr<testing::BgkmapdProcess> server_;
};

TEST_F(SecurityOptionsTest, TokenFromAFileOrTheEnvironmentOverMutualTls) {
  testing::CliRun info = testing::RunCli("info" + Tls() + " --token-file " + Path("admin.token"));
  EXPECT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("\"map_version\""), std::string::npos);
  testing::CliRun clear =
      testing::RunCommand("BGKMAP_TOKEN=planner-secret " + std::string(BGKMAP_CLI) +
                          " clear --bbox 0,0,1,1 --yes" + Tls() + " 2>&1");
  EXPECT_EQ(clear.exit_code, 1);
  EXPECT_NE(clear.output.find("PERMISSION_DENIED: token 'planner' has role planner"),
            std::string::npos)
      << clear.output;
  testing::CliRun cleared = testing::RunCli("clear --bbox 0,0,1,1 --yes" + Tls() +
                                            " --token-file " + Path("admin.token"));
  EXPECT_EQ(cleared.exit_code, 0) << cleared.output;
}

TEST_F(SecurityOptionsTest, MissingTokenOrTlsFailsAndBadOptionsAreUsageErrors) {
  testing::CliRun anonymous = testing::RunCommand("env -u BGKMAP_TOKEN " + std::string(BGKMAP_CLI) +
                                                  " info" + Tls() + " 2>&1");
  EXPECT_EQ(anonymous.exit_code, 1);
  EXPECT_NE(anonymous.output.find("UNAUTHENTICATED"), std::string::npos) << anonymous.output;
  testing::CliRun plaintext = testing::RunCli("info --server " + server_->target() +
                                              " --token-file " + Path("admin.token"));
  EXPECT_EQ(plaintext.exit_code, 1);
  EXPECT_NE(plaintext.output.find("UNAVAILABLE"), std::string::npos) << plaintext.output;
  testing::CliRun half = testing::RunCli("info --server " + server_->target() + " --tls-ca " +
                                         Path("ca.pem") + " --tls-cert " + Path("client.pem"));
  EXPECT_EQ(half.exit_code, 2);
  EXPECT_NE(half.output.find("--tls-cert and --tls-key go together"), std::string::npos)
      << half.output;
  testing::CliRun missing = testing::RunCli("info" + Tls() + " --token-file " + Path("none"));
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.output.find("--token-file: cannot read"), std::string::npos) << missing.output;
}

}  // namespace
}  // namespace bgkmap
