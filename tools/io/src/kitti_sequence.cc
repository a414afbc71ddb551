#include "bgkmap/io/kitti_sequence.h"

#include <fmt/format.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <system_error>

#include "bgkmap/io/pcd_reader.h"
#include "binary_file.h"

namespace bgkmap::io {
namespace {

namespace fs = std::filesystem;

// The record layout is the host's float layout; a big-endian host would need byte swaps.
static_assert(std::endian::native == std::endian::little, "KITTI .bin I/O assumes little-endian");

constexpr size_t kRecordBytes = 4 * sizeof(float);

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

// Scan number of "NNNNNN.bin" or "NNNNNN.pcd" (digits only), or -1.
long long ScanNumber(const fs::path& p) {
  if (p.extension() != ".bin" && p.extension() != ".pcd") return -1;
  const std::string stem = p.stem().string();
  if (stem.empty()) return -1;
  long long n = 0;
  auto [end, ec] = std::from_chars(stem.data(), stem.data() + stem.size(), n);
  if (ec != std::errc() || end != stem.data() + stem.size() || n < 0) return -1;
  return n;
}

// The scan files of `scan_dir` in order: numbered 0..n-1 without a gap, all .bin or all .pcd.
// An empty folder is refused: zero scans would "succeed" with an empty map.
Result<std::vector<std::string>> ListScans(const fs::path& scan_dir) {
  std::error_code ec;
  std::map<long long, std::string> numbered;
  std::map<std::string, size_t> kinds;  // extension -> files
  for (const auto& entry : fs::directory_iterator(scan_dir, ec)) {
    const long long n = ScanNumber(entry.path());
    if (n >= 0 && entry.is_regular_file()) {
      numbered[n] = entry.path().string();
      ++kinds[entry.path().extension().string()];
    }
  }
  if (ec) return Status::IoError(scan_dir.string() + ": cannot list (" + ec.message() + ")");
  if (numbered.empty()) {
    return Status::DataLoss(scan_dir.string() +
                            ": no scans (neither NNNNNN.bin nor NNNNNN.pcd files)");
  }
  if (kinds.size() > 1) {
    return Status::DataLoss(scan_dir.string() + ": mixes .bin and .pcd scans; use one kind");
  }
  std::vector<std::string> paths;
  for (const auto& [n, path] : numbered) {
    if (n != static_cast<long long>(paths.size())) {
      return Status::DataLoss(fmt::format("{}: scan {} is missing (found {} instead)",
                                          scan_dir.string(), KittiScanFileName(paths.size()),
                                          path));
    }
    paths.push_back(path);
  }
  return paths;
}

}  // namespace

std::string KittiScanFileName(size_t k) { return fmt::format("{:06d}.bin", k); }

Result<Pose> ParseKittiPoseLine(std::string_view line) {
  double v[12];
  size_t count = 0;
  const char* p = line.data();
  const char* end = line.data() + line.size();
  while (true) {
    while (p < end && IsSpace(*p)) ++p;
    if (p == end) break;
    double x = 0;
    auto [next, ec] = std::from_chars(p, end, x);
    if (ec != std::errc() || (next < end && !IsSpace(*next))) {
      const char* tok_end = p;
      while (tok_end < end && !IsSpace(*tok_end)) ++tok_end;
      return Status::DataLoss("not a number: '" + std::string(p, tok_end) + "'");
    }
    if (!std::isfinite(x)) return Status::DataLoss("non-finite number in pose");
    if (count < 12) v[count] = x;
    ++count;
    p = next;
  }
  if (count != 12) return Status::DataLoss(fmt::format("expected 12 numbers, found {}", count));
  Pose pose;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) pose.rotation(r, c) = v[4 * r + c];
    pose.translation(r) = v[4 * r + 3];
  }
  return pose;
}

