#include "durability/correction_log.h"

namespace bgkmap {
namespace {
Status NoCorrections() {
  return Status::FailedPrecondition(
      "pose corrections need a persistent store: set storage.data_dir (the map is in memory)");
}
}  // namespace

Result<CorrectionPlan> CorrectionLog::PlanCorrection(const std::string&,
                                                     const std::map<uint64_t, Pose>&,
                                                     const CorrectionRange&) const {
  return NoCorrections();
}

Result<storage::Reintegration> CorrectionLog::Reintegrate(const CorrectionPlan&, uint64_t,
                                                          bool) const {
  return NoCorrections();
}

Status CorrectionLog::RecordCorrection(const CorrectionPlan&, uint64_t) { return NoCorrections(); }

}  // namespace bgkmap
