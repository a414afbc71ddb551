// A pose correction (or a removal) of one robot's logged scans, as resolved against the scan
// log (docs/semantics.md, "Pose corrections").
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/storage/log_record.h"

namespace bgkmap {

// A removal's first and last sequence numbers (nullopt: a correction of poses).
using CorrectionRange = std::optional<std::pair<uint64_t, uint64_t>>;

struct CorrectionPlan {
  std::string robot_id;
  uint64_t base = 0;                // the retained checkpoint the rebuild starts from
  std::vector<TileKey> seed_tiles;  // the revised scans' tiles as first logged
  // By version: the scan prepared again with its corrected pose, or null (removed).
  std::map<uint64_t, std::shared_ptr<const PreparedScan>> replacements;
  std::vector<storage::LogRecord> rewritten;  // the revised records, with their raw scans
  std::vector<uint64_t> removed;              // versions of the removed records
};

}  // namespace bgkmap
