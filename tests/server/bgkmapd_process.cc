#include "bgkmapd_process.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <regex>
#include <thread>

namespace bgkmap::testing {
namespace {

std::vector<char*> Argv(std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  return argv;
}

int DecodeStatus(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

}  // namespace

BgkmapdProcess::BgkmapdProcess(const std::vector<std::string>& extra) {
  std::vector<std::string> args = {BGKMAPD_PATH, "--listen", "127.0.0.1:0"};
  args.insert(args.end(), extra.begin(), extra.end());
  Spawn(std::move(args), "event=listening .*port=([0-9]+)", /*with_stdout=*/false);
}

BgkmapdProcess::BgkmapdProcess(std::vector<std::string> argv, const std::string& ready) {
  Spawn(std::move(argv), ready, /*with_stdout=*/true);
}

void BgkmapdProcess::Spawn(std::vector<std::string> args, const std::string& ready,
                           bool with_stdout) {
  int fds[2];
  if (pipe(fds) != 0) return;
  pid_ = fork();
  if (pid_ == 0) {
    dup2(fds[1], STDERR_FILENO);
    if (with_stdout) dup2(fds[1], STDOUT_FILENO);
    close(fds[0]);
    close(fds[1]);
    std::vector<char*> argv = Argv(args);
    execv(argv[0], argv.data());
    _exit(127);
  }
  close(fds[1]);
  reader_ = std::thread([this, fd = fds[0]] { ReadLog(fd); });
  std::unique_lock lock(mu_);
  const std::regex ready_line(ready);
  cv_.wait_for(lock, std::chrono::seconds(30), [&] {
    for (const std::string& l : lines_) {
      std::smatch m;
      if (std::regex_search(l, m, ready_line)) {
        port_ = m.size() > 1 ? std::stoi(m[1]) : 1;
        return true;
      }
    }
    return eof_;
  });
}

BgkmapdProcess::~BgkmapdProcess() {
  if (pid_ > 0 && exit_code_ < 0) {
    kill(pid_, SIGKILL);
    int status = 0;
    waitpid(pid_, &status, 0);
  }
  if (reader_.joinable()) reader_.join();
}

void BgkmapdProcess::ReadLog(int fd) {
  FILE* f = fdopen(fd, "r");
  char buf[4096];
  while (f != nullptr && fgets(buf, sizeof buf, f) != nullptr) {
    std::lock_guard lock(mu_);
    std::string line(buf);
    if (!line.empty() && line.back() == '\n') line.pop_back();
    lines_.push_back(line);
    cv_.notify_all();
  }
  if (f != nullptr) fclose(f);
  std::lock_guard lock(mu_);
  eof_ = true;
  cv_.notify_all();
}

void BgkmapdProcess::Signal(int signal) {
  if (pid_ > 0) kill(pid_, signal);
}

int BgkmapdProcess::Wait(int timeout_s) {
  if (exit_code_ >= 0) return exit_code_;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = DecodeStatus(status);
      if (reader_.joinable()) reader_.join();
      return exit_code_;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return -1;
}

int BgkmapdProcess::Poll() {
  if (exit_code_ >= 0 || pid_ <= 0) return exit_code_;
  int status = 0;
  if (waitpid(pid_, &status, WNOHANG) == pid_) {
    exit_code_ = DecodeStatus(status);
    if (reader_.joinable()) reader_.join();
  }
  return exit_code_;
}

std::vector<std::string> BgkmapdProcess::Log() {
  std::lock_guard lock(mu_);
  return lines_;
}

std::string BgkmapdProcess::FindLine(const std::string& needle) {
  std::lock_guard lock(mu_);
  for (const std::string& l : lines_) {
    if (l.find(needle) != std::string::npos) return l;
  }
  return "";
}

std::string BgkmapdProcess::WaitForLine(const std::string& needle, double seconds) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  for (;;) {
    std::string line = FindLine(needle);
    if (!line.empty() || std::chrono::steady_clock::now() > until) return line;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

std::pair<int, std::string> RunBgkmapd(const std::vector<std::string>& extra) {
  std::vector<std::string> args = {BGKMAPD_PATH};
  args.insert(args.end(), extra.begin(), extra.end());
  int fds[2];
  if (pipe(fds) != 0) return {-1, ""};
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[1], STDOUT_FILENO);
    close(fds[0]);
    close(fds[1]);
    std::vector<char*> argv = Argv(args);
    execv(argv[0], argv.data());
    _exit(127);
  }
  close(fds[1]);
  std::string out;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) out.append(buf, static_cast<size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return {DecodeStatus(status), out};
}

}  // namespace bgkmap::testing
