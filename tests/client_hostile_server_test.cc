// The client library against a hostile server (whatever answers at
// base_url): a reply larger than max_reply_bytes, a reply that never ends,
// a reply that arrives one byte at a time, and a deeply nested JSON reply
// each end in a ClientError, with memory and time bounded. An outside
// attack run had the CLI grow to 16.6 GB on an endless chunked reply, hang
// for minutes on a 1 byte/s reply, and crash on a 200,000-deep array. The
// same holds before the body: endless header lines, one header line without
// end, and headers arriving a byte at a time (RawReplyServer: httplib's
// server cannot send such replies).
#include <atomic>
#include <cerrno>
#include <chrono>
#include <string>
#include <thread>

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "frictiond/client/client.h"

// After every header that includes Eigen: httplib.h includes <resolv.h>,
// whose `_res` macro breaks Eigen's product kernels.
#include <httplib.h>

namespace frictiond {
namespace {

using Clock = std::chrono::steady_clock;

class HostileServer {
 public:
  HostileServer() {
    svr_.Get("/v1/materials/endless/model",
             [](const httplib::Request&, httplib::Response& res) {
               res.set_chunked_content_provider(
                   "application/json",
                   [](std::size_t, httplib::DataSink& sink) {
                     const std::string chunk(1 << 16, ' ');
                     return sink.write(chunk.data(), chunk.size());
                   });
             });
    svr_.Get(
        "/v1/materials/drip/model",
        [](const httplib::Request&, httplib::Response& res) {
          res.set_chunked_content_provider(
              "application/json", [](std::size_t, httplib::DataSink& sink) {
                std::this_thread::sleep_for(std::chrono::milliseconds(100));
                return sink.write(" ", 1);
              });
        });
    svr_.Get("/v1/materials/deep/model",
             [](const httplib::Request&, httplib::Response& res) {
               res.set_content(
                   std::string(200000, '[') + std::string(200000, ']'),
                   "application/json");
             });
    port_ = svr_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { svr_.listen_after_bind(); });
    while (!svr_.is_running())
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ~HostileServer() {
    svr_.stop();
    thread_.join();
  }
  std::string url() const {
    return "http://127.0.0.1:" + std::to_string(port_);
  }

 private:
  httplib::Server svr_;
  int port_ = 0;
  std::thread thread_;
};

/// Answers every connection with `head` and then `step()` repeated until
/// the client goes (or `pause` between steps), ignoring the request.
class RawReplyServer {
 public:
  RawReplyServer(std::string head,
                 std::string step,
                 std::chrono::milliseconds pause)
      : head_(std::move(head)), step_(std::move(step)), pause_(pause) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), len) != 0 ||
        ::listen(fd_, 4) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0)
      throw std::runtime_error("RawReplyServer: cannot listen");
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { Serve(); });
  }
  ~RawReplyServer() {
    quit_ = true;
    ::shutdown(fd_, SHUT_RDWR);
    thread_.join();
    ::close(fd_);
  }
  std::string url() const {
    return "http://127.0.0.1:" + std::to_string(port_);
  }

 private:
  void Serve() {
    while (!quit_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) <= 0) continue;
      const int c = ::accept(fd_, nullptr, nullptr);
      if (c < 0) continue;
      // A client that stopped reading leaves send blocked: time out to see
      // quit_ (the peer's gone connection may not reset for a minute).
      timeval t{0, 100000};
      ::setsockopt(c, SOL_SOCKET, SO_SNDTIMEO, &t, sizeof t);
      auto send = [&](const std::string& s) {
        return ::send(c, s.data(), s.size(), MSG_NOSIGNAL) > 0 ||
               errno == EAGAIN || errno == EWOULDBLOCK;
      };
      bool ok = send(head_);
      while (ok && !quit_) {
        ok = send(step_);
        if (pause_.count() > 0) std::this_thread::sleep_for(pause_);
      }
      ::close(c);
    }
  }
  std::string head_, step_;
  std::chrono::milliseconds pause_;
  int fd_ = -1;
  int port_ = 0;
  std::atomic<bool> quit_{false};
  std::thread thread_;
};

long MaxRssKib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

TEST(ClientHostileServer, ReplyHeadersAreBoundedInSizeAndTime) {
  const std::string status = "HTTP/1.1 200 OK\r\n";
  struct Case {
    const char* name;
    std::string head, step;
    std::chrono::milliseconds pause;
    const char* error;
  };
  const Case cases[] = {
      {"endless header lines",
       status,
       "X-Pad: " + std::string(1000, 'a') + "\r\n",
       std::chrono::milliseconds(0),
       "reply headers larger than"},
      {"one header line without end",
       status + "X-Pad: ",
       std::string(1 << 16, 'a'),
       std::chrono::milliseconds(0),
       "reply headers larger than"},
      {"headers a byte at a time",
       status,
       "a",
       std::chrono::milliseconds(50),
       "reply not complete within deadline_s"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    RawReplyServer server(c.head, c.step, c.pause);
    ClientOptions o;
    o.base_url = server.url();
    o.timeout_s = 5.0;  // each read is far quicker: only the deadline ends it
    o.deadline_s = 1.0;
    FrictionClient client(o);
    const long rss0 = MaxRssKib();
    const auto t0 = Clock::now();
    try {
      client.FetchModel("felt");
      ADD_FAILURE() << "no error";
    } catch (const ClientError& e) {
      EXPECT_NE(std::string(e.what()).find(c.error), std::string::npos)
          << e.what();
    }
    EXPECT_LT(Clock::now() - t0, std::chrono::seconds(3));
    // 1 MiB of headers plus what one 5 ms poll lets arrive; without the
    // watchdog the first two cases grew by gigabytes within the deadline.
    EXPECT_LT(MaxRssKib() - rss0, 64 * 1024);
  }
}

TEST(ClientHostileServer, RepliesAreBoundedInSizeTimeAndDepth) {
  HostileServer server;
  ClientOptions o;
  o.base_url = server.url();
  o.timeout_s = 5.0;
  o.max_reply_bytes = 4u << 20;
  o.deadline_s = 1.0;
  FrictionClient client(o);
  auto expect_error = [&](const std::string& material,
                          const std::string& text) {
    SCOPED_TRACE(material);
    const auto t0 = Clock::now();
    try {
      client.FetchModel(material);
      ADD_FAILURE() << "no error";
    } catch (const ClientError& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos)
          << e.what();
    }
    EXPECT_LT(Clock::now() - t0, std::chrono::seconds(4));
  };
  expect_error("endless", "reply larger than max_reply_bytes");
  expect_error("drip", "reply not complete within deadline_s");
  expect_error("deep", "reply is not JSON");
}

}  // namespace
}  // namespace frictiond
