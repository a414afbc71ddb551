// ClusterNode as the map port (serving/map_port.h): what a handler asks of a shard.
#include <spdlog/spdlog.h>

#include <filesystem>
#include <tuple>

#include "bgkmap/storage/map_metadata.h"
#include "cluster/cluster_export.h"
#include "cluster/cluster_node.h"
#include "serving/archive_upload.h"
#include "serving/tile_table.h"

namespace bgkmap::cluster {
namespace {

// How long an append waits for the node's robot ledger to read its entry: normally a few
// milliseconds (it reads headers only), but while JetStream elects a stream leader after a NATS
// server's death the ledger's reader waits too (16-21 s measured on 2 loaded cores); the robot
// would otherwise hear UNAVAILABLE for a scan the log has stored.
constexpr int64_t kVerdictWaitMs = 60000;
// How long Info waits for the ledger to read the log's last entry before it answers with the
// ledger's counts as they are (a ledger behind an election).
constexpr int64_t kLedgerWaitMs = 5000;

}  // namespace

Status ClusterNode::Offers(Operation) const { return Status::Ok(); }

Result<std::pair<Appended, std::optional<LedgerVerdict>>> ClusterNode::AppendJudged(
    const ScanOrigin& origin, const PreparedScan& prepared) {
  const std::string encoded = origin.encoded();
  uint64_t epoch = ledger_->Epoch(origin.robot_id);
  std::string after;  // "/after<entry>": sent again after a refused entry of the same scan
  for (int attempt = 0;; ++attempt) {
    const std::string suffix = (epoch > 0 ? "/e" + std::to_string(epoch) : "") + after;
    Result<Appended> appended = Append(origin, encoded, prepared, suffix);
    if (!appended.ok()) return appended.status();
    // The log's order decides, as the partitions decide: the ledger's verdict on the entry.
    Result<std::optional<LedgerVerdict>> verdict =
        ledger_->WaitVerdict(appended->sequence, kVerdictWaitMs);
    if (!verdict.ok()) {
      return Status::Unavailable("the scan is in the cluster's log (entry " +
                                 std::to_string(appended->sequence) + ") but " +
                                 verdict.status().message() + "; send it again");
    }
    if (!appended->duplicate || !verdict->has_value() || attempt == 4) {
      return std::pair{*appended, *verdict};
    }
    const RobotAdmission first = (*verdict)->admission;
    if (first == RobotAdmission::kSequenceJump || first == RobotAdmission::kTooManyRobots) {
      after = "/after" + std::to_string(appended->sequence);  // that entry changed nothing
      continue;
    }
    // A retry, unless the robot was retired after that entry: known once the ledger has read
    // the log's end.
    Result<uint64_t> end = LastSequence(*nats_);
    if (!end.ok()) return Status::Unavailable(end.status().message());
    if (!ledger_->WaitRead(*end, kVerdictWaitMs)) {
      return Status::Unavailable("the cluster's robot ledger is behind the log; send it again");
    }
    epoch = ledger_->Epoch(origin.robot_id);
    if (epoch == (*verdict)->epoch) return std::pair{*appended, *verdict};
    after.clear();
  }
}

RobotAdmission ClusterNode::SubmitScan(ScanOrigin origin, std::shared_ptr<const PreparedScan> scan,
                                       std::function<void(ScanOutcome)> done,
                                       uint64_t* last_sequence) {
  if (last_sequence != nullptr) *last_sequence = 0;
  ScanOutcome outcome;
  Result<std::pair<Appended, std::optional<LedgerVerdict>>> judged = AppendJudged(origin, *scan);
  if (!judged.ok()) {
    outcome.status = judged.status();
    done(std::move(outcome));
    return RobotAdmission::kAdmitted;
  }
  const auto& [appended, verdict] = *judged;
  // Refused in the log's order (a duplicate, a jump, one robot too many): no partition applies
  // it, and the robot hears what a single server would tell it. (A verdict no longer kept is a
  // retry of an old entry.)
  if (verdict && verdict->admission != RobotAdmission::kAdmitted) {
    if (last_sequence != nullptr) *last_sequence = verdict->previous;
    return verdict->admission;
  }
  outcome.version = appended.sequence;
  outcome.already_logged = appended.duplicate;
  done(std::move(outcome));
  return RobotAdmission::kAdmitted;
}

void ClusterNode::SubmitClear(const CellBox& box, std::function<void(ClearOutcome)> done) {
  // In the cluster's log, ordered with the scans; the shards clear their copies as they read
  // it. The changed tiles are not known here (none are listed).
  Result<uint64_t> appended = AppendClear(box);
  ClearOutcome outcome;
  if (appended.ok()) {
    outcome.version = *appended;
  } else {
    outcome.status = appended.status();
  }
  done(std::move(outcome));
}

Result<std::unique_ptr<ArchiveUpload>> ClusterNode::BeginImport() {
  UploadTarget target;
  target.directory = std::filesystem::temp_directory_path().string();
  target.params = params_;
  target.georeference = [this] { return georeference(); };
  target.adopt_georeference = [this](const Georeference& g) { return AdoptGeoreference(g); };
  target.add = [this](std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles,
                      std::function<void(Result<uint64_t>)> done) {
    // Refused as a single server refuses it: a sum that would not be finite. Checked against
    // the tiles as of the log's end now (not at the import's own entry: a scan appended in
    // between is not seen).
    if (Status sums = CheckImportSums(keys, tiles); !sums.ok()) {
      done(sums);
      return;
    }
    // One entry of the cluster's log (the tiles stored beside it): every shard adds them in the
    // log's order.
    done(AppendImport(keys, tiles));
  };
  return StartArchiveUpload(std::move(target));
}

Status ClusterNode::CheckImportSums(std::span<const TileKey> keys,
                                    std::span<const std::unique_ptr<Tile>> tiles) const {
  if (keys.empty()) return Status::Ok();
  TileKey min = keys[0], max = keys[0];
  for (TileKey k : keys) {
    min = {std::min(min.x, k.x), std::min(min.y, k.y)};
    max = {std::max(max.x, k.x), std::max(max.y, k.y)};
  }
  Result<uint64_t> last = LastSequence(*nats_);
  if (!last.ok()) return Status::Unavailable(last.status().message());
  Result<std::unique_ptr<TerrainMap>> have = reads_->Gather(min, max, *last);
  if (!have.ok()) return Status::Unavailable(have.status().message());
  std::vector<const Tile*> adding;
  adding.reserve(tiles.size());
  for (const auto& t : tiles) adding.push_back(t.get());
  // The single server's own check, over the gathered tiles.
  const TileTable table(std::move(have).value(), /*keep_cleared=*/false);
  return table.CheckSumsFinite(keys, adding);
}

void ClusterNode::SubmitExport(const std::optional<CellBox>& box,
                               std::function<void(Result<std::unique_ptr<ArchiveChunks>>)> done) {
  // Round trips to the log and to every owner: on a worker, not the caller's (gRPC's) thread.
  Post([this, box, done = std::move(done)] { done(Export(box)); });
}

Result<std::unique_ptr<ArchiveChunks>> ClusterNode::Export(const std::optional<CellBox>& box) {
  // The snapshot point: an entry of the log, so every owner copies its tiles at the same place
  // in the log's order (later entries go on being applied meanwhile).
  Result<uint64_t> at = AppendExport(*nats_, *trust_);
  if (!at.ok()) return Status::Unavailable(at.status().message());
  if (!ledger_->WaitRead(*at, kVerdictWaitMs)) {
    return Status::Unavailable("the cluster's robot ledger has not read the export's entry");
  }
  // Every partition with data at the entry was recorded before it (before its first entry).
  Result<std::vector<PartitionKey>> recorded = members_->ListRecordedPartitions();
  if (!recorded.ok()) return Status::Unavailable(recorded.status().message());
  std::vector<PartitionKey> partitions;
  for (PartitionKey p : *recorded) {
    const CellBox cells = layout_.Cells(p);
    if (!box || (cells.max.x >= box->min.x && cells.min.x <= box->max.x &&
                 cells.max.y >= box->min.y && cells.min.y <= box->max.y)) {
      partitions.push_back(p);
    }
  }
  Result<std::unique_ptr<TerrainMap>> tiles = reads_->GatherAt(partitions, *at);
  if (!tiles.ok()) return tiles.status();
  storage::MapMetadata metadata;
  metadata.params = params_;
  metadata.georeference = georeference();
  // Versions as a single server fed the same changes counts them (RobotLedger::ChangesAt): the
  // archive's, and each tile's (stamped with the log sequence of its last change here). Robots'
  // sequences are not written, as a single server without a store writes none.
  metadata.map_version = metadata.checkpoint_version = ledger_->ChangesAt(*at);
  // The archive is streamed after this returns: it keeps its own copy of the count, not this node.
  return ClusterArchive::Start(std::move(tiles).value(), metadata, box, *at,
                               ledger_->ChangesUpTo(*at));
}

void ClusterNode::SubmitCorrection(CorrectionSpec spec,
                                   std::function<void(CorrectionOutcome)> done) {
  // Reads the log (its headers, the named scans) and appends one entry (cluster_corrections.cc):
  // on a worker. Answered once the log stores the entry, as a clear is; queries then read the
  // rebuilt partitions (an owner answers once it has applied the entry).
  ++corrections_in_progress_;
  Post([this, spec = std::move(spec), done = std::move(done)] {
    Result<CorrectionOutcome> outcome = Correct(spec);
    --corrections_in_progress_;
    if (outcome.ok()) {
      ledger_->WaitRead(outcome->version, kVerdictWaitMs);
      last_correction_seconds_ = outcome->seconds;
      done(std::move(outcome).value());
      return;
    }
    // Counted by every shard's ledger, as a single server counts the corrections it refuses.
    Result<uint64_t> recorded = AppendRefusal(*nats_, *trust_, spec.robot_id);
    if (recorded.ok()) {
      ledger_->WaitRead(*recorded, kVerdictWaitMs);
    } else {
      spdlog::warn("event=correction_refusal_not_recorded reason=\"{}\"",
                   recorded.status().message());
    }
    CorrectionOutcome refused;
    refused.status = outcome.status();
    done(std::move(refused));
  });
}

void ClusterNode::RetireRobot(const std::string& robot_id,
                              std::function<void(Result<RobotStats>)> done) {
  // An entry of the log: every partition and every node's ledger forgets the robot there, in
  // the log's order; the answer is what the ledger knew of the robot at that entry.
  Result<uint64_t> appended = AppendRetire(*nats_, *trust_, robot_id);
  if (!appended.ok()) {
    done(Status::IoError(appended.status().message()));
    return;
  }
  Result<std::optional<LedgerVerdict>> verdict = ledger_->WaitVerdict(*appended, kVerdictWaitMs);
  if (!verdict.ok()) {
    done(Status::IoError("the retirement is in the cluster's log (entry " +
                         std::to_string(*appended) + ") but " + verdict.status().message()));
  } else if (!verdict->has_value() || !(*verdict)->retired.has_value()) {
    done(Status::FailedPrecondition("robot_id: '" + robot_id + "' is not a known robot"));
  } else {
    done(*(*verdict)->retired);
  }
}

Georeference ClusterNode::georeference() const {
  std::lock_guard lock(georeference_mu_);
  return georeference_;
}

Status ClusterNode::AdoptGeoreference(const Georeference& georeference) {
  std::lock_guard lock(georeference_mu_);
  if (Status s = storage::CheckGeoreferenceCompatible(georeference_, georeference); !s.ok()) {
    return s;
  }
  if (georeference_.empty()) georeference_ = georeference;
  return Status::Ok();
}

MapState ClusterNode::State(bool /*with_disk_usage*/) {
  MapState state;
  state.version = known_version();
  state.robots = Robots();
  state.scans_applied = ledger_->scans_admitted();
  // The cluster's corrections from the log; those running and the last one's time this shard's.
  state.corrections = ledger_->corrections();
  state.corrections.in_progress = corrections_in_progress_.load();
  state.corrections.last_seconds = last_correction_seconds_.load();
  {
    std::lock_guard lock(summary_mu_);
    state.summary = summary_;
  }
  state.georeference = georeference();
  const ClusterStatus status = Describe();
  ShardState& shard = state.shard.emplace();
  shard.node = status.node;
  shard.live_nodes = status.live_nodes;
  shard.partitions_known = status.partitions_known;
  shard.partition_tiles = static_cast<uint32_t>(layout_.partition_tiles());
  shard.region_partitions = config_.region_partitions;
  std::tie(shard.nats_received_bytes, shard.nats_received_messages) = NatsReceived();
  for (const ReplicaStats& r : status.replicas) {
    shard.owned.push_back({PartitionName(r.key), r.log_sequence, r.scans_integrated, r.tiles,
                           r.serving, r.restored_from});
  }
  for (size_t k = 0; k < kUntrustedKinds; ++k) {
    const Untrusted kind = static_cast<Untrusted>(k);
    shard.refused.emplace_back(UntrustedName(kind), trust_->refused(kind));
  }
  return state;
}

void ClusterNode::ReadVersion(std::function<void(uint64_t)> done) {
  // A round trip to the log, then one to each partition's owner for its counts (what Info
  // reports with the version): not on the caller's (gRPC's) thread.
  Post([this, done = std::move(done)] {
    const uint64_t version = applied_version();
    // The ledger's counts (robots, scans, corrections) as of at least the same entry.
    ledger_->WaitRead(version, kLedgerWaitMs);
    Result<MapSummary> summary = reads_->Summarize(version);
    if (summary.ok()) {
      std::lock_guard lock(summary_mu_);
      summary_ = *summary;
    } else {
      spdlog::warn("event=cluster_summary_failed reason=\"{}\"", summary.status().message());
    }
    done(version);
  });
}

}  // namespace bgkmap::cluster
