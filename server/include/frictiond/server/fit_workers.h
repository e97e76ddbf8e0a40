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
/// Work-conserving: a refit splits only while every upload in flight can
/// have two hardware threads. An upload counts from the moment it holds its
/// pair until its commit (Begin), not only during its refit: over HTTP a
/// quarter of an upload's time is parse, commit and fsync, and a refit that
/// split because the other upload was committing just then made three
/// threads compete for two cores (the share's hand-over and the caller
/// waiting for it cost more than the share saved). Splitting costs CPU (the
/// shares' start and hand-over, two threads' caches), which pays while a
/// core is idle and is pure loss when every core already serves an upload.
/// Measured (bench/upload, 2 hardware threads, daemon over HTTP; details
/// in docs/ingest.md): counting refits only, two clients on two materials
/// made 734-783 uploads/s (run means); never splitting 875-888, but
/// in-process one client 550 instead of 640-660; counting uploads (this
/// rule) 808-888 (six runs' means) with one client at 548-584, as fast as
/// before.
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

  /// One upload in flight (from its pair lock through its commit, refit
  /// included), counted while the object lives.
  class InFlight {
   public:
    ~InFlight();
    InFlight(InFlight&& other) noexcept;
    InFlight(const InFlight&) = delete;
    InFlight& operator=(const InFlight&) = delete;
    InFlight& operator=(InFlight&&) = delete;
    /// Whether this upload's refit should post its second share now: true
    /// when at most threads/2 uploads are in flight, this one included.
    /// Ask when the refit starts (another upload may have begun meanwhile).
    /// Not on a moved-from InFlight.
    bool split() const;

   private:
    friend class FitWorkers;
    explicit InFlight(FitWorkers* pool) : pool_(pool) {}
    FitWorkers* pool_;
  };
  /// Counts an upload in flight until the returned InFlight goes: take it once
  /// the upload holds its pair (an upload waiting for its pair's lock does
  /// not compete for a core) and keep it through the commit.
  InFlight Begin();

  /// Like Post for a refit's second share, which its caller runs itself
  /// when no worker has started it (IdentifyMaterial): a worker skips the
  /// task when, by the time it would start it, more uploads are in flight
  /// than split (another upload arrived meanwhile).
  void PostShare(std::function<void()> task);

 private:
  void Loop();

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
  /// The one split rule: every upload in flight can have two hardware
  /// threads. Call with load_mu_ held.
  bool SplitFitsLocked() const;
  std::mutex load_mu_;
  int in_flight_ = 0;  // uploads between Begin and ~InFlight
};

}  // namespace frictiond
