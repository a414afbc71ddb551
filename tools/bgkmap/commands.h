// The `bgkmap` subcommands. Each Register* adds one subcommand to the app; the subcommand's
// callback sets `exit_code` (below; on failure it has printed one line to stderr).
#pragma once

#include <CLI/CLI.hpp>

namespace bgkmap::cli {

// Exit codes, the same for every subcommand (README, "Exit codes").
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // the command ran and failed: server error, I/O, ...
inline constexpr int kExitUsage = 2;    // a bad command line, found by CLI11 or by the command
// `check-path`, like grep and diff: 0 safe, 1 unsafe, 2 error (usage or failure).
inline constexpr int kExitUnsafe = 1;
inline constexpr int kExitCheckError = 2;

void RegisterBuildCommand(CLI::App& app, int& exit_code);
void RegisterSimulateCommand(CLI::App& app, int& exit_code);
void RegisterEvalCommand(CLI::App& app, int& exit_code);
void RegisterTruthCommand(CLI::App& app, int& exit_code);
void RegisterThinCommand(CLI::App& app, int& exit_code);
void RegisterRegressCommand(CLI::App& app, int& exit_code);
void RegisterInsertCommand(CLI::App& app, int& exit_code);
void RegisterQueryCommand(CLI::App& app, int& exit_code);
void RegisterPointsCommand(CLI::App& app, int& exit_code);
void RegisterCheckPathCommand(CLI::App& app, int& exit_code);
void RegisterWatchCommand(CLI::App& app, int& exit_code);
void RegisterInfoCommand(CLI::App& app, int& exit_code);
void RegisterClearCommand(CLI::App& app, int& exit_code);
void RegisterRobotsCommand(CLI::App& app, int& exit_code);
void RegisterCorrectCommand(CLI::App& app, int& exit_code);
void RegisterRemoveScansCommand(CLI::App& app, int& exit_code);
void RegisterRetireRobotCommand(CLI::App& app, int& exit_code);
void RegisterExportCommand(CLI::App& app, int& exit_code);
void RegisterImportCommand(CLI::App& app, int& exit_code);

}  // namespace bgkmap::cli
