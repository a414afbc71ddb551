#include "bgkmap/storage/store_options.h"

#include <string>

namespace bgkmap::storage {

std::string_view DurabilityName(Durability d) {
  return d == Durability::kSync ? "sync" : "periodic";
}

Result<Durability> ParseDurability(std::string_view name) {
  if (name == "sync") return Durability::kSync;
  if (name == "periodic") return Durability::kPeriodic;
  return Status::InvalidArgument("durability = " + std::string(name) +
                                 ": must be one of sync, periodic");
}

}  // namespace bgkmap::storage
