#pragma once
/// @file
/// Persistent threads for the second share of a refit (identification.h,
/// MaterialIdentificationOptions::post). Before, every upload started a
/// std::async thread for it: a thread start and exit per upload, and every
/// allocation of that share began with the thread's empty allocator cache
/// (perf: malloc's bin search was the daemon's top symbol). Tasks run in
/// the order posted; a task the caller claims first (IdentifyMaterial runs
/// the share itself when it is done before a worker started it) is a no-op
/// here, so a busy pool never delays an upload.
///
/// @code
///   FitWorkers workers(2);
///   MaterialIdentificationOptions o;
///   o.post = [&workers](std::function<void()> f) { workers.Post(std::move(f));
///   };
/// @endcode

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace frictiond {

/// Thread-safe. The destructor runs the tasks still queued, then joins.
class FitWorkers {
 public:
  /// `threads` >= 1 (clamped).
  explicit FitWorkers(int threads);
  ~FitWorkers();
  FitWorkers(const FitWorkers&) = delete;
  FitWorkers& operator=(const FitWorkers&) = delete;

  /// Queues `task`; a worker runs it. A task must not throw (one that does
  /// is dropped with its exception; IdentifyMaterial's task carries its
  /// exception in its own future).
  void Post(std::function<void()> task);

 private:
  void Loop();

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace frictiond
