// What a shard believes of what it reads from NATS. Anyone who can publish to the NATS servers can
// put entries in the log, answer tile fetches and write the membership buckets; with a cluster
// key (cluster.key_file) every such record carries an HMAC-SHA256 of its bytes and of what it
// answers (its subject, the request it replies to), made with the secret only the shards hold,
// and a shard verifies it before it believes the record. What fails is skipped, counted and
// logged (at most one line per kind every 10 s), never applied (docs/scale-out.md, "Trust").
// Without a key (cluster.insecure: true) nothing is signed and everything is believed.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

#include "bgkmap/core/status.h"

namespace bgkmap::cluster {

// What a refused record was, for the counts and the log.
enum class Untrusted { kLogEntry = 0, kTileReply, kMembership, kCheckpoint };
inline constexpr size_t kUntrustedKinds = 4;
const char* UntrustedName(Untrusted kind);

// The signer's clock and the NATS server's (which stamps what it stores) may differ by this
// much; a signed record stamped by the server longer than this before or after its signature
// was made is a replay (docs/scale-out.md: keep the hosts' clocks within it, e.g. by NTP).
inline constexpr std::chrono::seconds kMaxClockSkew{30};

class ClusterTrust {
 public:
  // The secret in `key_file` (surrounding whitespace ignored): at least 32 bytes, in a file no
  // one but its owner may read or write (FailedPrecondition naming the file otherwise, never the
  // secret). "" : no key (insecure).
  static Result<std::unique_ptr<ClusterTrust>> Open(const std::string& key_file);
  // No key: Sign answers "", Verify answers true.
  static std::unique_ptr<ClusterTrust> Insecure();

  bool keyed() const { return !secret_.empty(); }
  // HMAC-SHA256 of `fields`, each prefixed by its length (so "ab","c" and "a","bc" differ), in
  // lowercase hex; "" without a key.
  std::string Sign(std::initializer_list<std::string_view> fields) const;
  // Whether `mac` is Sign(fields), compared in constant time; true without a key.
  bool Verify(std::string_view mac, std::initializer_list<std::string_view> fields) const;

  // Counts a refused record of `kind` and logs `why` (rate-limited per kind).
  void Refuse(Untrusted kind, std::string_view why) const;
  uint64_t refused(Untrusted kind) const;

  // SHA-256 of `bytes`, lowercase hex (what a log entry's signed headers name its payload by).
  static std::string Digest(std::string_view bytes);
  // Now, in nanoseconds since the Unix epoch (the time a signature carries).
  static int64_t NowNs();
  // Whether a record signed at `signed_ns` and stored by a NATS server at `stored_ns` (both ns
  // since the epoch) may be the signer's own store of it: stored within kMaxClockSkew of the
  // signature, plus `allowed_delay` (how long a legitimate store may take after signing).
  static bool StoredInTime(int64_t signed_ns, int64_t stored_ns,
                           std::chrono::nanoseconds allowed_delay);

 private:
  explicit ClusterTrust(std::string secret) : secret_(std::move(secret)) {}
  const std::string secret_;
  mutable std::array<std::atomic<uint64_t>, kUntrustedKinds> refused_{};
  mutable std::mutex log_mu_;
  mutable std::array<std::chrono::steady_clock::time_point, kUntrustedKinds> logged_{};
  mutable std::array<uint64_t, kUntrustedKinds> logged_count_{};
};

}  // namespace bgkmap::cluster
