#include "auth/principal.h"

#include <algorithm>

namespace bgkmap {

const char* RoleName(Role role) {
  switch (role) {
    case Role::kRobot:
      return "robot";
    case Role::kPlanner:
      return "planner";
    case Role::kAdmin:
      return "admin";
  }
  return "?";
}

const char* RightName(Right right) {
  switch (right) {
    case Right::kIngest:
      return "ingest";
    case Right::kQuery:
      return "query";
    case Right::kWatch:
      return "watch";
    case Right::kAdmin:
      return "admin";
  }
  return "?";
}

bool RoleHas(Role role, Right right) {
  switch (role) {
    case Role::kAdmin:
      return true;
    case Role::kRobot:
      return right == Right::kIngest || right == Right::kQuery;
    case Role::kPlanner:
      return right == Right::kQuery || right == Right::kWatch;
  }
  return false;
}

bool Principal::MayIngestAs(std::string_view robot_id) const {
  if (role == Role::kAdmin) return true;
  if (role != Role::kRobot) return false;
  return std::find(robots.begin(), robots.end(), robot_id) != robots.end();
}

PrincipalRef AnonymousPrincipal() {
  static const PrincipalRef anonymous = [] {
    auto p = std::make_shared<Principal>();
    p->name = "anonymous";
    p->role = Role::kAdmin;
    return p;
  }();
  return anonymous;
}

}  // namespace bgkmap
