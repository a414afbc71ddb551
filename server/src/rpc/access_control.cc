#include "rpc/access_control.h"

#include <spdlog/spdlog.h>

#include "bgkmap/server/log_safe.h"

namespace bgkmap {

const std::unordered_map<std::string, Right>& RpcRights() {
  static const std::unordered_map<std::string, Right> rights = {
      {"Ingest", Right::kIngest},
      {"IngestScan", Right::kIngest},
      {"QueryRegion", Right::kQuery},
      {"QueryPoints", Right::kQuery},
      {"CheckPath", Right::kQuery},
      {"Info", Right::kQuery},
      {"Watch", Right::kWatch},
      {"ClearRegion", Right::kAdmin},
      {"ExportMap", Right::kAdmin},
      {"ImportMap", Right::kAdmin},
      {"RetireRobot", Right::kAdmin},
      // The robot itself (checked in the handler, MayIngestAs) or an admin.
      {"CorrectPoses", Right::kIngest},
      {"RemoveScans", Right::kIngest},
  };
  return rights;
}

grpc::Status AccessControl::Admit(const grpc::CallbackServerContext& call,
                                  const std::string& method, PrincipalRef* who) const {
  const auto right = RpcRights().find(method);
  if (right == RpcRights().end()) {
    // A method without an entry is refused to everyone rather than allowed to anyone.
    return {grpc::StatusCode::PERMISSION_DENIED, method + ": no access rule; refused"};
  }
  if (tokens_ == nullptr) {
    *who = AnonymousPrincipal();
    return grpc::Status::OK;
  }
  std::string_view authorization;
  const auto& metadata = call.client_metadata();
  if (const auto it = metadata.find("authorization"); it != metadata.end()) {
    authorization = std::string_view(it->second.data(), it->second.size());
  }
  std::string why;
  PrincipalRef p = tokens_->Authenticate(authorization, &why);
  if (p == nullptr) {
    if (uint64_t suppressed = 0; refusal_log_.Allow(&suppressed)) {
      spdlog::warn("event=unauthenticated method={} reason=\"{}\" peer=\"{}\" suppressed={}",
                   method, why, LogSafe(call.peer()), suppressed);
    }
    return {grpc::StatusCode::UNAUTHENTICATED, why};
  }
  if (!p->Has(right->second)) {
    return {grpc::StatusCode::PERMISSION_DENIED,
            "token '" + p->name + "' has role " + RoleName(p->role) + ", which may not " +
                RightName(right->second) + " (" + method + " needs the " +
                RightName(right->second) + " right)"};
  }
  *who = std::move(p);
  return grpc::Status::OK;
}

grpc::Status NotThisRobot(const Principal& who, const std::string& robot_id) {
  std::string ids;
  for (const std::string& r : who.robots) ids += (ids.empty() ? "" : ",") + r;
  return {grpc::StatusCode::PERMISSION_DENIED, "robot_id: token '" + who.name + "' (role " +
                                                   RoleName(who.role) + ") may not ingest as '" +
                                                   LogSafe(robot_id, 128) +
                                                   "'; it may ingest as [" + ids + "]"};
}

}  // namespace bgkmap
