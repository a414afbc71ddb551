// ServedMap's archives: imports spooled and checked (serving/archive_upload.h) before they are
// added as one change, and exports written from a snapshot taken at a barrier
// (durability/archive_export.h).
#include <climits>

#include "durability/archive_export.h"
#include "serving/archive_upload.h"
#include "serving/served_map.h"

namespace bgkmap {
namespace {

// The port's view of an archive being written.
class ExportedArchive final : public ArchiveChunks {
 public:
  explicit ExportedArchive(std::unique_ptr<ArchiveExport> archive) : archive_(std::move(archive)) {}
  uint64_t version() const override { return archive_->version(); }
  Result<std::string> Next(size_t max_bytes) override { return archive_->Next(max_bytes); }
  bool complete() const override { return archive_->complete(); }
  uint64_t tiles() const override { return archive_->tiles(); }
  uint64_t bytes() const override { return archive_->bytes(); }

 private:
  std::unique_ptr<ArchiveExport> archive_;
};

}  // namespace

Result<std::unique_ptr<ArchiveUpload>> ServedMap::BeginImport() {
  const Durability::ScratchDirectory dir = durability_.scratch_directory();
  UploadTarget target;
  target.directory = dir.path;
  target.exclusive = dir.exclusive;
  target.params = params();
  target.georeference = [this] { return durability_.georeference(); };
  target.admit = [this](uint64_t bytes) { return durability_.AdmitScratch(bytes); };
  target.adopt_georeference = [this](const Georeference& g) {
    return durability_.AdoptGeoreference(g);
  };
  target.add = [this](std::span<const TileKey> keys, std::span<const std::unique_ptr<Tile>> tiles,
                      std::function<void(Result<uint64_t>)> done) {
    SubmitImport(keys, tiles, [done = std::move(done)](const ImportOutcome& outcome) {
      done(outcome.status.ok() ? Result<uint64_t>(outcome.version)
                               : Result<uint64_t>(outcome.status));
    });
  };
  return StartArchiveUpload(std::move(target));
}

void ServedMap::SubmitExport(const std::optional<CellBox>& box,
                             std::function<void(Result<std::unique_ptr<ArchiveChunks>>)> done) {
  TileKey min{INT_MIN, INT_MIN}, max{INT_MAX, INT_MAX};
  if (box) {
    min = geometry().TileOf(box->min);
    max = geometry().TileOf(box->max);
  }
  SubmitSnapshot(min, max, [this, box, done = std::move(done)](Result<MapSnapshot> snapshot) {
    if (!snapshot.ok()) return done(snapshot.status());
    storage::MapMetadata metadata;
    metadata.params = params();
    metadata.georeference = durability_.georeference();
    metadata.map_version = snapshot->version;
    metadata.checkpoint_version = snapshot->version;
    metadata.robot_sequences = std::move(snapshot->robot_sequences);
    Result<std::unique_ptr<ArchiveExport>> archive =
        ArchiveExport::Start(std::move(snapshot->tiles), metadata, geometry(), box);
    if (!archive.ok()) return done(archive.status());
    done(std::unique_ptr<ArchiveChunks>(new ExportedArchive(std::move(archive).value())));
  });
}

}  // namespace bgkmap
