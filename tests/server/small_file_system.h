// A small real file system for the disk tests: a tmpfs mounted on a fresh directory, unmounted
// (lazily) and removed with everything in it when the object goes. Mounting needs
// CAP_SYS_ADMIN (root, as on the CI machine); without it mounted() is false and error() says
// why, and the tests skip saying so.
#pragma once

#include <sys/mount.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

namespace bgkmap::testing {

class SmallFileSystem {
 public:
  explicit SmallFileSystem(int megabytes) {
    namespace fs = std::filesystem;
    path_ = (fs::temp_directory_path() / ("bgkmap_small_fs_" + std::to_string(getpid()))).string();
    fs::create_directories(path_);
    const std::string options = "size=" + std::to_string(megabytes) + "m,mode=0700";
    if (mount("tmpfs", path_.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, options.c_str()) != 0) {
      error_ = std::strerror(errno);
      return;
    }
    mounted_ = true;
  }
  ~SmallFileSystem() {
    if (mounted_) umount2(path_.c_str(), MNT_DETACH);
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  SmallFileSystem(const SmallFileSystem&) = delete;
  SmallFileSystem& operator=(const SmallFileSystem&) = delete;
  bool mounted() const { return mounted_; }
  const std::string& error() const { return error_; }
  std::string Sub(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
  std::string error_;
  bool mounted_ = false;
};

// Bytes of every regular file under `dir` (what the store holds on disk).
inline uint64_t DirectoryBytes(const std::string& dir) {
  uint64_t total = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir, ec)) {
    if (e.is_regular_file(ec)) total += e.file_size(ec);
  }
  return total;
}

}  // namespace bgkmap::testing
