// The client library against a hostile server (whatever answers at
// base_url): a reply larger than max_reply_bytes, a reply that never ends,
// a reply that arrives one byte at a time, and a deeply nested JSON reply
// each end in a ClientError, with memory and time bounded. An outside
// attack run had the CLI grow to 16.6 GB on an endless chunked reply, hang
// for minutes on a 1 byte/s reply, and crash on a 200,000-deep array.
#include <chrono>
#include <string>
#include <thread>

#include <gtest/gtest.h>

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
