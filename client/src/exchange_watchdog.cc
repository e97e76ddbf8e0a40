#include "exchange_watchdog.h"

#include <cstddef>  // offsetof
#include <utility>

#include <linux/sockios.h>
#include <linux/tcp.h>   // struct tcp_info with tcpi_bytes_received
#include <netinet/in.h>  // IPPROTO_TCP
#include <sys/ioctl.h>
#include <sys/socket.h>

namespace frictiond::internal {

ExchangeWatchdog::ExchangeWatchdog(std::function<void()> stop,
                                   std::uint64_t max_header_bytes,
                                   std::chrono::milliseconds poll)
    : stop_(std::move(stop)),
      max_header_bytes_(max_header_bytes),
      poll_(poll) {}

ExchangeWatchdog::~ExchangeWatchdog() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    quit_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::uint64_t ExchangeWatchdog::BytesRead(int socket) {
  if (socket < 0) return 0;
  tcp_info info{};
  socklen_t len = sizeof info;
  if (::getsockopt(socket, IPPROTO_TCP, TCP_INFO, &info, &len) != 0 ||
      len < offsetof(tcp_info, tcpi_bytes_received) +
                sizeof info.tcpi_bytes_received)
    return 0;
  int queued = 0;
  if (::ioctl(socket, SIOCINQ, &queued) != 0 || queued < 0) queued = 0;
  const std::uint64_t received = info.tcpi_bytes_received;
  const auto unread = static_cast<std::uint64_t>(queued);
  return received > unread ? received - unread : 0;
}

void ExchangeWatchdog::Begin(Clock::time_point deadline, int socket) {
  const std::uint64_t base = BytesRead(socket);
  bool wake = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    active_ = true;
    body_ = false;
    socket_ = socket;
    base_ = base;
    deadline_ = deadline;
    fired_.clear();
    if (!thread_.joinable()) thread_ = std::thread([this] { Loop(); });
    wake = parked_;
  }
  // Only a parked thread is woken: an exchange costs no context switch
  // while exchanges keep coming.
  if (wake) cv_.notify_all();
}

void ExchangeWatchdog::OnSocket(int socket) {
  std::lock_guard<std::mutex> lock(mu_);
  socket_ = socket;
  base_ = 0;  // a new connection: everything it reads belongs to this exchange
}

void ExchangeWatchdog::OnBody() {
  std::lock_guard<std::mutex> lock(mu_);
  body_ = true;
}

std::string ExchangeWatchdog::End() {
  std::unique_lock<std::mutex> lock(mu_);
  // A stop still under way would hit the next exchange: let it finish.
  cv_.wait(lock, [this] { return !stopping_; });
  active_ = false;
  last_active_ = Clock::now();
  std::string fired;
  fired.swap(fired_);
  return fired;
}

void ExchangeWatchdog::Loop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (!quit_) {
    if (!active_ && Clock::now() - last_active_ > kParkAfter) {
      parked_ = true;
      cv_.wait(lock, [this] { return quit_ || active_; });
      parked_ = false;
      continue;
    }
    cv_.wait_for(lock, poll_, [this] { return quit_; });
    if (quit_ || !active_ || !fired_.empty()) continue;
    if (Clock::now() > deadline_) {
      fired_ = "deadline";
    } else if (!body_) {
      const std::uint64_t read = BytesRead(socket_);
      if (read > base_ && read - base_ > max_header_bytes_) fired_ = "headers";
    }
    if (fired_.empty()) continue;
    // Client::stop takes the client's own lock; ours is not needed.
    stopping_ = true;
    lock.unlock();
    stop_();
    lock.lock();
    stopping_ = false;
    cv_.notify_all();
  }
}

}  // namespace frictiond::internal
