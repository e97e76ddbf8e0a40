#include "frictiond/server/fit_workers.h"

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
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

}  // namespace
}  // namespace frictiond
