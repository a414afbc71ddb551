// Who a call comes from: the token's name, its role and what it may do. Known before any handler
// runs, so that every handler's checks (a robot's ids, a token's quotas) read one value.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace bgkmap {

// robot: ingest as its listed ids, and query. planner: query and watch. admin: everything.
enum class Role { kRobot, kPlanner, kAdmin };

// What an RPC needs (rpc/rpc_rights.h maps each RPC to one).
enum class Right { kIngest, kQuery, kWatch, kAdmin };

const char* RoleName(Role role);
const char* RightName(Right right);
bool RoleHas(Role role, Right right);

// What one token holds at a time, counted across its calls (and across tokens-file reloads).
struct TokenUsage {
  std::atomic<uint32_t> queries{0};
  std::atomic<uint32_t> ingest_streams{0};
  std::atomic<uint32_t> corrections{0};    // CorrectPoses and RemoveScans running (at most one)
  std::atomic<uint32_t> watchers{0};       // open Watch streams
  std::atomic<uint32_t> event_streams{0};  // open GET /events streams of the web map
};

struct Principal {
  std::string name;  // the token's name; "anonymous" when authentication is off
  Role role = Role::kAdmin;
  std::vector<std::string> robots;  // kRobot: the ids it may ingest as
  // Per-token limits; usage is null when authentication is off (no per-token quota).
  uint32_t max_queries = 0;
  uint32_t max_ingest_streams = 0;
  uint32_t max_watchers = 0;
  uint32_t max_event_streams = 0;
  std::shared_ptr<TokenUsage> usage;
  // Set when a reload of the tokens file dropped this token: its open streams end within the
  // streams' watchdog period, at most a second (issue 25).
  std::shared_ptr<std::atomic<bool>> revoked = std::make_shared<std::atomic<bool>>(false);

  bool Has(Right right) const { return RoleHas(role, right); }
  bool Revoked() const { return revoked->load(); }
  // A robot token ingests only as its own ids; planners never; admins (and anonymous) as any.
  bool MayIngestAs(std::string_view robot_id) const;
};

using PrincipalRef = std::shared_ptr<const Principal>;

// The caller when server.auth.tokens_file is not set: every right, no per-token quota.
PrincipalRef AnonymousPrincipal();

}  // namespace bgkmap
