#include "power_cut_file_system.h"

#include <algorithm>
#include <filesystem>
#include <optional>

namespace bgkmap::storage::testing {

using rocksdb::DataVerificationInfo;
using rocksdb::FileOptions;
using rocksdb::FSRandomRWFile;
using rocksdb::FSWritableFile;
using rocksdb::IODebugContext;
using rocksdb::IOOptions;
using rocksdb::IOStatus;
using rocksdb::Slice;

// A written file: forwards to the real one and keeps its FileState up to date; after the power
// cut every change is dropped.
class PowerCutWritableFile : public rocksdb::FSWritableFileOwnerWrapper {
 public:
  PowerCutWritableFile(std::unique_ptr<FSWritableFile> file, PowerCutFileSystem* fs,
                       std::shared_ptr<PowerCutFileSystem::FileState> state, bool wal)
      : FSWritableFileOwnerWrapper(std::move(file)), fs_(fs), state_(std::move(state)), wal_(wal) {}

  IOStatus Append(const Slice& data, const IOOptions& options, IODebugContext* dbg) override {
    if (fs_->power_is_cut()) return IOStatus::OK();
    IOStatus s = FSWritableFileOwnerWrapper::Append(data, options, dbg);
    if (s.ok()) Grow(data.size(), std::nullopt);
    return s;
  }
  IOStatus Append(const Slice& data, const IOOptions& options, const DataVerificationInfo& info,
                  IODebugContext* dbg) override {
    if (fs_->power_is_cut()) return IOStatus::OK();
    IOStatus s = FSWritableFileOwnerWrapper::Append(data, options, info, dbg);
    if (s.ok()) Grow(data.size(), std::nullopt);
    return s;
  }
  IOStatus PositionedAppend(const Slice& data, uint64_t offset, const IOOptions& options,
                            IODebugContext* dbg) override {
    if (fs_->power_is_cut()) return IOStatus::OK();
    IOStatus s = FSWritableFileOwnerWrapper::PositionedAppend(data, offset, options, dbg);
    if (s.ok()) Grow(data.size(), offset);
    return s;
  }
  IOStatus PositionedAppend(const Slice& data, uint64_t offset, const IOOptions& options,
                            const DataVerificationInfo& info, IODebugContext* dbg) override {
    if (fs_->power_is_cut()) return IOStatus::OK();
    IOStatus s = FSWritableFileOwnerWrapper::PositionedAppend(data, offset, options, info, dbg);
    if (s.ok()) Grow(data.size(), offset);
    return s;
  }
  IOStatus Truncate(uint64_t size, const IOOptions& options, IODebugContext* dbg) override {
    if (fs_->power_is_cut()) return IOStatus::OK();
    IOStatus s = FSWritableFileOwnerWrapper::Truncate(size, options, dbg);
    if (s.ok()) {
      std::lock_guard<std::mutex> lock(fs_->mu_);
      state_->size = size;
      state_->synced = std::min(state_->synced, size);
    }
    return s;
  }
  IOStatus Sync(const IOOptions& options, IODebugContext* dbg) override {
    return Durable([&] { return FSWritableFileOwnerWrapper::Sync(options, dbg); });
  }
  IOStatus Fsync(const IOOptions& options, IODebugContext* dbg) override {
    return Durable([&] { return FSWritableFileOwnerWrapper::Fsync(options, dbg); });
  }
  // sync_file_range: starts write-back, guarantees nothing; not a sync here.
  IOStatus RangeSync(uint64_t offset, uint64_t nbytes, const IOOptions& options,
                     IODebugContext* dbg) override {
    if (fs_->power_is_cut()) return IOStatus::OK();
    return FSWritableFileOwnerWrapper::RangeSync(offset, nbytes, options, dbg);
  }

 private:
  void Grow(uint64_t bytes, std::optional<uint64_t> offset) {
    std::lock_guard<std::mutex> lock(fs_->mu_);
    state_->size = offset ? std::max(state_->size, *offset + bytes) : state_->size + bytes;
  }

  // Only what was written before the sync started is certainly covered by it.
  template <typename SyncCall>
  IOStatus Durable(SyncCall sync) {
    if (fs_->power_is_cut()) return IOStatus::OK();
    uint64_t covered;
    {
      std::lock_guard<std::mutex> lock(fs_->mu_);
      covered = state_->size;
    }
    const uint64_t ticket = wal_ ? fs_->wal_sync_started_.fetch_add(1) + 1 : 0;
    IOStatus s = sync();
    // A sync that returns after the cut may not have reached the disk: it does not count.
    if (!s.ok() || fs_->power_is_cut()) return s;
    {
      std::lock_guard<std::mutex> lock(fs_->mu_);
      state_->synced = std::max(state_->synced, std::min(covered, state_->size));
      state_->ever_synced = true;
    }
    if (wal_) {
      uint64_t done = fs_->wal_sync_completed_.load();
      while (done < ticket && !fs_->wal_sync_completed_.compare_exchange_weak(done, ticket)) {
      }
    }
    return s;
  }

