#include "http_connections.h"

#include <algorithm>
#include <cerrno>
#include <cstring>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

namespace frictiond::internal {

namespace {

thread_local ConnectionStream* g_current_stream = nullptr;

int MillisUntil(SteadyClock::time_point t) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                      t - SteadyClock::now())
                      .count();
  return static_cast<int>(std::clamp<long long>(ms, 0, 1 << 30));
}

// Waits until fd is ready for `events` for at most timeout_ms.
bool WaitFor(int fd, short events, int timeout_ms) {
  pollfd p{fd, events, 0};
  for (;;) {
    const int r = ::poll(&p, 1, timeout_ms);
    if (r < 0 && errno == EINTR) continue;
    return r > 0 && (p.revents & (events | POLLHUP | POLLERR)) != 0;
  }
}

// A complete JSON error answer written without a worker (the socket is
// non-blocking; the answer fits any socket buffer). Best effort.
void WriteQuickAnswer(int fd, int status, const char* title, const char* why) {
  const std::string body =
      std::string("{\"error\":\"") + title + "\",\"detail\":\"" + why + "\"}";
  const char* reason = status == 503   ? "Service Unavailable"
                       : status == 408 ? "Request Timeout"
                                       : "Request Header Fields Too Large";
  const std::string text = "HTTP/1.1 " + std::to_string(status) + " " + reason +
                           "\r\nContent-Type: application/json\r\n"
                           "Connection: close\r\nContent-Length: " +
                           std::to_string(body.size()) + "\r\n\r\n" + body;
  (void)::send(fd, text.data(), text.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

bool HeadersComplete(const std::string& buf) {
  return buf.find("\r\n\r\n") != std::string::npos;
}

// A request line before its headers may be preceded by empty lines
// (RFC 9112 2.2); httplib does not skip them, so neither do we: such bytes
// simply reach httplib, which answers 400.

void PeerName(int fd, bool local, std::string& ip, int& port) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  const int r =
      local ? ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len)
            : ::getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ip.clear();
  port = 0;
  if (r != 0) return;
  char text[INET6_ADDRSTRLEN] = {0};
  if (addr.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&addr);
    ::inet_ntop(AF_INET, &a->sin_addr, text, sizeof text);
    port = ntohs(a->sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&addr);
    ::inet_ntop(AF_INET6, &a->sin6_addr, text, sizeof text);
    port = ntohs(a->sin6_port);
  }
  ip = text;
}

// Runs every task on the calling (accepting) thread: GuardedServer's
// process_and_close_socket only hands the socket to the gate.
class InlineQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

}  // namespace

ConnectionStream::ConnectionStream(int fd,
                                   std::string buffered,
                                   SteadyClock::time_point deadline,
                                   const ConnectionLimits& limits,
                                   ConnectionAddresses* addresses)
    : fd_(fd),
      addresses_(addresses),
      buf_(std::move(buffered)),
      deadline_(deadline),
      limits_(limits),
      started_(SteadyClock::now()) {}

int ConnectionStream::MillisUntilTooSlow() const {
  // The rule holds while received_ >= rate * elapsed (after the grace): it
  // fails at elapsed = max(grace, received_ / rate).
  const double rate = limits_.min_body_bytes_per_s;
  if (!(rate > 0)) return limits_.read_timeout_ms;
  const double fail_ms =
      std::max(static_cast<double>(limits_.min_rate_grace_ms),
               1e3 * static_cast<double>(received_) / rate);
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(SteadyClock::now() - started_)
          .count();
  return static_cast<int>(std::min(
      fail_ms - elapsed_ms, static_cast<double>(limits_.read_timeout_ms)));
}

ConnectionStream* ConnectionStream::Current() { return g_current_stream; }

bool ConnectionStream::is_readable() const {
  if (pos_ < buf_.size()) return true;
  return WaitFor(fd_,
                 POLLIN,
                 std::max(0,
                          std::min({limits_.read_timeout_ms,
                                    MillisUntil(deadline_),
                                    MillisUntilTooSlow()})));
}

bool ConnectionStream::is_writable() const {
  return WaitFor(fd_, POLLOUT, limits_.write_timeout_ms);
}

