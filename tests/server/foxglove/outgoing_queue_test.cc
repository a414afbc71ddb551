// A Foxglove session's outgoing queue (foxglove/outgoing_queue.h): a newer grid replaces only a
// waiting grid of its own subscription, never a transform, cloud or status, whatever ids the
// client picked (Foxglove's client numbers its subscriptions from 0); frames go out in order;
// the bound counts the bytes waiting behind the one being written.
#include "foxglove/outgoing_queue.h"

#include <gtest/gtest.h>

#include <vector>

namespace bgkmap::foxglove {
namespace {

OutgoingQueue::Frame Frame(const std::string& text, std::optional<uint32_t> grid = std::nullopt) {
  return {std::make_shared<const std::string>(text), true, grid};
}

// Writes out everything queued; returns the frames' bytes in order.
std::vector<std::string> Drain(OutgoingQueue& q) {
  std::vector<std::string> out;
  while (const OutgoingQueue::Frame* f = q.StartWrite()) {
    out.push_back(*f->bytes);
    q.FinishWrite();
  }
  return out;
}

TEST(OutgoingQueueTest, AGridReplacesOnlyAWaitingGridOfItsSubscriptionEvenForId0) {
  OutgoingQueue q(1 << 20);
  ASSERT_TRUE(q.Add(Frame("grid 1", 0)));
  ASSERT_NE(q.StartWrite(), nullptr);  // being written: never replaced
  ASSERT_TRUE(q.Add(Frame("tf b")));
  ASSERT_TRUE(q.Add(Frame("cloud b")));
  ASSERT_TRUE(q.Add(Frame("grid 2", 0)));
  ASSERT_TRUE(q.Add(Frame("grid of subscription 1", 1)));
  ASSERT_TRUE(q.Add(Frame("grid 3", 0)));  // replaces grid 2, waiting
  q.FinishWrite();
  EXPECT_EQ(Drain(q),
            (std::vector<std::string>{"tf b", "cloud b", "grid 3", "grid of subscription 1"}));
  EXPECT_EQ(q.queued_bytes(), 0u);
}

TEST(OutgoingQueueTest, TheBoundCountsTheBytesWaitingBehindTheOneBeingWritten) {
  OutgoingQueue q(10);
  ASSERT_TRUE(q.Add(Frame(std::string(100, 'g'), 0)));  // alone: always taken
  ASSERT_NE(q.StartWrite(), nullptr);
  EXPECT_TRUE(q.Add(Frame("12345")));
  EXPECT_TRUE(q.Add(Frame("67890")));
  EXPECT_FALSE(q.Add(Frame("x"))) << "11 bytes would wait behind the one being written";
  EXPECT_FALSE(q.Add(Frame(std::string(8, 'g'), 0))) << "a grid with none waiting adds bytes";
  EXPECT_EQ(q.queued_bytes(), 110u);
  q.FinishWrite();  // the 100 bytes went out: 10 wait
  EXPECT_FALSE(q.Add(Frame("x")));
  EXPECT_NE(q.StartWrite(), nullptr);  // "12345" being written: 5 wait
  EXPECT_TRUE(q.Add(Frame("abcde")));
}

TEST(OutgoingQueueTest, OneWriteAtATime) {
  OutgoingQueue q(1 << 20);
  EXPECT_EQ(q.StartWrite(), nullptr);
  ASSERT_TRUE(q.Add(Frame("a")));
  ASSERT_TRUE(q.Add(Frame("b")));
  const OutgoingQueue::Frame* first = q.StartWrite();
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(*first->bytes, "a");
  EXPECT_EQ(q.StartWrite(), nullptr) << "a's write has not finished";
  q.FinishWrite();
  EXPECT_EQ(Drain(q), std::vector<std::string>{"b"});
}

}  // namespace
}  // namespace bgkmap::foxglove
