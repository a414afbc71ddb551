// `bgkmap`: the command-line tool. One binary, one subcommand per job. Exit codes are the same
// for every subcommand (commands.h): 0 success, 1 failure, 2 usage error; check-path 0 safe,
// 1 unsafe, 2 error.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>

#include "bgkmap/client/heap_policy.h"
#include "bgkmap/io/progress_bar.h"
#include "commands.h"

int main(int argc, char** argv) {
  bgkmap::KeepFreedHeapMemoryForReuse();  // a build's per-scan buffers do not fault in again
  CLI::App app{"bgkmap: BGK terrain traversability maps for ground robots"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("bgkmap ") + BGKMAP_VERSION);
  // --quiet anywhere on the line (fallthrough: also after the subcommand), before any bar is made.
  app.add_flag_callback(
         "--quiet,-q", [] { bgkmap::io::ProgressBar::SilenceAll(); }, "No progress bars on stderr")
      ->trigger_on_parse();
  app.fallthrough();
  int exit_code = 0;
  bgkmap::cli::RegisterBuildCommand(app, exit_code);
  bgkmap::cli::RegisterSimulateCommand(app, exit_code);
  bgkmap::cli::RegisterEvalCommand(app, exit_code);
  bgkmap::cli::RegisterTruthCommand(app, exit_code);
  bgkmap::cli::RegisterThinCommand(app, exit_code);
  bgkmap::cli::RegisterRegressCommand(app, exit_code);
  bgkmap::cli::RegisterInsertCommand(app, exit_code);
  bgkmap::cli::RegisterQueryCommand(app, exit_code);
  bgkmap::cli::RegisterPointsCommand(app, exit_code);
  bgkmap::cli::RegisterCheckPathCommand(app, exit_code);
  bgkmap::cli::RegisterWatchCommand(app, exit_code);
  bgkmap::cli::RegisterInfoCommand(app, exit_code);
  bgkmap::cli::RegisterClearCommand(app, exit_code);
  bgkmap::cli::RegisterRobotsCommand(app, exit_code);
  bgkmap::cli::RegisterRetireRobotCommand(app, exit_code);
  bgkmap::cli::RegisterCorrectCommand(app, exit_code);
  bgkmap::cli::RegisterRemoveScansCommand(app, exit_code);
  bgkmap::cli::RegisterExportCommand(app, exit_code);
  bgkmap::cli::RegisterImportCommand(app, exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every other parse error is a usage error.
    return app.exit(e) == 0 ? bgkmap::cli::kExitOk : bgkmap::cli::kExitUsage;
  }
  return exit_code;
}