ssize_t ConnectionStream::read(char* ptr, size_t size) {
  // The client may wait for what was written (100 Continue) before it
  // sends more.
  if (pos_ >= buf_.size() && !out_.empty() && !Flush()) return -1;
  while (pos_ >= buf_.size()) {
    buf_.clear();
    pos_ = 0;
    if (failed_ || timed_out_) return -1;
    const int wait_ms = std::min({limits_.read_timeout_ms,
                                  MillisUntil(deadline_),
                                  MillisUntilTooSlow()});
    if (SteadyClock::now() >= deadline_ || wait_ms <= 0 ||
        !WaitFor(fd_, POLLIN, wait_ms)) {
      // The client sent nothing for the read timeout, the request deadline
      // passed, or the body comes slower than the minimum rate: no more
      // reads, but the socket still carries the answer (408). Until stop 22
      // this set failed_, so the 408 was never written and the client saw
      // the connection close.
      timed_out_ = true;
      return -1;
    }
    char chunk[8192];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK))
      continue;
    if (n <= 0) {
      if (n < 0) failed_ = true;
      return n;
    }
    buf_.assign(chunk, static_cast<std::size_t>(n));
    received_ += static_cast<std::size_t>(n);
  }
  const std::size_t n = std::min(size, buf_.size() - pos_);
  std::memcpy(ptr, buf_.data() + pos_, n);
  pos_ += n;
  return static_cast<ssize_t>(n);
}

ssize_t ConnectionStream::write(const char* ptr, size_t size) {
  if (failed_) return -1;
  if (out_.size() + size > kWriteBufferBytes) {
    // A large answer: what is pending, then this piece straight from the
    // caller's buffer (no copy).
    if (!Flush()) return -1;
    if (size >= kWriteBufferBytes)
      return SendAll(ptr, size) ? static_cast<ssize_t>(size) : -1;
  }
  out_.append(ptr, size);
  return static_cast<ssize_t>(size);
}

bool ConnectionStream::Flush() {
  const bool ok = SendAll(out_.data(), out_.size());
  out_.clear();
  return ok;
}

bool ConnectionStream::SendAll(const char* ptr, std::size_t size) {
  std::size_t sent = 0;
  while (sent < size && !failed_) {
    const ssize_t n =
        ::send(fd_, ptr + sent, size - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      if (!WaitFor(fd_, POLLOUT, limits_.write_timeout_ms)) failed_ = true;
    } else {
      failed_ = true;
    }
  }
  return !failed_;
}

const ConnectionAddresses& ConnectionStream::Addresses() const {
  ConnectionAddresses& a = addresses_ ? *addresses_ : own_addresses_;
  if (!a.known) {
    PeerName(fd_, false, a.remote_ip, a.remote_port);
    PeerName(fd_, true, a.local_ip, a.local_port);
    a.known = true;
  }
  return a;
}

void ConnectionStream::get_remote_ip_and_port(std::string& ip,
                                              int& port) const {
  const ConnectionAddresses& a = Addresses();
  ip = a.remote_ip;
  port = a.remote_port;
}

void ConnectionStream::get_local_ip_and_port(std::string& ip, int& port) const {
  const ConnectionAddresses& a = Addresses();
  ip = a.local_ip;
  port = a.local_port;
}

std::string ConnectionStream::TakeLeftover() {
  std::string out = buf_.substr(std::min(pos_, buf_.size()));
  buf_.clear();
  pos_ = 0;
  return out;
}

GuardedServer::GuardedServer(const ConnectionLimits& limits) : limits_(limits) {
  new_task_queue = [] { return new InlineQueue(); };
}

GuardedServer::~GuardedServer() { StopWorkers(); }

void GuardedServer::StartWorkers() {
  if (gate_.joinable()) return;
  stopping_ = false;
  // httplib listens with a backlog of 5: a burst of connections would wait
  // for SYN retransmissions (1 s, 3 s, ...) before the gate even sees them.
  // Re-listening on the bound socket raises the kernel's accept queue; the
  // gate bounds what is accepted (max_connections).
  if (svr_sock_ != INVALID_SOCKET)
    ::listen(svr_sock_, std::max(limits_.max_queue, 128));
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  gate_ = std::thread([this] { GateLoop(); });
  started_ = true;
  for (int i = 0; i < limits_.threads; ++i)
    workers_.emplace_back([this] { WorkerLoop(); });
}

void GuardedServer::StopWorkers() {
  if (!gate_.joinable()) return;
  stopping_ = true;
  started_ = false;
  Wake();
  {
    std::lock_guard<std::mutex> lock(queue_mu_);
    // Wake workers blocked in a read of a slow client.
    for (int fd : serving_fds_) ::shutdown(fd, SHUT_RDWR);
  }
  queue_cv_.notify_all();
  gate_.join();
  for (std::thread& t : workers_) t.join();
  workers_.clear();
  for (Conn& c : queue_) CloseConn(c.fd);
  queue_.clear();
  for (Conn& c : gate_incoming_) CloseConn(c.fd);
  gate_incoming_.clear();
  ::close(wake_fd_);
  wake_fd_ = -1;
}

void GuardedServer::Wake() {
  if (wake_fd_ < 0) return;
  const std::uint64_t one = 1;
  (void)!::write(wake_fd_, &one, sizeof one);
}

