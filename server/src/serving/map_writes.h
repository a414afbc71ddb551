// The changes a handler asks of the map (the port's write side, serving/map_port.h). Each is
// answered through `done`, which runs either on the caller's thread, when the map answers at
// once (a cluster node appending to its log), or later on a worker, once the change counts as
// applied (a single server). Nothing here knows of gRPC or of the store.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.h"
#include "bgkmap/core/raw_scan.h"
#include "bgkmap/core/scan.h"
#include "bgkmap/core/status.h"
#include "bgkmap/server/robot_stats.h"
#include "serving/robot_sequence.h"

namespace bgkmap {

// A scan on its way into the map, besides its prepared form.
struct ScanOrigin {
  std::string robot_id;
  uint64_t sequence = 0;
  Stamp stamp;
  // The raw scan as sent, when the map retains scans for corrections (retains_scans()).
  std::shared_ptr<const RawScan> raw;
  // The scan's message as it arrived (bgkmap.v1.Scan, encoded), for a map that logs scans as
  // they were sent (a cluster's log). Called at most once.
  std::function<std::string()> encoded = nullptr;
  // The scan's pose in the map frame, for the robot's recent poses (RobotStats); absent: none.
  std::optional<RobotPose> pose = std::nullopt;
};

struct ScanOutcome {
  uint64_t version = 0;
  std::vector<TileKey> changed_tiles;  // (a cluster node lists none)
  // Not OK: not applied. IoError or DataLoss: it could not be made durable; any other code:
  // the map refused it (Unavailable: a cluster's log is out of reach; OutOfRange: too large).
  Status status;
  // The map's log held it already (a retry the log stores once): not applied again.
  bool already_logged = false;
};

struct ClearOutcome {
  uint64_t version = 0;
  std::vector<TileKey> changed_tiles;  // (a cluster node lists none)
  Status status;                       // not OK: nothing was cleared; codes as in ScanOutcome
};

// Where an import stopped.
enum class ImportStage {
  kSpool,         // the upload could not be spooled or read back
  kCheck,         // the archive is refused: InvalidArgument, DataLoss or FailedPrecondition
  kGeoreference,  // the map cannot take the archive's georeference
  kChange,        // the change failed: DataLoss (a stored tile lost), OutOfRange (a sum would
                  // overflow), anything else (it could not be made durable)
};

struct ImportOutcome {
  uint64_t version = 0;
  Status status;  // not OK: nothing was imported
  ImportStage stage = ImportStage::kChange;
  bool cancelled = false;  // by the caller, once the archive was checked: nothing imported
  uint64_t tiles_added = 0;
  uint64_t archive_map_version = 0;
  uint64_t archive_known_cells = 0;
  uint64_t bytes = 0;  // of the upload
};

// An archive on its way into the map (ImportMap): its bytes are spooled as they arrive, then the
// whole archive is read and checked before anything changes, and added as one change (a merge:
// statistics are summed). What was spooled goes with the object, whatever the outcome.
class ArchiveUpload {
 public:
  virtual ~ArchiveUpload() = default;
  // IoError when the spool cannot take the bytes (or they would eat the free-space reserve).
  virtual Status Append(std::string_view bytes) = 0;
  virtual uint64_t size() const = 0;  // bytes spooled
  // Reads back and checks the archive against the map (parameters, georeference, every tile),
  // then adds it. `cancelled` is asked once it is checked, before anything changes. `done` runs
  // once (on this thread or a worker); the upload must outlive it.
  virtual void Submit(std::function<bool()> cancelled, std::function<void(ImportOutcome)> done) = 0;
};

// A map archive being written (ExportMap): a consistent snapshot at version(), encoded as it is
// read, while the map changes on.
class ArchiveChunks {
 public:
  virtual ~ArchiveChunks() = default;
  virtual uint64_t version() const = 0;
  // The next bytes of the archive: `max_bytes` of them unless they are its last, none once it is
  // complete. DataLoss naming a stored tile that fails its checksum.
  virtual Result<std::string> Next(size_t max_bytes) = 0;
  virtual bool complete() const = 0;   // every byte was handed out
  virtual uint64_t tiles() const = 0;  // written so far
  virtual uint64_t bytes() const = 0;
};

// A pose correction (or a removal) of one robot's logged scans (docs/semantics.md, "Pose
// corrections").
struct CorrectionSpec {
  std::string robot_id;
  std::map<uint64_t, Pose> poses;  // sequence number -> corrected T_map_sensor
  // Instead: remove the robot's scans with first <= sequence <= last.
  std::optional<std::pair<uint64_t, uint64_t>> remove;
  // Set (by the caller, any thread) when whoever asked no longer waits for it: a correction
  // not yet switched in is then dropped, nothing changed (issue 25). Null: never cancelled.
  std::shared_ptr<const std::atomic<bool>> cancelled;
  bool is_cancelled() const { return cancelled != nullptr && cancelled->load(); }
};

struct CorrectionOutcome {
  uint64_t version = 0;        // the correction's own map version
  uint64_t scans_revised = 0;  // corrected or removed
  uint64_t records_replayed = 0;
  uint64_t records_in_history = 0;
  std::vector<TileKey> changed_tiles;
  double seconds = 0;  // from submission to the switch
  Status status;       // not OK: nothing changed
};

class MapWrites {
 public:
  // The operations a map may not offer. Both maps offer all of them now (a cluster node since
  // corrections became log entries, issue 30). Offers() is OK, or Unimplemented naming the call
  // and what the map does offer; the operation itself then answers the same.
  enum class Operation { kExportMap, kCorrectPoses, kRemoveScans, kRetireRobot };
  virtual Status Offers(Operation operation) const = 0;