Result<KittiSequence> KittiSequence::Open(const std::string& directory) {
  std::error_code ec;
  if (!fs::is_directory(directory, ec)) {
    return Status::IoError(directory + ": not a directory");
  }
  const fs::path scan_dir = fs::path(directory) / "velodyne";
  if (!fs::is_directory(scan_dir, ec)) {
    return Status::IoError(
        directory +
        ": no scans (a sequence folder holds velodyne/NNNNNN.bin or "
        "velodyne/NNNNNN.pcd and poses.txt; recordings are .mcap, .db3 or .bag)");
  }

  Result<std::vector<std::string>> scans = ListScans(scan_dir);
  if (!scans.ok()) return scans.status();
  KittiSequence seq;
  seq.directory_ = directory;
  seq.scan_paths_ = std::move(scans).value();

  const std::string poses_path = (fs::path(directory) / "poses.txt").string();
  Result<std::string> text = internal::ReadWholeFile(poses_path);
  if (!text.ok()) return text.status();
  std::string_view rest = *text;
  size_t line_no = 0;
  while (!rest.empty()) {
    const size_t nl = rest.find('\n');
    const std::string_view line = rest.substr(0, nl);
    rest = nl == std::string_view::npos ? std::string_view() : rest.substr(nl + 1);
    ++line_no;
    // Trailing blank lines are common; a blank line between poses would shift every index.
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) {
      if (rest.find_first_not_of(" \t\r\n") == std::string_view::npos) break;
      return Status::DataLoss(fmt::format("{}:{}: empty line", poses_path, line_no));
    }
    Result<Pose> pose = ParseKittiPoseLine(line);
    if (!pose.ok()) {
      return Status::DataLoss(
          fmt::format("{}:{}: {}", poses_path, line_no, pose.status().message()));
    }
    seq.poses_.push_back(*pose);
  }
  if (seq.poses_.size() < seq.scan_paths_.size()) {
    return Status::DataLoss(fmt::format("{}: {} poses for {} scans", poses_path, seq.poses_.size(),
                                        seq.scan_paths_.size()));
  }
  seq.poses_.resize(seq.scan_paths_.size());

  // Scan times (KITTI odometry's times.txt): optional; the map time of forgetting.
  const std::string times_path = (fs::path(directory) / "times.txt").string();
  if (fs::exists(times_path, ec)) {
    Result<std::string> times = internal::ReadWholeFile(times_path);
    if (!times.ok()) return times.status();
    std::string_view left = *times;
    line_no = 0;
    while (!left.empty() && seq.times_.size() < seq.scan_paths_.size()) {
      const size_t nl = left.find('\n');
      std::string_view line = left.substr(0, nl);
      left = nl == std::string_view::npos ? std::string_view() : left.substr(nl + 1);
      ++line_no;
      const size_t b = line.find_first_not_of(" \t\r");
      const size_t e = line.find_last_not_of(" \t\r");
      line = b == std::string_view::npos ? std::string_view() : line.substr(b, e - b + 1);
      double t = 0;
      const auto [end, err] = std::from_chars(line.data(), line.data() + line.size(), t);
      if (line.empty() || err != std::errc() || end != line.data() + line.size() ||
          !std::isfinite(t)) {
        return Status::DataLoss(
            fmt::format("{}:{}: not a finite number of seconds: '{}'", times_path, line_no, line));
      }
      seq.times_.push_back(t);
    }
    if (seq.times_.size() < seq.scan_paths_.size()) {
      return Status::DataLoss(fmt::format("{}: {} times for {} scans", times_path,
                                          seq.times_.size(), seq.scan_paths_.size()));
    }
  }
  return seq;
}

Result<Scan> KittiSequence::Read(size_t k) const {
  if (k >= size()) {
    return Status::OutOfRange(
        fmt::format("{}: scan {} requested, sequence has {}", directory_, k, size()));
  }
  const std::string& path = scan_paths_[k];
  if (fs::path(path).extension() == ".pcd") return ReadPcdScan(path, k);
  thread_local std::string file;  // kept per reading thread: no fresh megabytes per scan
  if (Status s = internal::ReadWholeFileInto(path, file); !s.ok()) return s;
  if (file.size() % kRecordBytes != 0) {
    return Status::DataLoss(
        fmt::format("{}: size {} bytes is not a multiple of {} (x,y,z,i float32)", path,
                    file.size(), kRecordBytes));
  }
  Scan scan;
  scan.pose = poses_[k];
  if (!times_.empty()) scan.time_s = times_[k];
  const size_t n = file.size() / kRecordBytes;
  scan.points.resize(n);
  for (size_t i = 0; i < n; ++i) {
    std::memcpy(&scan.points[i], file.data() + i * kRecordBytes, sizeof(Point3f));
  }
  return scan;
}

Result<Scan> KittiSequence::ReadPcdScan(const std::string& path, size_t k) const {
  Result<PcdCloud> cloud = ReadPcd(path);
  if (!cloud.ok()) return cloud.status();
  Scan scan;
  scan.pose = poses_[k];
  if (!times_.empty()) scan.time_s = times_[k];
  scan.points.reserve(cloud->points.size());
  for (const Point3d& p : cloud->points) {
    scan.points.push_back(
        {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
  }
  return scan;
}

Status WriteKittiScan(const std::string& path, std::span<const Point3f> points,
                      std::span<const float> intensity) {
  if (!intensity.empty() && intensity.size() != points.size()) {
    return Status::InvalidArgument(
        fmt::format("{}: {} intensities for {} points", path, intensity.size(), points.size()));
  }
  std::string bytes(points.size() * kRecordBytes, '\0');
  for (size_t i = 0; i < points.size(); ++i) {
    const float rec[4] = {points[i].x, points[i].y, points[i].z,
                          intensity.empty() ? 0.0f : intensity[i]};
    std::memcpy(bytes.data() + i * kRecordBytes, rec, kRecordBytes);
  }
  return internal::WriteWholeFile(path, bytes);
}

Status AppendPose(const std::string& poses_path, const Pose& pose) {
  std::string line;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      const double v = c < 3 ? pose.rotation(r, c) : pose.translation(r);
      line += fmt::format("{}{:.17g}", line.empty() ? "" : " ", v);
    }
  }
  line += '\n';
  return internal::WriteWholeFile(poses_path, line, /*append=*/true);
}

}  // namespace bgkmap::io
