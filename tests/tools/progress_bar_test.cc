#include "bgkmap/io/progress_bar.h"

#include <gtest/gtest.h>
#include <pty.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>
#include <thread>
#include <vector>

namespace bgkmap::io {
namespace {

std::string Contents(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string out;
  for (int c; (c = std::fgetc(f)) != EOF;) out += static_cast<char>(c);
  return out;
}

std::vector<std::string> Lines(const std::string& s) {
  std::vector<std::string> lines;
  size_t start = 0;
  for (size_t nl; (nl = s.find('\n', start)) != std::string::npos; start = nl + 1) {
    lines.push_back(s.substr(start, nl - start));
  }
  return lines;
}

TEST(ProgressBarTest, NonTerminalPrintsAboutEveryTenPercent) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressBar bar("scans", 1000, "scans", f);
    for (int i = 0; i < 1000; ++i) bar.Add();
  }  // the destructor prints the final line
  const std::vector<std::string> lines = Lines(Contents(f));
  std::fclose(f);
  ASSERT_EQ(lines.size(), 10u);  // 10%, ..., 90%, then the final 100% line
  EXPECT_NE(lines[0].find(" 10% 100/1000 scans"), std::string::npos) << lines[0];
  EXPECT_NE(lines[0].find("ETA "), std::string::npos) << lines[0];
  EXPECT_NE(lines[9].find("100% 1000/1000 scans"), std::string::npos) << lines[9];
  EXPECT_NE(lines[9].find("scans/s"), std::string::npos) << lines[9];
  for (const auto& line : lines) EXPECT_EQ(line.find('\r'), std::string::npos);
}

TEST(ProgressBarTest, FinishIsIdempotentAndUnknownTotalWorks) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressBar bar("points", 0, "points", f);
    bar.Set(12345);
    bar.Finish();
    bar.Finish();
  }
  const std::vector<std::string> lines = Lines(Contents(f));
  std::fclose(f);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].rfind("points 12345 points, ", 0), 0u) << lines[0];
}

TEST(ProgressBarTest, ConcurrentAddsAreCounted) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressBar bar("work", 4000, "items", f);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t) {
      threads.emplace_back([&] {
        for (int i = 0; i < 1000; ++i) bar.Add();
      });
    }
    for (auto& th : threads) th.join();
  }
  const std::vector<std::string> lines = Lines(Contents(f));
  std::fclose(f);
  ASSERT_FALSE(lines.empty());
  EXPECT_NE(lines.back().find("4000/4000"), std::string::npos) << lines.back();
}

TEST(ProgressBarTest, TerminalRedrawsOneLineWithABar) {
  int master = -1, slave = -1;
  if (openpty(&master, &slave, nullptr, nullptr, nullptr) != 0)
    GTEST_SKIP() << "no pseudo-terminal";
  std::FILE* tty = fdopen(slave, "w");
  ASSERT_NE(tty, nullptr);
  {
    ProgressBar bar("ingest", 4, "scans", tty);
    bar.Add(2);
    bar.Add(2);
  }
  std::fclose(tty);
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = read(master, buf, sizeof(buf))) > 0;) out.append(buf, n);
  close(master);
  EXPECT_EQ(out.rfind("\r", 0), 0u) << out;  // redraws start at the line's beginning
  EXPECT_NE(out.find("ingest [###############               ]  50% 2/4 scans"), std::string::npos)
      << out;
  EXPECT_NE(out.find("[##############################] 100% 4/4 scans"), std::string::npos) << out;
  EXPECT_NE(out.find("\x1b[K"), std::string::npos);
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;  // one line, ended by Finish
}

TEST(ProgressBarTest, FormatsDurations) {
  EXPECT_EQ(ProgressBar::FormatDuration(0), "00:00");
  EXPECT_EQ(ProgressBar::FormatDuration(62.4), "01:02");
  EXPECT_EQ(ProgressBar::FormatDuration(3723), "1:02:03");
  EXPECT_EQ(ProgressBar::FormatDuration(-1), "--:--");
  EXPECT_EQ(ProgressBar::FormatDuration(std::numeric_limits<double>::infinity()), "--:--");
}

}  // namespace
}  // namespace bgkmap::io
