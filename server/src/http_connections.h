#pragma once
/// @file
/// Connection handling under the HTTP server (internal; includes httplib).
///
/// cpp-httplib 0.11 (Debian 12) gives each accepted connection a worker
/// thread for its whole life and reads the request line and headers with
/// only a per-read timeout, without bounding their total size. A client that
/// dribbles one header byte every few seconds therefore holds a worker for
/// as long as it likes, and a few dozen such clients stop the server.
///
/// GuardedServer replaces httplib's per-connection loop (it overrides
/// Server::process_and_close_socket and calls Server::process_request):
///  - one gate thread reads request headers of every open connection with
///    poll(), up to `max_header_bytes`, within `header_timeout_ms` (408 or
///    431 otherwise); idle keep-alive connections also wait there, not on a
///    worker;
///  - only a connection whose headers are complete is queued for a worker;
///    the queue holds at most `max_queue` connections and at most
///    `max_connections` are open; beyond either the client gets 503 at once;
///  - a worker serves one request on a ConnectionStream whose reads stop at
///    the whole-request deadline (`request_timeout_ms` from the first byte)
///    and, once the worker has waited `min_rate_grace_ms` for it, when the
///    body arrives slower than `min_body_bytes_per_s` on average (a client
///    that dribbled a 5,000-byte body one byte per 5 s held a worker for 70 s
///    in an outside attack run; now about the grace);
///  - the answer is collected (up to kWriteBufferBytes) and sent with one
///    send() when the request is done (or before the stream next reads from
///    the socket, e.g. after "100 Continue"): httplib writes the status
///    line and headers and the body separately, and with TCP_NODELAY each
///    write was a segment of its own that woke the client twice per answer.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

namespace frictiond::internal {

using SteadyClock = std::chrono::steady_clock;

/// Limits of GuardedServer (see HttpOptions for their meaning).
struct ConnectionLimits {
  int threads = 8;
  int max_connections = 256;
  int max_queue = 64;
  std::size_t max_header_bytes = 32u << 10;
  int header_timeout_ms = 10000;
  int request_timeout_ms = 60000;
  int read_timeout_ms = 10000;
  int write_timeout_ms = 10000;
  int keep_alive_timeout_ms = 5000;
  int keep_alive_max_count = 100000;
  /// A body must arrive at least this fast on average, counted from when a
  /// worker took the request, after a grace of `min_rate_grace_ms`: 16 KiB/s
  /// moves the 16 MB body limit in about 17 minutes and any ordinary body
  /// within the grace.
  double min_body_bytes_per_s = 16384;
  int min_rate_grace_ms = 2000;
};

/// The addresses of a connection's two ends, looked up once per connection
/// (httplib asks for them on every request).
struct ConnectionAddresses {
  bool known = false;
  std::string remote_ip, local_ip;
  int remote_port = 0, local_port = 0;
};

/// One request's view of a connection: first the bytes the gate already
/// read, then the socket, with reads bounded by the request deadline.
class ConnectionStream : public httplib::Stream {
 public:
  /// `addresses` (may be null: looked up on each call) caches the
  /// connection's addresses across its requests; it must outlive the
  /// stream.
  ConnectionStream(int fd,
                   std::string buffered,
                   SteadyClock::time_point deadline,
                   const ConnectionLimits& limits,
                   ConnectionAddresses* addresses = nullptr);

  bool is_readable() const override;
  bool is_writable() const override;
  ssize_t read(char* ptr, size_t size) override;
  ssize_t write(const char* ptr, size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override;
  void get_local_ip_and_port(std::string& ip, int& port) const override;
  socket_t socket() const override { return fd_; }

  /// Bytes read from the socket but not consumed (a pipelined request).
  std::string TakeLeftover();
  /// A read waited the read timeout without data, or the whole-request
  /// deadline passed: no more reads; an answer (408) can still be written.
  bool timed_out() const { return timed_out_; }
  /// A read or write failed: the connection is unusable.
  bool failed() const { return failed_; }
  /// Close the connection after this response (unread body bytes remain).
  void CloseAfterResponse() { close_after_ = true; }
  bool close_after() const { return close_after_; }

  /// Sends what write() collected. False when the connection failed.
  bool Flush();

  /// The stream of the request being served on this thread, or null.
  static ConnectionStream* Current();

  /// Answers up to this size are sent in one piece; a larger write goes
  /// out at once, after what was collected before it.
  static constexpr std::size_t kWriteBufferBytes = 64u << 10;

 private:
  friend class CurrentStreamScope;
  bool SendAll(const char* ptr, std::size_t size);
  const ConnectionAddresses& Addresses() const;
  int fd_;
  ConnectionAddresses* addresses_;
  mutable ConnectionAddresses own_addresses_;
  std::string buf_;
  std::size_t pos_ = 0;
  std::string out_;  ///< written, not yet sent
  SteadyClock::time_point deadline_;
  ConnectionLimits limits_;
  SteadyClock::time_point started_;  ///< when the worker took the request
  std::size_t received_ = 0;         ///< bytes read from the socket since
  /// Milliseconds the next wait may take before the minimum body rate
  /// (ConnectionLimits::min_body_bytes_per_s) is missed; <= 0: missed.
  int MillisUntilTooSlow() const;
  bool timed_out_ = false;
  bool failed_ = false;
  bool close_after_ = false;
};

/// httplib::Server with the connection handling described in the file
/// comment. Call StartWorkers() before listen_after_bind() and
/// StopWorkers() after stop().
class GuardedServer : public httplib::Server {
 public:
  explicit GuardedServer(const ConnectionLimits& limits);
  ~GuardedServer() override;
  GuardedServer(const GuardedServer&) = delete;
  GuardedServer& operator=(const GuardedServer&) = delete;

  void StartWorkers();
  /// Closes every connection and joins the gate and workers (idempotent).
  void StopWorkers();

  /// Connections refused with 503 (too many open or queued), answered 408
  /// (deadline) and 431 (headers too large), since start.
  std::size_t refused_busy() const { return refused_busy_; }
  std::size_t timed_out() const { return timed_out_; }

 private:
  struct Conn {
    int fd = -1;
    std::string buf;
    bool idle = true;  ///< no byte of the next request yet
    SteadyClock::time_point started;
    SteadyClock::time_point deadline;
    int served = 0;
    ConnectionAddresses addresses;
    /// Answered and shut for writing: the gate reads and drops what the
    /// client still sends until it closes or `deadline` (lingering close).
    bool draining = false;
    std::size_t drained = 0;
  };

  bool process_and_close_socket(socket_t sock) override;
  void GateLoop();
  void WorkerLoop();
  void ServeOne(Conn conn);
  void Enqueue(Conn conn);
  void ReturnToGate(Conn conn);
  void CloseConn(int fd);
  void Wake();

  ConnectionLimits limits_;
  std::atomic<bool> stopping_{false};
  std::atomic<bool> started_{false};  ///< gate and workers running
  std::atomic<int> open_{0};
  std::atomic<std::size_t> refused_busy_{0};
  std::atomic<std::size_t> timed_out_{0};
  int wake_fd_ = -1;
  std::thread gate_;
  std::vector<std::thread> workers_;

  std::mutex gate_mu_;
  std::vector<Conn> gate_incoming_;  ///< new and kept-alive connections

  std::mutex queue_mu_;
  std::condition_variable queue_cv_;
  std::deque<Conn> queue_;     ///< headers complete, waiting for a worker
  std::set<int> serving_fds_;  ///< on a worker now (shut down on stop)
};

}  // namespace frictiond::internal
