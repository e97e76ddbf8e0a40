#include "frictiond/server/fit_workers.h"

#include <algorithm>
#include <utility>

namespace frictiond {

FitWorkers::FitWorkers(int threads) {
  const int n = std::max(1, threads);
  threads_.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) threads_.emplace_back([this] { Loop(); });
}

FitWorkers::~FitWorkers() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void FitWorkers::Post(std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    queue_.push_back(std::move(task));
  }
  cv_.notify_one();
}

void FitWorkers::PostShare(std::function<void()> task) {
  Post([this, task = std::move(task)] {
    {
      std::lock_guard<std::mutex> lock(load_mu_);
      if (!SplitFitsLocked()) return;
    }
    task();
  });
}

FitWorkers::InFlight FitWorkers::Begin() {
  std::lock_guard<std::mutex> lock(load_mu_);
  ++in_flight_;
  return InFlight(this);
}

bool FitWorkers::InFlight::split() const {
  std::lock_guard<std::mutex> lock(pool_->load_mu_);
  return pool_->SplitFitsLocked();
}

bool FitWorkers::SplitFitsLocked() const {
  return 2 * in_flight_ <= static_cast<int>(threads_.size());
}

FitWorkers::InFlight::InFlight(InFlight&& other) noexcept : pool_(other.pool_) {
  other.pool_ = nullptr;
}

FitWorkers::InFlight::~InFlight() {
  if (pool_ == nullptr) return;
  std::lock_guard<std::mutex> lock(pool_->load_mu_);
  --pool_->in_flight_;
}

void FitWorkers::Loop() {
  for (;;) {
    std::function<void()> task;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      task();
    } catch (...) {
      // Dropped: see Post.
    }
  }
}

}  // namespace frictiond
