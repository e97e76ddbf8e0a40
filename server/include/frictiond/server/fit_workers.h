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
/// Work-conserving: a refit splits only while every refit in flight can have
/// two hardware threads (Begin). Splitting costs CPU (the shares' start and
/// hand-over, two threads' caches), which pays while a core is idle and is
/// pure loss when every core already serves an upload: measured in-process
/// with two clients on two materials, 697 uploads/s always splitting vs
/// 764-818 never splitting, while one client alone gains 14-23 % from it.
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
  /// `threads` >= 1 (clamped): the hardware threads refits may use.
  explicit FitWorkers(int threads);
  ~FitWorkers();
  FitWorkers(const FitWorkers&) = delete;
  FitWorkers& operator=(const FitWorkers&) = delete;

  /// Queues `task`; a worker runs it. A task must not throw (one that does
  /// is dropped with its exception; IdentifyMaterial's task carries its
  /// exception in its own future).
  void Post(std::function<void()> task);

  /// One refit in flight, counted while the object lives.
  class Refit {
   public:
    ~Refit();
    Refit(Refit&& other) noexcept;
    Refit(const Refit&) = delete;
    Refit& operator=(const Refit&) = delete;
    Refit& operator=(Refit&&) = delete;
    /// Whether this refit should post its second share: true when, with it,
    /// at most threads/2 refits are in flight (decided at Begin).
    bool split() const { return split_; }

   private:
    friend class FitWorkers;
    Refit(FitWorkers* pool, bool split) : pool_(pool), split_(split) {}
    FitWorkers* pool_;
    bool split_;
  };
  /// Counts a refit until the returned Refit goes.
  Refit Begin();

  /// Like Post for a refit's second share, which its caller runs itself
  /// when no worker has started it (IdentifyMaterial): a worker skips the
  /// task when, by the time it would start it, more refits are in flight
  /// than split (another upload arrived meanwhile).
  void PostShare(std::function<void()> task);

 private:
  void Loop();

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
  /// The one split rule: every refit in flight can have two hardware
  /// threads. Call with load_mu_ held.
  bool SplitFitsLocked() const;
  std::mutex load_mu_;
  int in_flight_ = 0;  // refits between Begin and ~Refit
};

}  // namespace frictiond
