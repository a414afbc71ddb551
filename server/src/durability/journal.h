// The journal: changes recorded before they are applied, so a restart applies them again
// (Durability's first concern; durability/durability.h).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"

namespace bgkmap {

// A change about to be applied, as the journal sees it: a scan, or a clear of `clear_box`.
struct ChangeRecord {
  uint64_t version = 0;
  std::shared_ptr<const PreparedScan> scan;  // null for a clear
  std::string robot_id;
  uint64_t sequence = 0;
  CellBox clear_box;
  // The raw scan, kept beside the record when the store retains scans for corrections.
  std::shared_ptr<const RawScan> raw_scan;
};

class Journal {
 public:
  // The state the map starts from: the version of its last change and each robot's last
  // logged sequence number.
  virtual uint64_t recovered_version() const = 0;
  virtual std::map<std::string, uint64_t> LoggedRobotSequences() const = 0;

  // Journals a change before it is applied (durable as configured); not OK: skip the change.
  // Changes that do not conflict call it concurrently.
  virtual Status Record(const ChangeRecord& change) = 0;

  // Forgets a robot's logged sequence number for good (it survives a restart as forgotten).
  // Called at a scheduler barrier: no scan of the robot is being journaled.
  virtual Status RetireRobot(const std::string& robot_id) = 0;

 protected:
  ~Journal() = default;
};

}  // namespace bgkmap
