#include "frictiond/server/fit_workers.h"

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

// Every posted task runs once, in posting order on one worker; a throwing
// task does not stop the worker; the destructor runs what is still queued.
TEST(FitWorkers, RunsEveryTaskInOrderAndSurvivesAThrow) {
  std::vector<int> order;
  std::mutex mu;
  {
    FitWorkers one(1);
    one.Post([] { throw std::runtime_error("dropped"); });
    for (int i = 0; i < 100; ++i) {
      one.Post([&order, &mu, i] {
        std::lock_guard<std::mutex> lock(mu);
        order.push_back(i);
      });
    }
  }  // joins after the queue is empty
  ASSERT_EQ(order.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(order[i], i);
}

// Tasks run on the workers at once: two tasks that each wait for the other
// finish only when two threads serve them.
TEST(FitWorkers, TwoWorkersRunTwoTasksAtOnce) {
  FitWorkers two(2);
  std::promise<void> a_started, b_started;
  std::shared_future<void> a = a_started.get_future().share();
  std::shared_future<void> b = b_started.get_future().share();
  std::promise<void> a_done, b_done;
  two.Post([&] {
    a_started.set_value();
    b.wait();
    a_done.set_value();
  });
  two.Post([&] {
    b_started.set_value();
    a.wait();
    b_done.set_value();
  });
  EXPECT_EQ(a_done.get_future().wait_for(std::chrono::seconds(10)),
            std::future_status::ready);
  EXPECT_EQ(b_done.get_future().wait_for(std::chrono::seconds(10)),
            std::future_status::ready);
}

// Work-conserving: with two hardware threads an upload alone splits its
// refit; while a second upload is in flight neither does (the answer is
// the state when asked, not when the upload began); when one is gone, the
// other splits again.
TEST(FitWorkers, SplitsOnlyWhileEveryUploadCanHaveTwoThreads) {
  FitWorkers two(2);
  {
    const FitWorkers::InFlight a = two.Begin();
    EXPECT_TRUE(a.split());
    {
      const FitWorkers::InFlight b = two.Begin();
      EXPECT_FALSE(b.split());
      EXPECT_FALSE(a.split());  // b arrived: a refit starting now stays whole
    }
    EXPECT_TRUE(a.split());
  }
  EXPECT_TRUE(two.Begin().split());
  FitWorkers four(4);
  const FitWorkers::InFlight a = four.Begin();
  const FitWorkers::InFlight b = four.Begin();
  EXPECT_TRUE(a.split());
  EXPECT_TRUE(b.split());
  {
    const FitWorkers::InFlight c = four.Begin();
    EXPECT_FALSE(a.split());
    EXPECT_FALSE(c.split());
  }
  EXPECT_TRUE(b.split());
  FitWorkers moved_from(2);
  {
    FitWorkers::InFlight first = moved_from.Begin();
    const FitWorkers::InFlight second(std::move(first));  // still one upload
    EXPECT_TRUE(second.split());
  }
  FitWorkers one(1);
  EXPECT_FALSE(one.Begin().split());
}

// A posted share runs while the pool is idle, and is skipped (left to its
// caller) when more uploads are in flight than split by the time a worker
// reaches it.
TEST(FitWorkers, PostedShareIsSkippedWhenTheMachineBecameBusy) {
  for (bool busy : {false, true}) {
    SCOPED_TRACE(busy ? "a second refit began" : "alone");
    FitWorkers two(2);
    std::promise<void> open_a, open_b, reached;
    std::shared_future<void> gate_a = open_a.get_future().share();
    std::shared_future<void> gate_b = open_b.get_future().share();
    two.Post([gate_a] { gate_a.wait(); });  // one worker each
    two.Post([gate_b] { gate_b.wait(); });
    const FitWorkers::InFlight mine = two.Begin();
    ASSERT_TRUE(mine.split());
    std::atomic<int> ran{0};
    two.PostShare([&ran] { ++ran; });
    two.Post([&reached] { reached.set_value(); });
    std::optional<FitWorkers::InFlight> other;
    if (busy) other.emplace(two.Begin());
    open_a.set_value();  // one worker runs the share, then the marker
    reached.get_future().wait();
    EXPECT_EQ(ran.load(), busy ? 0 : 1);
    open_b.set_value();
  }
}

}  // namespace
}  // namespace frictiond
