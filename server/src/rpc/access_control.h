// Who may call which RPC. RpcRights() is the one table mapping every MapService method to the
// right it needs (a test checks that every method of the service's descriptor has an entry);
// AccessControl authenticates a call's bearer token and checks the right before any handler
// runs.
#pragma once

#include <grpcpp/server_context.h>

#include <string>
#include <string_view>
#include <unordered_map>

#include "auth/principal.h"
#include "auth/token_table.h"
#include "rpc/log_rate_limit.h"

namespace bgkmap {

// Method name ("QueryPoints") -> the right it needs.
const std::unordered_map<std::string, Right>& RpcRights();

class AccessControl {
 public:
  // `tokens` null: authentication is off and every caller is AnonymousPrincipal().
  explicit AccessControl(const TokenTable* tokens) : tokens_(tokens) {}

  // OK with *who set; UNAUTHENTICATED (no or unknown token) or PERMISSION_DENIED (the token's
  // role lacks the method's right), with the reason.
  grpc::Status Admit(const grpc::CallbackServerContext& call, const std::string& method,
                     PrincipalRef* who) const;

 private:
  const TokenTable* tokens_;
  // Refusals are logged at most 10 times a second (a client retrying without a token).
  mutable LogRateLimit refusal_log_{10};
};

// PERMISSION_DENIED for a robot token sending a scan as an id it does not list.
grpc::Status NotThisRobot(const Principal& who, const std::string& robot_id);

}  // namespace bgkmap
