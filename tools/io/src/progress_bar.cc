#include "bgkmap/io/progress_bar.h"

#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace bgkmap::io {
namespace {

constexpr int kBarWidth = 30;
constexpr auto kRedrawInterval = std::chrono::milliseconds(100);
std::atomic<bool> silenced{false};

}  // namespace

ProgressBar::ProgressBar(std::string label, uint64_t total, std::string unit, std::FILE* out)
    : label_(std::move(label)),
      unit_(std::move(unit)),
      total_(total),
      out_(silenced ? nullptr : out),
      tty_(out_ != nullptr && isatty(fileno(out_))),
      start_(Clock::now()),
      last_draw_(start_ - kRedrawInterval) {}

ProgressBar::~ProgressBar() { Finish(); }

void ProgressBar::SilenceAll() { silenced = true; }

void ProgressBar::Add(uint64_t n) {
  std::lock_guard lock(mu_);
  done_ += n;
  Report(false);
}

void ProgressBar::Set(uint64_t done) {
  std::lock_guard lock(mu_);
  done_ = done;
  Report(false);
}

void ProgressBar::Finish() {
  std::lock_guard lock(mu_);
  if (finished_) return;
  Report(true);
  finished_ = true;
}

std::string ProgressBar::FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const auto s = static_cast<uint64_t>(std::llround(seconds));
  if (s >= 3600) return fmt::format("{}:{:02d}:{:02d}", s / 3600, s / 60 % 60, s % 60);
  return fmt::format("{:02d}:{:02d}", s / 60, s % 60);
}

std::string ProgressBar::Line(double elapsed) const {
  const double rate = elapsed > 0 ? done_ / elapsed : 0.0;
  std::string line = label_ + " ";
  if (total_ > 0) {
    const double frac = std::min(1.0, static_cast<double>(done_) / total_);
    if (tty_) {
      const int filled = static_cast<int>(frac * kBarWidth);
      line += fmt::format("[{:#<{}}{: <{}}] ", "", filled, "", kBarWidth - filled);
    }
    line += fmt::format("{:3.0f}% {}/{} {}", 100 * frac, done_, total_, unit_);
  } else {
    line += fmt::format("{} {}", done_, unit_);
  }
  line += fmt::format(", {:.1f} {}/s", rate, unit_);
  if (total_ > 0 && done_ < total_) {
    const double eta = rate > 0 ? (total_ - done_) / rate : -1.0;
    line += ", ETA " + FormatDuration(eta);
  } else {
    line += ", " + FormatDuration(elapsed);
  }
  return line;
}

void ProgressBar::Report(bool final) {
  if (out_ == nullptr || finished_) return;
  const Clock::time_point now = Clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  if (tty_) {
    if (!final && now - last_draw_ < kRedrawInterval) return;
    last_draw_ = now;
    // \x1b[K clears what a longer previous line left behind.
    std::fprintf(out_, "\r%s\x1b[K%s", Line(elapsed).c_str(), final ? "\n" : "");
  } else {
    const int decile =
        total_ > 0 ? static_cast<int>(std::min<uint64_t>(10, done_ * 10 / total_)) : 0;
    if (final) {
      std::fprintf(out_, "%s\n", Line(elapsed).c_str());
    } else if (decile > last_decile_ && decile < 10) {  // 100% is left to the final line
      last_decile_ = decile;
      std::fprintf(out_, "%s\n", Line(elapsed).c_str());
    }
  }
  std::fflush(out_);
}

}  // namespace bgkmap::io