  // ---- Scans. A robot's scans must be submitted in the order they were sent.
  // Whether the map keeps raw scans (ScanOrigin::raw) for corrections.
  virtual bool retains_scans() const = 0;
  // At most how many scans of one robot a correction can name: the retained log's records
  // (CorrectionLog::retained_records_bound; cheap, reads nothing). 0 when none is retained.
  virtual uint64_t retained_records_bound() const = 0;
  // A retry after a lost ack, answered before the scan is prepared: true, counted as a
  // duplicate, if `sequence` is at or below the robot's last one (given in `last`).
  virtual bool TakeDuplicate(const std::string& robot_id, uint64_t sequence, uint64_t* last) = 0;
  // Counts a refused scan against its robot (robots already known only).
  virtual void CountRejected(const std::string& robot_id) = 0;
  // Admits the scan by its robot's sequence number (serving/robot_sequence.h) and applies it;
  // `done` runs for an admitted scan only. `last_sequence` (optional) receives the robot's last
  // sequence number before this scan (what a duplicate or a refused jump is measured against).
  virtual RobotAdmission SubmitScan(ScanOrigin origin, std::shared_ptr<const PreparedScan> scan,
                                    std::function<void(ScanOutcome)> done,
                                    uint64_t* last_sequence = nullptr) = 0;

  // ---- Other changes.
  // Forgets every cell of `box`, ordered with the scans.
  virtual void SubmitClear(const CellBox& box, std::function<void(ClearOutcome)> done) = 0;
  // An upload to add into the map; IoError naming no path if it cannot be spooled.
  virtual Result<std::unique_ptr<ArchiveUpload>> BeginImport() = 0;
  // A consistent snapshot of the map (or of the cells of `box`) as an archive.
  virtual void SubmitExport(const std::optional<CellBox>& box,
                            std::function<void(Result<std::unique_ptr<ArchiveChunks>>)> done) = 0;
  // Re-integrates a robot's scans with corrected poses, or without the removed ones, in the
  // background; `done` runs once it is durable (or refused: nothing changed).
  virtual void SubmitCorrection(CorrectionSpec spec,
                                std::function<void(CorrectionOutcome)> done) = 0;
  // Forgets a robot (also after a restart): `done` gets what it was; FailedPrecondition if it
  // is not known, IoError (and the robot kept) if that cannot be made durable.
  virtual void RetireRobot(const std::string& robot_id,
                           std::function<void(Result<RobotStats>)> done) = 0;

 protected:
  ~MapWrites() = default;
};

}  // namespace bgkmap
