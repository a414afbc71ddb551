// `bgkmap thin`: a sparser copy of a KITTI-like sequence, for scoring maps against a truth made
// from the whole sequence (`bgkmap truth`; docs/results.md, "Real street scans (issue 14
// protocol)"). Keeps the records at index i with i % N == offset of every scan file (bytes
// unchanged, intensity included) and, with --scans, only the listed scans (renumbered from 0).
// What index thinning removes depends on the order of the file's points: the Ouster street
// scans are ring-major (all returns of beam 0 by azimuth, then beam 1, ...), so there it keeps
// every N-th return along each ring: fewer columns, the same 128 rings.
//   <out>/velodyne/NNNNNN.bin, <out>/poses.txt, <out>/times.txt (if the source has one)
//   <out>/thin.json   the source, N, the offset, the scans kept and the points per scan
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "bgkmap/io/kitti_sequence.h"
#include "commands.h"
#include "json_output.h"

namespace bgkmap::cli {
namespace {

constexpr size_t kRecordBytes = 16;  // {x, y, z, intensity} float32

struct ThinOptions {
  std::string sequence;
  std::string out;
  int keep_every = 1;
  int offset = 0;
  std::vector<int> scans;  // empty: all
};

int Fail(const std::string& msg) {
  std::fprintf(stderr, "bgkmap thin: %s\n", msg.c_str());
  return kExitFailure;
}

int Usage(const std::string& msg) {
  Fail(msg);
  return kExitUsage;
}

int RunThin(const ThinOptions& o) {
  namespace fs = std::filesystem;
  if (o.offset >= o.keep_every) return Usage("--offset must be below --keep-every");
  Result<io::KittiSequence> seq = io::KittiSequence::Open(o.sequence);
  if (!seq.ok()) return Fail(seq.status().message());
  std::vector<size_t> scans;
  if (o.scans.empty()) {
    for (size_t k = 0; k < seq->size(); ++k) scans.push_back(k);
  } else {
    for (int k : o.scans) {
      if (k < 0 || static_cast<size_t>(k) >= seq->size()) {
        return Usage("--scans: no scan " + std::to_string(k) + " (the sequence has " +
                     std::to_string(seq->size()) + ")");
      }
      scans.push_back(static_cast<size_t>(k));
    }
  }
  const fs::path out(o.out);
  if (fs::exists(out / "velodyne") || fs::exists(out / "poses.txt")) {
    return Fail(o.out + ": already holds a sequence (choose an empty --out)");
  }
  std::error_code ec;
  fs::create_directories(out / "velodyne", ec);
  if (ec) return Fail(o.out + ": cannot create: " + ec.message());
  const std::string poses_path = (out / "poses.txt").string();
  std::ofstream times;
  if (seq->has_times()) times.open(out / "times.txt", std::ios::trunc);

  using Json = nlohmann::ordered_json;
  Json per_scan = Json::array();
  uint64_t total_in = 0, total_out = 0;
  for (size_t j = 0; j < scans.size(); ++j) {
    const size_t k = scans[j];
    std::ifstream in(seq->scan_path(k), std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.eof() && in.fail()) return Fail(seq->scan_path(k) + ": cannot read");
    if (bytes.size() % kRecordBytes != 0) {
      return Fail(seq->scan_path(k) + ": size is not a multiple of 16 bytes");
    }
    const size_t n = bytes.size() / kRecordBytes;
    std::vector<char> kept;
    kept.reserve((n / static_cast<size_t>(o.keep_every) + 1) * kRecordBytes);
    for (size_t i = static_cast<size_t>(o.offset); i < n; i += static_cast<size_t>(o.keep_every)) {
      kept.insert(kept.end(), bytes.begin() + static_cast<std::ptrdiff_t>(i * kRecordBytes),
                  bytes.begin() + static_cast<std::ptrdiff_t>((i + 1) * kRecordBytes));
    }
    const fs::path path = out / "velodyne" / io::KittiScanFileName(j);
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(kept.data(), static_cast<std::streamsize>(kept.size()));
    if (!f) return Fail(path.string() + ": cannot write");
    if (Status s = io::AppendPose(poses_path, seq->pose(k)); !s.ok()) return Fail(s.message());
    if (seq->has_times()) {
      Result<io::Scan> scan = seq->Read(k);  // for its time
      if (!scan.ok()) return Fail(scan.status().message());
      char line[64];
      std::snprintf(line, sizeof line, "%.17g\n", scan->time_s);
      times << line;
      if (!times) return Fail(o.out + "/times.txt: cannot write");
    }
    const uint64_t m = kept.size() / kRecordBytes;
    per_scan.push_back({{"source_scan", k}, {"points_in", n}, {"points_out", m}});
    total_in += n;
    total_out += m;
  }
  Json j;
  j["source"] = o.sequence;
  j["keep_every"] = o.keep_every;
  j["offset"] = o.offset;
  j["points_in"] = total_in;
  j["points_out"] = total_out;
  j["scans"] = std::move(per_scan);
  std::ofstream js(out / "thin.json");
  js << JsonText(j);
  if (!js) return Fail(o.out + "/thin.json: cannot write");
  std::printf("bgkmap thin: %zu scans, kept %llu of %llu points (every %d-th from %d) -> %s\n",
              scans.size(), static_cast<unsigned long long>(total_out),
              static_cast<unsigned long long>(total_in), o.keep_every, o.offset, o.out.c_str());
  return 0;
}

}  // namespace

void RegisterThinCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<ThinOptions>();
  CLI::App* cmd = app.add_subcommand(
      "thin", "Copy a KITTI-like sequence keeping every N-th point of each scan and chosen scans");
  cmd->add_option("sequence", o->sequence, "KITTI-like directory")->required();
  cmd->add_option("--out", o->out, "Output directory (a new KITTI-like sequence)")->required();
  cmd->add_option("--keep-every", o->keep_every,
                  "Keep the points whose index i in the scan file has i % N == offset (default 1)")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--offset", o->offset, "The index kept first (default 0)")
      ->check(CLI::Range(0, 1000000));
  cmd->add_option("--scans", o->scans, "Only these scans, in this order (default all), e.g. 0,2")
      ->delimiter(',');
  cmd->callback([o, &exit_code] { exit_code = RunThin(*o); });
}

}  // namespace bgkmap::cli