  PowerCutFileSystem* fs_;
  std::shared_ptr<PowerCutFileSystem::FileState> state_;
  const bool wal_;
};

PowerCutFileSystem::PowerCutFileSystem(std::shared_ptr<rocksdb::FileSystem> base)
    : rocksdb::FileSystemWrapper(base) {}

bool PowerCutFileSystem::IsWal(const std::string& name) const {
  return name.size() > 4 && name.compare(name.size() - 4, 4, ".log") == 0;
}

std::shared_ptr<PowerCutFileSystem::FileState> PowerCutFileSystem::Track(const std::string& name,
                                                                         uint64_t size,
                                                                         bool durable) {
  auto state = std::make_shared<FileState>();
  state->size = size;
  state->synced = durable ? size : 0;
  state->ever_synced = durable;
  std::lock_guard<std::mutex> lock(mu_);
  files_[name] = state;
  return state;
}

void PowerCutFileSystem::CutPower() { cut_.store(true); }

uint64_t PowerCutFileSystem::LoseUnsyncedData() {
  std::lock_guard<std::mutex> lock(mu_);
  uint64_t lost = 0;
  for (const auto& [name, state] : files_) {
    std::error_code ec;
    const uint64_t size = std::filesystem::file_size(name, ec);
    if (ec) continue;  // deleted before the cut
    const uint64_t keep = state->ever_synced ? std::min(size, state->synced) : 0;
    lost += size - keep;
    if (IsWal(name)) lost_wal_bytes_ += size - keep;
    if (!state->ever_synced) {
      std::filesystem::remove(name, ec);
    } else if (size > keep) {
      std::filesystem::resize_file(name, keep, ec);
    }
  }
  files_.clear();
  return lost;
}

IOStatus PowerCutFileSystem::NewWritableFile(const std::string& name, const FileOptions& options,
                                             std::unique_ptr<FSWritableFile>* result,
                                             IODebugContext* dbg) {
  // After the cut the file is still created (the store needs a handle while it closes), but
  // never synced, so LoseUnsyncedData() removes it.
  IOStatus s = target()->NewWritableFile(name, options, result, dbg);
  if (!s.ok()) return s;
  *result = std::make_unique<PowerCutWritableFile>(std::move(*result), this, Track(name, 0, false),
                                                   IsWal(name));
  return s;
}

IOStatus PowerCutFileSystem::ReopenWritableFile(const std::string& name, const FileOptions& options,
                                                std::unique_ptr<FSWritableFile>* result,
                                                IODebugContext* dbg) {
  IOStatus s = target()->ReopenWritableFile(name, options, result, dbg);
  if (!s.ok()) return s;
  std::shared_ptr<FileState> state;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = files_.find(name);
    if (it != files_.end()) state = it->second;
  }
  if (!state) {  // written before this file system knew it: taken as durable
    std::error_code ec;
    state = Track(name, std::filesystem::file_size(name, ec), true);
  }
  *result = std::make_unique<PowerCutWritableFile>(std::move(*result), this, state, IsWal(name));
  return s;
}

IOStatus PowerCutFileSystem::ReuseWritableFile(const std::string& name, const std::string& old_name,
                                               const FileOptions& options,
                                               std::unique_ptr<FSWritableFile>* result,
                                               IODebugContext* dbg) {
  if (power_is_cut()) return IOStatus::IOError("power is cut");
  IOStatus s = target()->ReuseWritableFile(name, old_name, options, result, dbg);
  if (!s.ok()) return s;
  {
    std::lock_guard<std::mutex> lock(mu_);
    files_.erase(old_name);
  }
  *result = std::make_unique<PowerCutWritableFile>(std::move(*result), this, Track(name, 0, false),
                                                   IsWal(name));
  return s;
}

// The store does not use random read-write files; refusing them keeps the model honest.
IOStatus PowerCutFileSystem::NewRandomRWFile(const std::string& name, const FileOptions&,
                                             std::unique_ptr<FSRandomRWFile>*, IODebugContext*) {
  return IOStatus::NotSupported("PowerCutFileSystem does not track random writes: " + name);
}

IOStatus PowerCutFileSystem::DeleteFile(const std::string& name, const IOOptions& options,
                                        IODebugContext* dbg) {
  if (power_is_cut()) return IOStatus::OK();
  IOStatus s = target()->DeleteFile(name, options, dbg);
  if (s.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    files_.erase(name);
  }
  return s;
}

IOStatus PowerCutFileSystem::RenameFile(const std::string& from, const std::string& to,
                                        const IOOptions& options, IODebugContext* dbg) {
  if (power_is_cut()) return IOStatus::OK();
  IOStatus s = target()->RenameFile(from, to, options, dbg);
  if (s.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = files_.find(from);
    if (it != files_.end()) {
      files_[to] = it->second;
      files_.erase(it);
    } else {
      files_.erase(to);  // replaced by a file written before we knew it: durable
    }
  }
  return s;
}

IOStatus PowerCutFileSystem::LinkFile(const std::string& from, const std::string& to,
                                      const IOOptions& options, IODebugContext* dbg) {
  if (power_is_cut()) return IOStatus::OK();
  IOStatus s = target()->LinkFile(from, to, options, dbg);
  if (s.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = files_.find(from);
    if (it != files_.end()) files_[to] = it->second;
  }
  return s;
}

IOStatus PowerCutFileSystem::Truncate(const std::string& name, size_t size,
                                      const IOOptions& options, IODebugContext* dbg) {
  if (power_is_cut()) return IOStatus::OK();
  IOStatus s = target()->Truncate(name, size, options, dbg);
  if (s.ok()) {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = files_.find(name);
    if (it != files_.end()) {
      it->second->size = size;
      it->second->synced = std::min<uint64_t>(it->second->synced, size);
    }
  }
  return s;
}

IOStatus PowerCutFileSystem::DeleteDir(const std::string& name, const IOOptions& options,
                                       IODebugContext* dbg) {
  if (power_is_cut()) return IOStatus::OK();
  return target()->DeleteDir(name, options, dbg);
}

}  // namespace bgkmap::storage::testing
