// Runs the `bgkmap` binary under test as a user would, capturing its output and exit code.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace bgkmap::testing {

struct CliRun {
  int exit_code;
  std::string output;
};

// A shell command line (with its own redirections), what it printed and its exit code.
inline CliRun RunCommand(const std::string& cmd) {
  CliRun run{-1, ""};
  FILE* pipe = popen(cmd.c_str(), "r");
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, pipe)) run.output.append(buf, n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

// `bgkmap <args>`; `streams` is the shell redirection choosing what is captured, e.g. "2>&1"
// (both), "2>/dev/null" (stdout only) or "2>&1 >/dev/null" (stderr only).
inline CliRun RunCli(const std::string& args, const std::string& streams = "2>&1") {
  return RunCommand(std::string(BGKMAP_CLI) + " " + args + " " + streams);
}

}  // namespace bgkmap::testing
