// Pose corrections (docs/semantics.md, "Pose corrections"): the scans retained to prepare again,
// the plan and re-integration of a correction, and its journaling (Durability's fourth concern).
// A map that keeps no scans answers FailedPrecondition to each (the defaults).
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/storage/reintegration.h"
#include "durability/correction_plan.h"

namespace bgkmap {

class CorrectionLog {
 public:
  // Whether Record() keeps raw scans (ChangeRecord::raw_scan) for corrections.
  virtual bool retains_scans() const { return false; }
  // At most how many records (so scans of any one robot) the retained log holds: the map
  // versions after its oldest retained checkpoint, one record each. Reads nothing, so a
  // correction can be bounded by it before any work (issue 25). 0 when nothing is retained.
  virtual uint64_t retained_records_bound() const { return 0; }
  // Resolves a correction of `robot_id`'s scans against the log: its scans by sequence number,
  // each prepared again with its corrected pose in `poses` (or, with `remove`, the scans with
  // first <= sequence <= last dropped), and the retained checkpoint to rebuild from.
  // InvalidArgument for a pose the engine refuses; NotFound-like InvalidArgument for a sequence
  // never logged; FailedPrecondition when a scan is no longer retained (naming the robot's
  // oldest retained sequence number) or the map keeps none.
  virtual Result<CorrectionPlan> PlanCorrection(const std::string& robot_id,
                                                const std::map<uint64_t, Pose>& poses,
                                                const CorrectionRange& remove) const;
  // The re-integration of `plan` over the log's records below `end` (reintegration.h).
  virtual Result<storage::Reintegration> Reintegrate(const CorrectionPlan& plan, uint64_t end,
                                                     bool plan_only) const;
  // The map changed at `version` outside the log (an import): corrections cannot reach past it.
  virtual void NoteChangeOutsideLog(uint64_t /*version*/) {}
  // Journals the correction at `version` and rewrites the revised records, atomically and
  // durably: once OK, a restart rebuilds the corrected map.
  virtual Status RecordCorrection(const CorrectionPlan& plan, uint64_t version);

 protected:
  ~CorrectionLog() = default;
};

}  // namespace bgkmap
