// Runs the real bgkmapd binary on a loopback port for a test: starts it, reads its log, signals
// it, waits for its exit code.
#pragma once

#include <sys/types.h>

#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace bgkmap::testing {

class BgkmapdProcess {
 public:
  // Starts `bgkmapd --listen 127.0.0.1:0 <args>` and waits for its "event=listening" log line.
  explicit BgkmapdProcess(const std::vector<std::string>& args = {});
  // Any program (`argv[0]` a path), started once a line of its output (stdout and stderr)
  // matches `ready`; its first group, if any, is the port.
  BgkmapdProcess(std::vector<std::string> argv, const std::string& ready);
  ~BgkmapdProcess();  // SIGKILL if still running

  bool started() const { return port_ > 0; }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }

  void Signal(int signal);
  // Exit code (128 + signal if killed by one); -1 on timeout.
  int Wait(int timeout_s = 60);
  // The exit code if the process has exited, -1 while it runs; does not wait.
  int Poll();
  // Every log line so far.
  std::vector<std::string> Log();
  // The first log line containing `needle` ("" if none).
  std::string FindLine(const std::string& needle);
  // FindLine() until it finds one or `seconds` pass.
  std::string WaitForLine(const std::string& needle, double seconds);

 private:
  void Spawn(std::vector<std::string> args, const std::string& ready, bool with_stdout);
  void ReadLog(int fd);
  pid_t pid_ = -1;
  int port_ = 0;
  int exit_code_ = -1;
  std::thread reader_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::string> lines_;
  bool eof_ = false;
};

// Runs bgkmapd with `args` to completion and returns (exit code, stdout).
std::pair<int, std::string> RunBgkmapd(const std::vector<std::string>& args);

}  // namespace bgkmap::testing
