#pragma once
/// @file
/// Bounds one HTTP exchange of the client as a whole, from another thread:
/// its time (deadline_s, headers included) and the bytes read before the
/// reply body begins (the status line and headers).
///
/// Why: httplib 0.11 reads a reply's headers with no bound on their number,
/// nor on a line's length before its end arrives, and its read timeout
/// holds per read. A hostile server answering at base_url could make the
/// client grow without bound (endless header lines, or one line without
/// end) or wait for ever (one header byte per read timeout). The body's
/// size is bounded where it is received (client.cc, content receiver); its
/// time, like the headers', here: the one place deadline_s is enforced.
///
/// How: while an exchange is in flight, a thread of its own samples the
/// socket every `poll` (bytes read = TCP_INFO bytes received minus the
/// bytes still queued) and calls `stop` (httplib::Client::stop, which may be
/// called from another thread and ends the request in flight) when the
/// deadline has passed or, before the body began, more than
/// max_header_bytes were read. Memory is then bounded by max_header_bytes
/// plus what one poll period lets arrive. Begin and End only set state (no
/// context switch per exchange); the thread polls while exchanges come and
/// sleeps once none has been in flight for a second.
///
/// Not covered: trailer lines after a chunked body (httplib reads and
/// drops them); the deadline bounds them in time only.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace frictiond::internal {

class ExchangeWatchdog {
 public:
  using Clock = std::chrono::steady_clock;

  /// `stop` ends the exchange in flight (called from the watchdog's thread);
  /// at most `max_header_bytes` may be read before a reply's body begins.
  ExchangeWatchdog(
      std::function<void()> stop,
      std::uint64_t max_header_bytes,
      std::chrono::milliseconds poll = std::chrono::milliseconds(5));
  ~ExchangeWatchdog();
  ExchangeWatchdog(const ExchangeWatchdog&) = delete;
  ExchangeWatchdog& operator=(const ExchangeWatchdog&) = delete;

  /// An exchange begins. `socket` is the connection it will use when one is
  /// open already (kept alive), else -1 (OnSocket gives the new one).
  void Begin(Clock::time_point deadline, int socket);
  /// A connection was opened (httplib's socket options hook).
  void OnSocket(int socket);
  /// The reply body began (its first piece was received).
  void OnBody();
  /// The exchange ended: the limit that stopped it, or "" when none did.
  std::string End();

  /// Bytes the process has read from `socket` so far; 0 when unknown.
  static std::uint64_t BytesRead(int socket);

 private:
  void Loop();

  std::function<void()> stop_;
  const std::uint64_t max_header_bytes_;
  std::chrono::milliseconds poll_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool active_ = false;
  bool body_ = false;
  bool quit_ = false;
  bool stopping_ = false;  // stop_ under way (End waits for it)
  bool parked_ = false;    // the thread sleeps until the next Begin
  Clock::time_point last_active_;
  /// Idle this long, the thread stops polling until the next Begin.
  static constexpr std::chrono::seconds kParkAfter{1};
  int socket_ = -1;
  std::uint64_t base_ = 0;  // BytesRead(socket_) when watching began
  Clock::time_point deadline_;
  std::string fired_;
  std::thread thread_;  // started by the first Begin
};

}  // namespace frictiond::internal
