#include "auth/token_table.h"

#include <openssl/evp.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <set>
#include <sstream>
#include <utility>

namespace bgkmap {
namespace {

bool IsHexDigest(const std::string& s) {
  return s.size() == 64 && std::all_of(s.begin(), s.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

bool IsName(const std::string& s) {
  return !s.empty() && s.size() <= 128 && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
  });
}

Result<uint32_t> ReadLimit(const YAML::Node& node, const std::string& where) {
  try {
    const int64_t v = node.as<int64_t>();
    if (v < 1 || v > 1'000'000) return Status::InvalidArgument(where + ": must be in 1..1000000");
    return static_cast<uint32_t>(v);
  } catch (const YAML::Exception&) {
    return Status::InvalidArgument(where + ": not a number");
  }
}

// The tokens file as YAML, with its list of tokens.
Result<YAML::Node> ReadTokenList(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::IoError(path + ": cannot read");
  std::stringstream text;
  text << in.rdbuf();
  YAML::Node root;
  try {
    root = YAML::Load(text.str());
  } catch (const YAML::Exception& e) {
    return Status::InvalidArgument(path + ": not YAML: " + e.what());
  }
  if (!root.IsMap() || !root["tokens"] || !root["tokens"].IsSequence()) {
    return Status::InvalidArgument(path + ": expected 'tokens:' holding a list");
  }
  return root["tokens"];
}

Status CheckFields(const YAML::Node& t, const std::string& at) {
  if (!t.IsMap()) return Status::InvalidArgument(at + ": expected a mapping");
  for (const auto& field : t) {
    static const std::set<std::string> kFields = {
        "name",         "sha256",           "role", "robots", "max_queries", "max_ingest_streams",
        "max_watchers", "max_event_streams"};
    const std::string key = field.first.as<std::string>();
    if (kFields.count(key) == 0) return Status::InvalidArgument(at + "." + key + ": unknown key");
  }
  return Status::Ok();
}

// The entry's role, and for a robot token the ids it may ingest as.
Status ReadRole(const YAML::Node& t, const std::string& at, Principal* p) {
  const std::string role = t["role"] ? t["role"].as<std::string>() : "";
  if (role == "robot") {
    p->role = Role::kRobot;
  } else if (role == "planner") {
    p->role = Role::kPlanner;
  } else if (role == "admin") {
    p->role = Role::kAdmin;
  } else {
    return Status::InvalidArgument(at + ".role: '" + role + "' is not one of robot|planner|admin");
  }
  if (const YAML::Node robots = t["robots"]) {
    if (p->role != Role::kRobot) {
      return Status::InvalidArgument(at + ".robots: only a robot token lists robot ids");
    }
    if (!robots.IsSequence()) return Status::InvalidArgument(at + ".robots: expected a list");
    for (const auto& r : robots) p->robots.push_back(r.as<std::string>());
  }
  if (p->role == Role::kRobot && p->robots.empty()) {
    return Status::InvalidArgument(at + ".robots: a robot token lists the ids it ingests as");
  }
  return Status::Ok();
}

// The entry's per-token limits, `defaults` where it names none.
Status ReadLimits(const YAML::Node& t, const std::string& at, const TokenTable::Defaults& defaults,
                  Principal* p) {
  const std::pair<const char*, uint32_t Principal::*> kLimits[] = {
      {"max_queries", &Principal::max_queries},
      {"max_ingest_streams", &Principal::max_ingest_streams},
      {"max_watchers", &Principal::max_watchers},
      {"max_event_streams", &Principal::max_event_streams}};
  p->max_queries = defaults.max_queries;
  p->max_ingest_streams = defaults.max_ingest_streams;
  p->max_watchers = defaults.max_watchers;
  p->max_event_streams = defaults.max_event_streams;
  for (const auto& [key, field] : kLimits) {
    if (!t[key]) continue;
    Result<uint32_t> v = ReadLimit(t[key], at + "." + key);
    if (!v.ok()) return v.status();
    p->*field = *v;
  }
  return Status::Ok();
}

// One entry: its principal (without usage counters) and its digest; its name joins `names`
// (refused if already there). Throws YAML::Exception for a value of the wrong type.
Status ReadEntry(const YAML::Node& t, const std::string& at, const TokenTable::Defaults& defaults,
                 std::set<std::string>& names, Principal* p, std::string* digest) {
  if (Status s = CheckFields(t, at); !s.ok()) return s;
  p->name = t["name"] ? t["name"].as<std::string>() : "";
  if (!IsName(p->name)) {
    return Status::InvalidArgument(at + ".name: '" + p->name +
                                   "' must be 1..128 of [A-Za-z0-9._-]");
  }
  if (!names.insert(p->name).second) {
    return Status::InvalidArgument(at + ".name: '" + p->name + "' is listed twice");
  }
  *digest = t["sha256"] ? t["sha256"].as<std::string>() : "";
  std::transform(digest->begin(), digest->end(), digest->begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (!IsHexDigest(*digest)) {
    return Status::InvalidArgument(at +
                                   ".sha256: expected 64 hex digits (the token's "
                                   "SHA-256, e.g. `printf %s TOKEN | sha256sum`)");
  }
  if (Status s = ReadRole(t, at, p); !s.ok()) return s;
  return ReadLimits(t, at, defaults, p);
}

}  // namespace

std::string Sha256Hex(std::string_view data) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_Digest(data.data(), data.size(), digest, &length, EVP_sha256(), nullptr);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(2 * length);
  for (unsigned int i = 0; i < length; ++i) {
    hex += kHex[digest[i] >> 4];
    hex += kHex[digest[i] & 15];
  }
  return hex;
}

Result<std::unique_ptr<TokenTable>> TokenTable::Load(const std::string& path, Defaults defaults) {
  std::unique_ptr<TokenTable> table(new TokenTable(path, defaults));
  if (Status s = table->Reload(); !s.ok()) return s;
  return table;
}

Status TokenTable::Reload() {
  Result<std::shared_ptr<const Digests>> parsed = Parse();
  if (!parsed.ok()) return parsed.status();
  std::shared_ptr<const Digests> old;
  {
    std::lock_guard lock(mu_);
    old = std::exchange(digests_, *parsed);
  }
  // A token the new file no longer holds is revoked: the calls it has open see it and end.
  if (old != nullptr) {
    for (const auto& [digest, principal] : *old) {
      if (!(*parsed)->contains(digest)) principal->revoked->store(true);
    }
  }
  return Status::Ok();
}

Result<std::shared_ptr<const TokenTable::Digests>> TokenTable::Parse() const {
  Result<YAML::Node> tokens = ReadTokenList(path_);
  if (!tokens.ok()) return tokens.status();
  auto digests = std::make_shared<Digests>();
  std::set<std::string> names;
  for (size_t i = 0; i < tokens->size(); ++i) {
    const std::string at = path_ + ": tokens[" + std::to_string(i) + "]";
    auto p = std::make_shared<Principal>();
    std::string digest;
    try {
      if (Status s = ReadEntry((*tokens)[i], at, defaults_, names, p.get(), &digest); !s.ok()) {
        return s;
      }
    } catch (const YAML::Exception& e) {
      return Status::InvalidArgument(at + ": " + e.what());
    }
    if (digests->count(digest) > 0) {
      return Status::InvalidArgument(at + ".sha256: the same digest as another token");
    }
    {
      std::lock_guard lock(mu_);
      std::shared_ptr<TokenUsage>& usage = usage_[p->name];
      if (usage == nullptr) usage = std::make_shared<TokenUsage>();
      p->usage = usage;
    }
    digests->emplace(std::move(digest), std::move(p));
  }
  return std::shared_ptr<const Digests>(std::move(digests));
}

PrincipalRef TokenTable::Authenticate(std::string_view authorization, std::string* why) const {
  if (authorization.empty()) {
    *why = "no token: send the metadata 'authorization: Bearer <token>'";
    return nullptr;
  }
  constexpr std::string_view kScheme = "bearer ";
  if (authorization.size() <= kScheme.size() ||
      !std::equal(kScheme.begin(), kScheme.end(), authorization.begin(), [](char a, char b) {
        return a == std::tolower(static_cast<unsigned char>(b));
      })) {
    *why = "the 'authorization' metadata is not 'Bearer <token>'";
    return nullptr;
  }
  // Looked up by digest: the comparison's timing says nothing about the token itself.
  const std::string digest = Sha256Hex(authorization.substr(kScheme.size()));
  std::shared_ptr<const Digests> digests;
  {
    std::lock_guard lock(mu_);
    digests = digests_;
  }
  const auto it = digests->find(digest);
  if (it == digests->end()) {
    *why = "unknown token";
    return nullptr;
  }
  return it->second;
}

size_t TokenTable::size() const {
  std::lock_guard lock(mu_);
  return digests_ == nullptr ? 0 : digests_->size();
}

}  // namespace bgkmap
