#include "serving/archive_upload.h"

#include <spdlog/spdlog.h>

#include "bgkmap/server/log_safe.h"
#include "durability/archive_import.h"

namespace bgkmap {
namespace {

class SpooledUpload final : public ArchiveUpload {
 public:
  SpooledUpload(UploadTarget target, std::unique_ptr<SpoolFile> spool)
      : target_(std::move(target)), spool_(std::move(spool)) {}

  Status Append(std::string_view bytes) override {
    // The spool shares the store's disk: it must not eat the reserve RocksDB relies on.
    if (target_.admit) {
      if (Status s = target_.admit(bytes.size()); !s.ok()) return s;
    }
    return spool_->Append(bytes);
  }

  uint64_t size() const override { return spool_ != nullptr ? spool_->size() : 0; }

  void Submit(std::function<bool()> cancelled, std::function<void(ImportOutcome)> done) override {
    ImportOutcome out;
    out.bytes = spool_->size();
    auto stop = [&](ImportStage stage, Status status) {
      out.stage = stage;
      out.status = std::move(status);
      done(std::move(out));
    };
    if (Status s = spool_->Close(); !s.ok()) return stop(ImportStage::kSpool, s);
    Status checked =
        ReadVerifiedArchive(spool_->path(), target_.params, target_.georeference(), &archive_);
    spool_.reset();  // the tiles are in memory now
    if (!checked.ok()) {
      spdlog::warn("event=import_refused bytes={} reason=\"{}\"", out.bytes,
                   LogSafe(checked.message()));
      return stop(ImportStage::kCheck, checked);
    }
    if (cancelled()) {
      out.cancelled = true;
      return stop(ImportStage::kCheck, Status::Unavailable("import cancelled"));
    }
    // A map in a local frame takes a georeferenced archive's frame, before its tiles: the
    // tiles are placed by it (imports run one at a time, so nothing adopts another meanwhile).
    if (Status s = target_.adopt_georeference(archive_.metadata.georeference); !s.ok()) {
      return stop(ImportStage::kGeoreference, s);
    }
    out.tiles_added = archive_.keys.size();
    out.archive_map_version = archive_.metadata.map_version;
    out.archive_known_cells = archive_.known_cells;
    target_.add(archive_.keys, archive_.tiles,
                [this, out, done = std::move(done)](Result<uint64_t> version) mutable {
                  archive_.tiles.clear();
                  if (version.ok()) {
                    out.version = *version;
                  } else {
                    out.status = version.status();
                  }
                  done(std::move(out));
                });
  }

 private:
  const UploadTarget target_;
  std::unique_ptr<SpoolFile> spool_;
  VerifiedArchive archive_;
};

}  // namespace

Result<std::unique_ptr<ArchiveUpload>> StartArchiveUpload(UploadTarget target) {
  // Imports run one at a time: any other spool file there is a crash's leftover.
  if (target.exclusive) RemoveStaleSpoolFiles(target.directory);
  Result<std::unique_ptr<SpoolFile>> spool = SpoolFile::Create(target.directory);
  if (!spool.ok()) {
    // The directory is the operator's business, not the client's.
    spdlog::error("event=import_spool_failed dir=\"{}\" reason=\"{}\"", LogSafe(target.directory),
                  LogSafe(spool.status().message()));
    return Status::IoError("cannot spool it: " + spool.status().message());
  }
  return std::unique_ptr<ArchiveUpload>(
      new SpooledUpload(std::move(target), std::move(spool).value()));
}

}  // namespace bgkmap