void GuardedServer::CloseConn(int fd) {
  ::shutdown(fd, SHUT_RDWR);
  ::close(fd);
  --open_;
}

bool GuardedServer::process_and_close_socket(socket_t sock) {
  // On the accepting thread: never block here.
  ++open_;
  const int flags = ::fcntl(sock, F_GETFL, 0);
  ::fcntl(sock, F_SETFL, flags | O_NONBLOCK);
  // Answers go out as two writes (headers, body): no Nagle delay.
  const int yes = 1;
  ::setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
  if (stopping_ || !started_ || open_ > limits_.max_connections) {
    ++refused_busy_;
    WriteQuickAnswer(
        sock, 503, "unavailable", "too many open connections; retry later");
    CloseConn(sock);
    return false;
  }
  Conn c;
  c.fd = sock;
  c.started = SteadyClock::now();
  c.deadline = c.started + std::chrono::milliseconds(limits_.header_timeout_ms);
  c.idle = false;  // a new connection owes its first request line
  {
    std::lock_guard<std::mutex> lock(gate_mu_);
    gate_incoming_.push_back(std::move(c));
  }
  Wake();
  return true;
}

void GuardedServer::Enqueue(Conn conn) {
  {
    std::lock_guard<std::mutex> lock(queue_mu_);
    if (static_cast<int>(queue_.size()) < limits_.max_queue && !stopping_) {
      queue_.push_back(std::move(conn));
      queue_cv_.notify_one();
      return;
    }
  }
  ++refused_busy_;
  WriteQuickAnswer(
      conn.fd, 503, "unavailable", "all workers busy; retry later");
  CloseConn(conn.fd);
}

void GuardedServer::ReturnToGate(Conn conn) {
  {
    std::lock_guard<std::mutex> lock(gate_mu_);
    gate_incoming_.push_back(std::move(conn));
  }
  Wake();
}

void GuardedServer::GateLoop() {
  std::vector<Conn> waiting;
  std::vector<pollfd> fds;
  while (!stopping_) {
    {
      std::lock_guard<std::mutex> lock(gate_mu_);
      for (Conn& c : gate_incoming_) waiting.push_back(std::move(c));
      gate_incoming_.clear();
    }
    // Pipelined requests may already be complete.
    for (std::size_t i = 0; i < waiting.size();) {
      if (!waiting[i].draining && HeadersComplete(waiting[i].buf)) {
        Enqueue(std::move(waiting[i]));
        waiting.erase(waiting.begin() + static_cast<std::ptrdiff_t>(i));
      } else {
        ++i;
      }
    }
    fds.clear();
    fds.push_back(pollfd{wake_fd_, POLLIN, 0});
    int timeout_ms = 1000;
    for (const Conn& c : waiting) {
      fds.push_back(pollfd{c.fd, POLLIN, 0});
      timeout_ms = std::min(timeout_ms, MillisUntil(c.deadline) + 1);
    }
    const int r = ::poll(fds.data(), fds.size(), timeout_ms);
    if (r < 0 && errno != EINTR) break;
    if (fds[0].revents & POLLIN) {
      std::uint64_t drained;
      (void)!::read(wake_fd_, &drained, sizeof drained);
    }
    const auto now = SteadyClock::now();
    std::vector<Conn> keep;
    keep.reserve(waiting.size());
    for (std::size_t i = 0; i < waiting.size(); ++i) {
      Conn& c = waiting[i];
      if (c.draining) {
        bool done = now >= c.deadline;
        if (!done && r > 0 && fds[i + 1].revents != 0) {
          char sink[16384];
          for (;;) {
            const ssize_t n = ::recv(c.fd, sink, sizeof sink, 0);
            if (n > 0) {
              c.drained += static_cast<std::size_t>(n);
              if (c.drained > (256u << 20)) {
                done = true;
                break;
              }
              continue;
            }
            if (n < 0 && errno == EINTR) continue;
            if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
            done = true;  // peer closed or reset
            break;
          }
        }
        if (done)
          CloseConn(c.fd);
        else
          keep.push_back(std::move(c));
        continue;
      }
      bool closed = false;
      if (r > 0 && fds[i + 1].revents != 0) {
        char chunk[4096];
        for (;;) {
          const std::size_t room = limits_.max_header_bytes + 1 - c.buf.size();
          const ssize_t n =
              ::recv(c.fd, chunk, std::min(sizeof chunk, room), 0);
          if (n > 0) {
            if (c.idle) {
              c.idle = false;
              c.started = now;
              c.deadline =
                  now + std::chrono::milliseconds(limits_.header_timeout_ms);
            }
            c.buf.append(chunk, static_cast<std::size_t>(n));
            if (c.buf.size() > limits_.max_header_bytes ||
                HeadersComplete(c.buf))
              break;
            continue;
          }
          if (n < 0 && errno == EINTR) continue;
          if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
          CloseConn(c.fd);  // peer closed or reset
          closed = true;
          break;
        }
      }
      if (closed) continue;
      if (HeadersComplete(c.buf)) {
        Enqueue(std::move(c));
      } else if (c.buf.size() > limits_.max_header_bytes) {
        WriteQuickAnswer(c.fd,
                         431,
                         "request header fields too large",
                         "request line and headers exceed the limit");
        CloseConn(c.fd);
      } else if (now >= c.deadline) {
        if (!c.idle) {
          ++timed_out_;
          WriteQuickAnswer(c.fd,
                           408,
                           "request timeout",
                           "request headers not complete within the deadline");
        }
        CloseConn(c.fd);
      } else {
        keep.push_back(std::move(c));
      }
    }
    waiting.swap(keep);
  }
  for (Conn& c : waiting) CloseConn(c.fd);
}

