#include "cluster/cluster_trust.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/sha.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <fstream>
#include <iterator>
#include <sstream>

namespace bgkmap::cluster {
namespace {

constexpr size_t kMinSecretBytes = 32;
constexpr auto kLogEvery = std::chrono::seconds(10);

std::string Hex(const unsigned char* bytes, size_t n) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(2 * n);
  for (size_t i = 0; i < n; ++i) {
    out.push_back(kDigits[bytes[i] >> 4]);
    out.push_back(kDigits[bytes[i] & 15]);
  }
  return out;
}

}  // namespace

const char* UntrustedName(Untrusted kind) {
  switch (kind) {
    case Untrusted::kLogEntry:
      return "log_entry";
    case Untrusted::kTileReply:
      return "tile_reply";
    case Untrusted::kMembership:
      return "membership";
    case Untrusted::kCheckpoint:
      return "checkpoint";
  }
  return "unknown";
}

Result<std::unique_ptr<ClusterTrust>> ClusterTrust::Open(const std::string& key_file) {
  if (key_file.empty()) return Insecure();
  const std::string what = "cluster.key_file '" + key_file + "'";
  struct stat st {};
  if (stat(key_file.c_str(), &st) != 0) {
    return Status::FailedPrecondition(what + ": cannot be read");
  }
  if ((st.st_mode & (S_IRWXG | S_IRWXO)) != 0) {
    return Status::FailedPrecondition(what +
                                      ": others may read or write it (chmod 600 it: it holds "
                                      "the cluster's secret)");
  }
  std::ifstream in(key_file, std::ios::binary);
  if (!in) return Status::FailedPrecondition(what + ": cannot be read");
  std::string secret((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto space = [](char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; };
  while (!secret.empty() && space(secret.back())) secret.pop_back();
  size_t lead = 0;
  while (lead < secret.size() && space(secret[lead])) ++lead;
  secret.erase(0, lead);
  if (secret.size() < kMinSecretBytes) {
    return Status::FailedPrecondition(what + ": holds " + std::to_string(secret.size()) +
                                      " bytes, at least " + std::to_string(kMinSecretBytes) +
                                      " are needed (e.g. openssl rand -hex 32 > " + key_file + ")");
  }
  return std::unique_ptr<ClusterTrust>(new ClusterTrust(std::move(secret)));
}

std::unique_ptr<ClusterTrust> ClusterTrust::Insecure() {
  return std::unique_ptr<ClusterTrust>(new ClusterTrust(""));
}

std::string ClusterTrust::Sign(std::initializer_list<std::string_view> fields) const {
  if (!keyed()) return "";
  std::string message;
  for (std::string_view f : fields) {
    message += std::to_string(f.size());
    message += ':';
    message += f;
  }
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  HMAC(EVP_sha256(), secret_.data(), static_cast<int>(secret_.size()),
       reinterpret_cast<const unsigned char*>(message.data()), message.size(), mac, &len);
  return Hex(mac, len);
}

bool ClusterTrust::Verify(std::string_view mac,
                          std::initializer_list<std::string_view> fields) const {
  if (!keyed()) return true;
  const std::string want = Sign(fields);
  return mac.size() == want.size() && CRYPTO_memcmp(mac.data(), want.data(), want.size()) == 0;
}

void ClusterTrust::Refuse(Untrusted kind, std::string_view why) const {
  const size_t k = static_cast<size_t>(kind);
  const uint64_t total = ++refused_[k];
  std::lock_guard lock(log_mu_);
  const auto now = std::chrono::steady_clock::now();
  if (logged_count_[k] != 0 && now - logged_[k] < kLogEvery) return;
  spdlog::warn(
      "event=cluster_untrusted_refused kind={} refused_total={} since_last_line={} "
      "reason=\"{}\"",
      UntrustedName(kind), total, total - logged_count_[k], why);
  logged_[k] = now;
  logged_count_[k] = total;
}

uint64_t ClusterTrust::refused(Untrusted kind) const {
  return refused_[static_cast<size_t>(kind)].load();
}

std::string ClusterTrust::Digest(std::string_view bytes) {
  unsigned char digest[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), digest);
  return Hex(digest, sizeof digest);
}

int64_t ClusterTrust::NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

bool ClusterTrust::StoredInTime(int64_t signed_ns, int64_t stored_ns,
                                std::chrono::nanoseconds allowed_delay) {
  const int64_t skew = std::chrono::nanoseconds(kMaxClockSkew).count();
  const int64_t delay = stored_ns - signed_ns;
  return delay >= -skew && delay <= skew + allowed_delay.count();
}

}  // namespace bgkmap::cluster
