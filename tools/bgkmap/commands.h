// The `bgkmap` subcommands. Each Register* adds one subcommand to the app; the subcommand's
// callback sets `exit_code` (0 on success; on failure it has printed one line to stderr).
#pragma once

#include <CLI/CLI.hpp>

namespace bgkmap::cli {

void RegisterBuildCommand(CLI::App& app, int& exit_code);
void RegisterSimulateCommand(CLI::App& app, int& exit_code);
void RegisterEvalCommand(CLI::App& app, int& exit_code);
void RegisterRegressCommand(CLI::App& app, int& exit_code);
void RegisterInsertCommand(CLI::App& app, int& exit_code);
void RegisterQueryCommand(CLI::App& app, int& exit_code);
void RegisterPointsCommand(CLI::App& app, int& exit_code);
void RegisterCheckPathCommand(CLI::App& app, int& exit_code);
void RegisterWatchCommand(CLI::App& app, int& exit_code);
void RegisterInfoCommand(CLI::App& app, int& exit_code);
void RegisterClearCommand(CLI::App& app, int& exit_code);
void RegisterRobotsCommand(CLI::App& app, int& exit_code);
void RegisterRetireRobotCommand(CLI::App& app, int& exit_code);
void RegisterExportCommand(CLI::App& app, int& exit_code);
void RegisterImportCommand(CLI::App& app, int& exit_code);

}  // namespace bgkmap::cli
