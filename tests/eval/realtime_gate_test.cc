#include "bgkmap/eval/realtime_gate.h"

#include <gtest/gtest.h>

#include <vector>

namespace bgkmap::eval {
namespace {

TEST(RealtimeGateTest, FastScansAreAllKept) {
  const std::vector<ScanTiming> t(20, {0.03, 0.05});
  const std::vector<bool> admitted = AdmitScans(t, 0.1);
  // One verdict per scan: the loop below would pass on an empty answer. Mutation checked:
  // AdmitScans returning {} for these timings failed only once this size check was added.
  ASSERT_EQ(admitted.size(), t.size());
  for (bool a : admitted) EXPECT_TRUE(a);
}

TEST(RealtimeGateTest, ASlowElevationStepDropsTheScansArrivingMeanwhile) {
  // Scan 0 keeps process 1 busy for 0.25 s: scans 1 (0.1 s) and 2 (0.2 s) arrive while it is busy.
  std::vector<ScanTiming> t(5, {0.01, 0.01});
  t[0].process1 = 0.25;
  EXPECT_EQ(AdmitScans(t, 0.1), (std::vector<bool>{true, false, false, true, true}));
}

TEST(RealtimeGateTest, ASlowTraversabilityStepDropsAtTheHandover) {
  // Process 2 is busy until 0.01 + 0.35 s; scans 1-3 reach it before then and are dropped.
  std::vector<ScanTiming> t(6, {0.01, 0.01});
  t[0].process2 = 0.35;
  EXPECT_EQ(AdmitScans(t, 0.1), (std::vector<bool>{true, false, false, false, true, true}));
}

TEST(RealtimeGateTest, TwoProcessesPipelineScansThatEachFitThePeriod) {
  // 0.09 s in each process: 0.18 s per scan in total, yet the pipeline keeps up at 10 Hz.
  const std::vector<ScanTiming> t(10, {0.09, 0.09});
  const std::vector<bool> admitted = AdmitScans(t, 0.1);
  ASSERT_EQ(admitted.size(), t.size());
  for (bool a : admitted) EXPECT_TRUE(a);
}

TEST(RealtimeGateTest, ConstantOverloadKeepsEveryOtherScan) {
  const std::vector<ScanTiming> t(6, {0.15, 0.01});
  EXPECT_EQ(AdmitScans(t, 0.1), (std::vector<bool>{true, false, true, false, true, false}));
}

}  // namespace
}  // namespace bgkmap::eval