void GuardedServer::WorkerLoop() {
  for (;;) {
    Conn conn;
    {
      std::unique_lock<std::mutex> lock(queue_mu_);
      queue_cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      conn = std::move(queue_.front());
      queue_.pop_front();
      serving_fds_.insert(conn.fd);
    }
    ServeOne(std::move(conn));
  }
}

void GuardedServer::ServeOne(Conn conn) {
  // Serves requests of one connection while the client keeps them coming
  // at once (the next request's headers complete within a millisecond of
  // the answer, at most kFastPathRequests in a row); otherwise the
  // connection goes back to the gate, so an idle or slow client never
  // holds this worker.
  constexpr int kFastPathRequests = 64;
  for (int round = 0;; ++round) {
    const auto deadline =
        conn.started + std::chrono::milliseconds(limits_.request_timeout_ms);
    ConnectionStream strm(
        conn.fd, std::move(conn.buf), deadline, limits_, &conn.addresses);
    const bool close_connection =
        stopping_ || conn.served + 1 >= limits_.keep_alive_max_count;
    bool connection_closed = false;
    bool ok = false;
    g_current_stream = &strm;
    try {
      ok = process_request(strm, close_connection, connection_closed, nullptr);
    } catch (...) {
      ok = false;
    }
    g_current_stream = nullptr;
    if (!strm.Flush()) ok = false;
    if (strm.close_after() && !strm.failed() && !stopping_) {
      // The answer went out before the body was read (413, 415, 401, an
      // unparsable request line...). The gate reads and drops what the
      // client still sends for a short while, so that a client writing its
      // whole body before reading can see the answer (a "lingering
      // close"); bounded in time and bytes, nothing is kept. It waits in
      // the gate's poll, not here: a client that sends a rejected request
      // and then neither writes nor closes held this worker for 2 s
      // (outside attack run: 20 such connections delayed a lookup 3.5 s).
      ::shutdown(conn.fd, SHUT_WR);
      {
        std::lock_guard<std::mutex> lock(queue_mu_);
        serving_fds_.erase(conn.fd);
      }
      conn.buf.clear();
      conn.draining = true;
      conn.deadline =
          std::min(SteadyClock::now() + std::chrono::seconds(2), deadline);
      ReturnToGate(std::move(conn));
      return;
    }
    if (!ok || connection_closed || close_connection || strm.failed() ||
        strm.timed_out() || strm.close_after() || stopping_) {
      {
        std::lock_guard<std::mutex> lock(queue_mu_);
        serving_fds_.erase(conn.fd);
      }
      CloseConn(conn.fd);
      return;
    }
    conn.buf = strm.TakeLeftover();
    conn.served += 1;
    conn.started = SteadyClock::now();
    if (round + 1 < kFastPathRequests && conn.buf.size() < 65536 &&
        (HeadersComplete(conn.buf) || WaitFor(conn.fd, POLLIN, 1))) {
      char chunk[8192];
      for (;;) {
        const ssize_t n = ::recv(conn.fd, chunk, sizeof chunk, MSG_DONTWAIT);
        if (n <= 0) break;
        conn.buf.append(chunk, static_cast<std::size_t>(n));
        if (conn.buf.size() > limits_.max_header_bytes ||
            HeadersComplete(conn.buf))
          break;
      }
      if (HeadersComplete(conn.buf)) continue;  // serve it here
    }
    break;
  }
  {
    std::lock_guard<std::mutex> lock(queue_mu_);
    serving_fds_.erase(conn.fd);
  }
  conn.idle = conn.buf.empty();
  conn.deadline = conn.started + std::chrono::milliseconds(
                                     conn.idle ? limits_.keep_alive_timeout_ms
                                               : limits_.header_timeout_ms);
  ReturnToGate(std::move(conn));
}

}  // namespace frictiond::internal
