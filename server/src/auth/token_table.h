// The bearer tokens bgkmapd accepts (server.auth.tokens_file): a YAML file
//
//   tokens:
//     - {name: lidar-7, sha256: <64 hex digits>, role: robot, robots: [lidar-7]}
//     - {name: planner, sha256: <...>, role: planner, max_queries: 32, max_watchers: 4}
//
// holding the SHA-256 digests of the tokens, never the tokens. A presented token is hashed and
// looked up by digest. The table is replaced whole on Reload(); a file that does not load keeps
// the table in use.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

#include "auth/principal.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

// Lower-case hex SHA-256 of `data`.
std::string Sha256Hex(std::string_view data);

class TokenTable {
 public:
  // Per-token limits for tokens whose entry names none.
  struct Defaults {
    uint32_t max_queries = 1;
    uint32_t max_ingest_streams = 1;
    uint32_t max_watchers = 1;
    uint32_t max_event_streams = 1;
  };

  // Reads `path`; the message names the file and the entry at fault.
  static Result<std::unique_ptr<TokenTable>> Load(const std::string& path, Defaults defaults);

  // Reads the file again and replaces the tokens; on failure keeps them and says why. The
  // principals of tokens the file no longer holds are marked revoked (Principal::Revoked).
  Status Reload();

  // The principal for an "authorization" header value ("Bearer <token>"), or null with `*why`
  // set (no token, not a bearer token, unknown token).
  PrincipalRef Authenticate(std::string_view authorization, std::string* why) const;

  size_t size() const;
  const std::string& path() const { return path_; }

 private:
  using Digests = std::unordered_map<std::string, PrincipalRef>;  // sha256 hex -> principal
  TokenTable(std::string path, Defaults defaults) : path_(std::move(path)), defaults_(defaults) {}
  Result<std::shared_ptr<const Digests>> Parse() const;

  const std::string path_;
  const Defaults defaults_;
  mutable std::mutex mu_;
  std::shared_ptr<const Digests> digests_;
  // Per-name counters, kept across reloads: a reload must not reset a token's open calls.
  mutable std::unordered_map<std::string, std::shared_ptr<TokenUsage>> usage_;
};

}  // namespace bgkmap
