// `bgkmap correct --robot R --poses FILE`: a robot's SLAM revised its trajectory; the server
// re-integrates the scans with the corrected poses. `bgkmap remove-scans --robot R --from A --to
// B`: drops a robot's scans (a bad calibration).
#include <charconv>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "bgkmap/io/kitti_sequence.h"
#include "client_options.h"
#include "commands.h"

namespace bgkmap::cli {
namespace {

struct CorrectOptions {
  ServerTarget server;
  std::string robot;
  std::string poses_path;
};

// Lines of 12 numbers (row-major 3x4 T_map_sensor): line i (from 1) is sequence number i, the
// numbering `bgkmap insert` uses (scan k of a sequence is sequence k + 1). Lines of 13 numbers:
// the first is the sequence number. One form per file; blank lines are not allowed.
Result<std::vector<std::pair<uint64_t, ScanPose>>> ReadPoses(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::InvalidArgument("cannot open " + path);
  std::vector<std::pair<uint64_t, ScanPose>> out;
  std::string line;
  int columns = 0;
  for (uint64_t n = 1; std::getline(in, line); ++n) {
    const std::string where = path + ":" + std::to_string(n) + ": ";
    std::istringstream words(line);
    std::vector<std::string> tokens;
    for (std::string w; words >> w;) tokens.push_back(w);
    if (tokens.size() != 12 && tokens.size() != 13) {
      return Status::InvalidArgument(where + std::to_string(tokens.size()) +
                                     " numbers; expected 12 (a 3x4 pose) or 13 (seq and pose)");
    }
    if (columns != 0 && static_cast<int>(tokens.size()) != columns) {
      return Status::InvalidArgument(where + "mixes 12- and 13-number lines");
    }
    columns = static_cast<int>(tokens.size());
    uint64_t sequence = n;
    size_t first = 0;
    if (columns == 13) {
      const std::string& s = tokens[0];
      if (std::from_chars(s.data(), s.data() + s.size(), sequence).ec != std::errc() ||
          sequence == 0) {
        return Status::InvalidArgument(where + "sequence '" + s + "' is not a number above 0");
      }
      first = 1;
    }
    std::string pose_text;
    for (size_t i = first; i < tokens.size(); ++i) pose_text += tokens[i] + " ";
    Result<Pose> pose = io::ParseKittiPoseLine(pose_text);
    if (!pose.ok()) return Status::InvalidArgument(where + pose.status().message());
    out.emplace_back(sequence, ScanPose::FromPose(*pose));
  }
  if (out.empty()) return Status::InvalidArgument(path + ": no poses");
  return out;
}

void PrintResult(const char* command, const CorrectionResult& r) {
  std::printf(
      "bgkmap %s: %llu scans re-integrated at map version %llu (%llu of %llu log records "
      "replayed, %llu tiles changed, %.3f s)\n",
      command, static_cast<unsigned long long>(r.scans_revised),
      static_cast<unsigned long long>(r.map_version),
      static_cast<unsigned long long>(r.records_replayed),
      static_cast<unsigned long long>(r.records_in_history),
      static_cast<unsigned long long>(r.tiles_changed), r.seconds);
}

int RunCorrect(const CorrectOptions& o) {
  Result<std::vector<std::pair<uint64_t, ScanPose>>> poses = ReadPoses(o.poses_path);
  if (!poses.ok()) return Usage("correct", poses.status().message());
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("correct", connected.status().message());
  RpcResult<CorrectionResult> r = (*connected)->CorrectPoses(o.robot, *poses);
  if (!r.ok()) return Fail("correct", r.status().ToString());
  PrintResult("correct", *r);
  return 0;
}

struct RemoveOptions {
  ServerTarget server;
  std::string robot;
  uint64_t from = 0, to = 0;
};

int RunRemove(const RemoveOptions& o) {
  if (o.from > o.to) return Usage("remove-scans", "--from must not be above --to");
  Result<std::unique_ptr<Client>> connected = Connect(o.server);
  if (!connected.ok()) return Usage("remove-scans", connected.status().message());
  RpcResult<CorrectionResult> r = (*connected)->RemoveScans(o.robot, o.from, o.to);
  if (!r.ok()) return Fail("remove-scans", r.status().ToString());
  PrintResult("remove-scans", *r);
  return 0;
}

}  // namespace

void RegisterCorrectCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<CorrectOptions>();
  CLI::App* cmd = app.add_subcommand(
      "correct", "Re-integrate a robot's scans with corrected poses (its SLAM revised them)");
  AddServerOption(cmd, o->server);
  cmd->add_option("--robot", o->robot, "The robot whose scans are corrected")->required();
  cmd->add_option("--poses", o->poses_path,
                  "KITTI poses (row-major 3x4 T_map_sensor per line): line i is the scan sent "
                  "as sequence number i (bgkmap insert sends scan k as k+1), or 13 numbers per "
                  "line, the first being the sequence number, for a subset")
      ->required();
  cmd->callback([o, &exit_code] { exit_code = RunCorrect(*o); });
}

void RegisterRemoveScansCommand(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<RemoveOptions>();
  CLI::App* cmd = app.add_subcommand("remove-scans",
                                     "Remove a robot's scans by sequence number, as if never sent");
  AddServerOption(cmd, o->server);
  cmd->add_option("--robot", o->robot, "The robot whose scans are removed")->required();
  cmd->add_option("--from", o->from, "First sequence number removed")->required();
  cmd->add_option("--to", o->to, "Last sequence number removed (inclusive)")->required();
  cmd->callback([o, &exit_code] { exit_code = RunRemove(*o); });
}

}  // namespace bgkmap::cli
