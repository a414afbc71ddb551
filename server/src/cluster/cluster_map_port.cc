// ClusterNode as the map port (serving/map_port.h): what a handler asks of a shard.
#include <filesystem>

#include "bgkmap/storage/map_metadata.h"
#include "cluster/cluster_node.h"
#include "serving/archive_upload.h"

namespace bgkmap::cluster {
namespace {

const char* CallName(MapWrites::Operation operation) {
  switch (operation) {
    case MapWrites::Operation::kExportMap:
      return "ExportMap";
    case MapWrites::Operation::kCorrectPoses:
      return "CorrectPoses";
    case MapWrites::Operation::kRemoveScans:
      return "RemoveScans";
    case MapWrites::Operation::kRetireRobot:
      return "RetireRobot";
  }
  return "this call";
}

// The calls a shard does not take yet (docs/scale-out.md, "What is not distributed yet").
Status NotOnShard(MapWrites::Operation operation) {
  return Status::Unimplemented(
      std::string(CallName(operation)) +
      " is not available on a cluster node yet (cluster.nats is set); ingest, QueryRegion, "
      "QueryPoints, CheckPath, Watch, ClearRegion, ImportMap and Info are");
}

}  // namespace

Status ClusterNode::Offers(Operation operation) const { return NotOnShard(operation); }

RobotAdmission ClusterNode::SubmitScan(ScanOrigin origin, std::shared_ptr<const PreparedScan> scan,
                                       std::function<void(ScanOutcome)> done,
                                       uint64_t* last_sequence) {
  if (last_sequence != nullptr) *last_sequence = 0;
  ScanOutcome outcome;
  Result<Appended> appended = Append(origin, *scan);
  if (appended.ok()) {
    outcome.version = appended->sequence;
    outcome.already_logged = appended->duplicate;
  } else {
    outcome.status = appended.status();
  }
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
    // One entry of the cluster's log (the tiles stored beside it): every shard adds them in the
    // log's order.
    done(AppendImport(keys, tiles));
  };
  return StartArchiveUpload(std::move(target));
}

void ClusterNode::SubmitExport(const std::optional<CellBox>&,
                               std::function<void(Result<std::unique_ptr<ArchiveChunks>>)> done) {
  done(NotOnShard(Operation::kExportMap));
}

void ClusterNode::SubmitCorrection(CorrectionSpec spec,
                                   std::function<void(CorrectionOutcome)> done) {
  CorrectionOutcome outcome;
  outcome.status = NotOnShard(spec.remove ? Operation::kRemoveScans : Operation::kCorrectPoses);
  done(std::move(outcome));
}

void ClusterNode::RetireRobot(const std::string&, std::function<void(Result<RobotStats>)> done) {
  done(NotOnShard(Operation::kRetireRobot));
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
  state.georeference = georeference();
  const ClusterStatus status = Describe();
  ShardState& shard = state.shard.emplace();
  shard.node = status.node;
  shard.live_nodes = status.live_nodes;
  shard.partitions_known = status.partitions_known;
  shard.partition_tiles = static_cast<uint32_t>(layout_.partition_tiles());
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
  // A round trip to the log: not on the caller's (gRPC's) thread.
  executor_([this, done = std::move(done)] { done(applied_version()); });
}

}  // namespace bgkmap::cluster
