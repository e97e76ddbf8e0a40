// Hostile HTTP input (issue 16 items 3-6; docs/security.md "HTTP"): bodies
// are bounded while they are read (chunked, length-less, compressed) and the
// daemon's peak memory stays put; slow clients do not hold the workers;
// invalid or overlong text in any parameter or header of any route is a 4xx,
// never a 500, and the listings keep answering 200.
#include <chrono>
#include <fstream>
#include <iostream>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <nlohmann/json.hpp>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>
#include <zlib.h>

#include "frictiond/server/daemon.h"
#include "frictiond/testing/daemon_process.h"

// After Eigen: <httplib.h> pulls in <resolv.h>, whose `_res` macro breaks
// Eigen's headers.
#include <httplib.h>

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::TempDir;
using Clock = std::chrono::steady_clock;

constexpr char kKnown[] = "microtribo-recip";  // bundled, has a model

// Peak resident set size of a process [bytes] (VmHWM).
std::size_t PeakRss(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmHWM:", 0) == 0)
      return static_cast<std::size_t>(std::stoull(line.substr(6))) * 1024;
  }
  return 0;
}

// A raw loopback connection (the tests need to misbehave where httplib's
// client would not).
class RawConn {
 public:
  explicit RawConn(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~RawConn() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawConn(const RawConn&) = delete;
  RawConn& operator=(const RawConn&) = delete;
  bool ok() const { return fd_ >= 0; }
  int fd() const { return fd_; }

  // Sends all of `data` unless the server answers first (or fails).
  // @return false when the server answered (or closed) before all was sent.
  bool SendUnlessAnswered(const std::string& data) {
    std::size_t off = 0;
    while (off < data.size()) {
      pollfd p{fd_, POLLIN | POLLOUT, 0};
      if (::poll(&p, 1, 5000) <= 0) return false;
      if (p.revents & (POLLIN | POLLHUP | POLLERR)) return false;
      const ssize_t n =
          ::send(fd_, data.data() + off, data.size() - off, MSG_NOSIGNAL);
      if (n <= 0) return false;
      off += static_cast<std::size_t>(n);
    }
    return true;
  }
  bool Readable(int timeout_ms) const {
    pollfd p{fd_, POLLIN, 0};
    return ::poll(&p, 1, timeout_ms) > 0;
  }
  // Reads an answer (until the body named by Content-Length is complete,
  // or the peer closes, or timeout). Returns the status (0: none).
  int ReadAnswer(std::string* body, int timeout_ms = 10000) {
    std::string in;
    const auto until = Clock::now() + std::chrono::milliseconds(timeout_ms);
    for (;;) {
      const std::size_t head_end = in.find("\r\n\r\n");
      if (head_end != std::string::npos) {
        const std::size_t cl = in.find("Content-Length: ");
        if (cl != std::string::npos && cl < head_end) {
          const std::size_t n = std::stoul(in.substr(cl + 16));
          if (in.size() >= head_end + 4 + n) break;
        }
      }
      const int left = static_cast<int>(
          std::chrono::duration_cast<std::chrono::milliseconds>(until -
                                                                Clock::now())
              .count());
      if (left <= 0 || !Readable(left)) break;
      char buf[65536];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) break;
      in.append(buf, static_cast<std::size_t>(n));
    }
    if (in.rfind("HTTP/1.1 ", 0) != 0) return 0;
    const std::size_t head_end = in.find("\r\n\r\n");
    if (body) {
      *body = head_end == std::string::npos ? "" : in.substr(head_end + 4);
      // Only this answer's body: a next answer may follow in the same read.
      const std::size_t cl = in.find("Content-Length: ");
      if (head_end != std::string::npos && cl != std::string::npos &&
          cl < head_end)
        body->resize(
            std::min(body->size(),
                     static_cast<std::size_t>(std::stoul(in.substr(cl + 16)))));
    }
    return std::stoi(in.substr(9, 3));
  }

 private:
  int fd_ = -1;
};

std::string GzipOfZeros(std::size_t n) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 9, Z_DEFLATED, 31, 9, Z_DEFAULT_STRATEGY), Z_OK);
  const std::string zeros(1u << 20, '\0');
  std::string out;
  char buf[1 << 16];
  std::size_t fed = 0;
  int flush = Z_NO_FLUSH;
  do {
    if (z.avail_in == 0 && fed < n) {
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(zeros.data()));
      z.avail_in = static_cast<uInt>(zeros.size());
      fed += zeros.size();
    }
    flush = fed >= n && z.avail_in == 0 ? Z_FINISH : Z_NO_FLUSH;
    if (fed >= n) flush = Z_FINISH;
    z.next_out = reinterpret_cast<Bytef*>(buf);
    z.avail_out = sizeof buf;
    const int r = deflate(&z, flush);
    out.append(buf, sizeof buf - z.avail_out);
    if (r == Z_STREAM_END) break;
  } while (true);
  deflateEnd(&z);
  return out;
}

class HostileHttpTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    signal(SIGPIPE, SIG_IGN);
    dir_ = new TempDir("hostile");
    DaemonOptions o;
    o.db = dir_->path() + "/lib.db";
    o.threads = 2;  // few workers: slow clients must not take them
    o.extra_args = {"--header-timeout-ms",
                    "7000",
                    "--request-timeout-ms",
                    "20000",
                    "--max-connections",
                    "64"};
    daemon_ = new DaemonProcess(o);
    daemon_->Start();
  }
  static void TearDownTestSuite() {
    delete daemon_;
    delete dir_;
  }
  std::string AuthHeader() const {
    return "Authorization: Bearer " + daemon_->options().operator_token +
           "\r\n";
  }
  static TempDir* dir_;
  static DaemonProcess* daemon_;
};

TempDir* HostileHttpTest::dir_ = nullptr;
DaemonProcess* HostileHttpTest::daemon_ = nullptr;

// Everything the daemon sends on `c` until it closes the connection;
// fails the test when it is still open after 5 s.
std::string ReadUntilClosed(RawConn& c) {
  std::string all;
  const auto until = Clock::now() + std::chrono::seconds(5);
  while (Clock::now() < until && c.Readable(5000)) {
    char buf[4096];
    const ssize_t n = ::recv(c.fd(), buf, sizeof buf, 0);
    if (n <= 0) break;  // closed: what we want
    all.append(buf, static_cast<std::size_t>(n));
  }
  EXPECT_LT(Clock::now(), until) << "the connection stayed open";
  return all;
}

void ExpectJsonError(int status, const std::string& body, int want) {
  EXPECT_EQ(status, want) << body.substr(0, 300);
  const json j = json::parse(body, nullptr, false);
  EXPECT_TRUE(j.is_object() && j.contains("error") && j.contains("detail"))
      << body.substr(0, 300);
}

TEST_F(HostileHttpTest, BodiesAreBoundedWhileReadAndPeakMemoryStays) {
  auto client = daemon_->MakeClient();
  ASSERT_TRUE(client->Get("/healthz"));
  const std::size_t peak_before = PeakRss(daemon_->pid());
  ASSERT_GT(peak_before, 0u);
  const std::string path =
      std::string("POST /v1/materials/") + kKnown + "/strokes HTTP/1.1\r\n";
  const std::string mib(1u << 20, '7');

  {  // 1 GiB chunked, authenticated: read up to the limit, then 413.
    RawConn c(daemon_->port());
    ASSERT_TRUE(c.ok());
    std::string head = path + "Host: x\r\n" + AuthHeader() +
                       "Content-Type: text/csv\r\n"
                       "Transfer-Encoding: chunked\r\n\r\n";
    ASSERT_TRUE(c.SendUnlessAnswered(head));
    const std::string chunk = "100000\r\n" + mib + "\r\n";
    std::size_t sent = 0;
    while (sent < (1u << 30) && c.SendUnlessAnswered(chunk)) sent += 1u << 20;
    EXPECT_LT(sent, 1u << 30) << "the daemon read a whole 1 GiB body";
    std::string body;
    ExpectJsonError(c.ReadAnswer(&body), body, 413);
  }
  {  // Unauthenticated chunked: refused from the headers, body unread.
    RawConn c(daemon_->port());
    ASSERT_TRUE(c.ok());
    ASSERT_TRUE(c.SendUnlessAnswered(path +
                                     "Host: x\r\nContent-Type: text/csv\r\n"
                                     "Transfer-Encoding: chunked\r\n\r\n"));
    ASSERT_TRUE(c.Readable(5000)) << "no answer before the body";
    std::string body;
    ExpectJsonError(c.ReadAnswer(&body), body, 401);
  }
  {  // No Content-Length, no chunking: no body (RFC 7230 3.3.3). The
     // request is answered at once (an empty upload: 400); the bytes after
     // it are an unparsable next request (400, close), never buffered.
    RawConn c(daemon_->port());
    ASSERT_TRUE(c.ok());
    ASSERT_TRUE(c.SendUnlessAnswered(path + "Host: x\r\n" + AuthHeader() +
                                     "Content-Type: text/csv\r\n\r\n"));
    std::size_t sent = 0;
    while (sent < (256u << 20) && c.SendUnlessAnswered(mib)) sent += 1u << 20;
    EXPECT_LT(sent, 256u << 20);
    std::string body;
    ExpectJsonError(c.ReadAnswer(&body), body, 400);
  }
  {  // A gzip bomb (256 MiB of zeros): compressed bodies are refused.
    const std::string bomb = GzipOfZeros(256u << 20);
    ASSERT_LT(bomb.size(), 1u << 20);
    RawConn c(daemon_->port());
    ASSERT_TRUE(c.ok());
    c.SendUnlessAnswered(path + "Host: x\r\n" + AuthHeader() +
                         "Content-Type: text/csv\r\nContent-Encoding: gzip\r\n"
                         "Content-Length: " +
                         std::to_string(bomb.size()) + "\r\n\r\n" + bomb);
    std::string body;
    ExpectJsonError(c.ReadAnswer(&body), body, 415);
  }
  {  // Declared too large: 413 before reading.
    RawConn c(daemon_->port());
    ASSERT_TRUE(c.ok());
    ASSERT_TRUE(c.SendUnlessAnswered(path + "Host: x\r\n" + AuthHeader() +
                                     "Content-Length: 99999999999\r\n\r\n"));
    std::string body;
    ExpectJsonError(c.ReadAnswer(&body), body, 413);
  }
  const std::size_t peak_after = PeakRss(daemon_->pid());
  std::cout << "daemon peak RSS (VmHWM) before " << (peak_before >> 10)
            << " KiB, after " << (peak_after >> 10) << " KiB\n";
#if defined(__SANITIZE_ADDRESS__)
  // AddressSanitizer keeps freed blocks in quarantine (256 MiB by
  // default), so the bound is only meaningful in a plain build.
  std::cout << "(ASan build: peak RSS bound not checked)\n";
#else
  EXPECT_LT(peak_after, peak_before + (64u << 20))
      << "peak RSS " << (peak_before >> 20) << " MiB -> " << (peak_after >> 20)
      << " MiB";
#endif
  // Still serving.
  auto res = client->Get("/healthz");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
}

TEST_F(HostileHttpTest, SlowClientsDoNotHoldTheWorkers) {
  // 32 connections dribbling one header byte every 5 s (the daemon has 2
  // workers and a 7 s header deadline) while lookups are timed.
  std::vector<std::unique_ptr<RawConn>> slow;
  const std::string request = "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n";
  for (int i = 0; i < 32; ++i) {
    slow.push_back(std::make_unique<RawConn>(daemon_->port()));
    ASSERT_TRUE(slow.back()->ok());
  }
  auto client = daemon_->MakeClient(5.0);
  const std::string lookup = std::string("/v1/materials/") + kKnown + "/model";
  const auto start = Clock::now();
  std::size_t sent = 0;
  double worst_s = 0;
  int lookups = 0;
  while (Clock::now() - start < std::chrono::milliseconds(6500)) {
    const auto elapsed = Clock::now() - start;
    if (elapsed >= std::chrono::seconds(5 * static_cast<int>(sent))) {
      for (auto& c : slow)
        ASSERT_TRUE(c->SendUnlessAnswered(request.substr(sent, 1)));
      ++sent;
    }
    const auto t0 = Clock::now();
    auto res = client->Get(lookup.c_str());
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    ASSERT_TRUE(res) << httplib::to_string(res.error());
    EXPECT_EQ(res->status, 200) << res->body.substr(0, 200);
    worst_s = std::max(worst_s, s);
    ++lookups;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  std::cout << lookups << " lookups beside 32 slow clients, slowest "
            << worst_s * 1e3 << " ms\n";
  EXPECT_GE(lookups, 10);
  EXPECT_LT(worst_s, 1.0) << "slowest lookup beside 32 slow clients";
  // Each slow client is cut at the header deadline with 408.
  int timed_out = 0;
  for (auto& c : slow) {
    std::string body;
    if (c->ReadAnswer(&body, 3000) == 408) ++timed_out;
  }
  EXPECT_EQ(timed_out, 32);
}

// A request line the HTTP layer cannot parse gets exactly one 400 naming
// the request line, and the connection closes (httplib answered once per
// following header line and kept the connection: an outside attack run).
TEST_F(HostileHttpTest, UnparsableRequestLineGetsOneAnswerAndClose) {
  for (const std::string line :
       {"FOO /healthz HTTP/1.1", "get /healthz HTTP/1.1", "GARBAGE"}) {
    SCOPED_TRACE(line);
    RawConn c(daemon_->port());
    ASSERT_TRUE(c.ok());
    ASSERT_TRUE(c.SendUnlessAnswered(
        line + "\r\nHost: x\r\nAccept: */*\r\nX-A: 1\r\n\r\n"));
    const std::string all = ReadUntilClosed(c);
    std::size_t answers = 0;
    for (std::size_t at = all.find("HTTP/1.1 "); at != std::string::npos;
         at = all.find("HTTP/1.1 ", at + 1))
      ++answers;
    EXPECT_EQ(answers, 1u) << all;
    EXPECT_EQ(all.rfind("HTTP/1.1 400", 0), 0u) << all;
    EXPECT_NE(all.find("\"field\":\"request line\""), std::string::npos) << all;
  }
  // Rejected requests from clients that then neither write nor close do
  // not hold the 2 workers (the lingering close waits in the gate).
  std::vector<std::unique_ptr<RawConn>> silent;
  for (int i = 0; i < 16; ++i) {
    silent.push_back(std::make_unique<RawConn>(daemon_->port()));
    ASSERT_TRUE(silent.back()->SendUnlessAnswered("FOO / HTTP/1.1\r\n\r\n"));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = Clock::now();
  auto res = daemon_->MakeClient()->Get("/healthz");
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_LT(s, 1.0) << "a lookup beside 16 silent rejected connections";
}

// A body that stops short of its Content-Length gets 408 naming the body
// once it falls below the minimum body rate (16 KiB/s after a 2 s grace;
// before, the read timeout of 10 s); the connection then closes. Before
// stop 22, the timed-out read marked the connection failed, so the 408 was
// never written (an outside attack run saw the connection close after 10 s
// with no answer).
TEST_F(HostileHttpTest, StalledBodyGets408) {
  RawConn c(daemon_->port());
  ASSERT_TRUE(c.ok());
  ASSERT_TRUE(c.SendUnlessAnswered(
      "POST /v1/materials/stall/strokes HTTP/1.1\r\nHost: x\r\n" +
      AuthHeader() +
      "Content-Type: text/csv\r\nContent-Length: 100\r\n\r\nt_s,"));
  const auto t0 = Clock::now();
  std::string body;
  const int status = c.ReadAnswer(&body, 15000);
  const double waited =
      std::chrono::duration<double>(Clock::now() - t0).count();
  ExpectJsonError(status, body, 408);
  EXPECT_NE(body.find("\"field\":\"body\""), std::string::npos) << body;
  EXPECT_GT(waited, 1.5);
  EXPECT_LT(waited, 8.0);
  char more = 0;
  EXPECT_FALSE(c.Readable(3000) && ::recv(c.fd(), &more, 1, 0) > 0)
      << "bytes after the answer";
}

// A body dribbled one byte every 0.5 s (never stalled for the read
// timeout) is cut at the minimum body rate, so two such clients do not hold
// the two workers: an outside attack run held them for 70 s with one byte
// every 5 s, and lookups beside them waited 57 s.
TEST_F(HostileHttpTest, DribbledBodyIsCutAtTheMinimumRate) {
  std::vector<std::unique_ptr<RawConn>> slow;
  for (int i = 0; i < 2; ++i) {
    slow.push_back(std::make_unique<RawConn>(daemon_->port()));
    ASSERT_TRUE(slow.back()->SendUnlessAnswered(
        "POST /v1/recognize HTTP/1.1\r\nHost: x\r\n" + AuthHeader() +
        "Content-Type: image/png\r\nContent-Length: 5000\r\n\r\n"));
  }
  const auto t0 = Clock::now();
  std::vector<bool> answered(slow.size(), false);
  while (Clock::now() - t0 < std::chrono::seconds(8)) {
    for (std::size_t i = 0; i < slow.size(); ++i)
      if (!answered[i] && !slow[i]->SendUnlessAnswered("x")) answered[i] = true;
    if (std::all_of(answered.begin(), answered.end(), [](bool a) { return a; }))
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  const double cut_s = std::chrono::duration<double>(Clock::now() - t0).count();
  for (auto& c : slow) {
    std::string body;
    const int status = c->ReadAnswer(&body, 3000);
    ExpectJsonError(status, body, 408);
    EXPECT_NE(body.find("\"field\":\"body\""), std::string::npos) << body;
  }
  EXPECT_LT(cut_s, 6.0) << "dribbled bodies held the workers";
  const auto t1 = Clock::now();
  auto res = daemon_->MakeClient()->Get("/healthz");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t1).count(), 1.0);
}

// An answer of the HTTP layer before the body is read (414 here) closes the
// connection: the unread body is never read as a next request. An outside
// attack smuggled a PUT with its own token in the body of a request answered
// 414, and the PUT was executed.
TEST_F(HostileHttpTest, RejectedTargetClosesAndSmugglesNothing) {
  const std::string inner = "{\"name\":\"smugg\"}";
  const std::string smuggled =
      "PUT /v1/materials/smuggled HTTP/1.1\r\nHost: x\r\n" + AuthHeader() +
      "Content-Length: " + std::to_string(inner.size()) + "\r\n\r\n" + inner;
  RawConn c(daemon_->port());
  ASSERT_TRUE(c.ok());
  ASSERT_TRUE(c.SendUnlessAnswered(
      "POST /v1/materials/" + std::string(10240, 'x') +
      "/strokes HTTP/1.1\r\nHost: x\r\nContent-Length: " +
      std::to_string(smuggled.size()) + "\r\n\r\n" + smuggled));
  const std::string all = ReadUntilClosed(c);
  EXPECT_EQ(all.rfind("HTTP/1.1 414", 0), 0u) << all.substr(0, 300);
  EXPECT_EQ(all.find("HTTP/1.1 ", 1), std::string::npos) << all;
  EXPECT_NE(all.find("\"field\":\"target\""), std::string::npos) << all;
  auto res = daemon_->MakeClient()->Get("/v1/materials/smuggled");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404) << res->body.substr(0, 200);
}

// Range requests are not served: the whole JSON answer comes back (httplib
// cut it to the range, 200 with 11 bytes, or 416 with no body); a Range
// header httplib cannot parse is a JSON 416 naming it.
TEST_F(HostileHttpTest, RangeHeaderIsIgnored) {
  auto client = daemon_->MakeClient();
  for (const char* range : {"bytes=0-10", "bytes=99999999-"}) {
    SCOPED_TRACE(range);
    auto res = client->Get("/v1/materials", {{"Range", range}});
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << res->body.substr(0, 200);
    EXPECT_FALSE(json::parse(res->body, nullptr, false).is_discarded())
        << res->body.substr(0, 200);
  }
  auto res = client->Get("/v1/materials", {{"Range", "bytes=5-1"}});
  ASSERT_TRUE(res);
  ExpectJsonError(res->status, res->body, 416);
  EXPECT_NE(res->body.find("\"field\":\"Range\""), std::string::npos)
      << res->body;
}

TEST_F(HostileHttpTest, ConnectionsBeyondTheCapGet503) {
  // 80 silent connections against --max-connections 64: the excess is
  // answered 503 at once (well before the 7 s header deadline).
  std::vector<std::unique_ptr<RawConn>> idle;
  for (int i = 0; i < 80; ++i)
    idle.push_back(std::make_unique<RawConn>(daemon_->port()));
  std::vector<pollfd> fds;
  for (auto& c : idle) fds.push_back(pollfd{c->fd(), POLLIN, 0});
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  ASSERT_GE(::poll(fds.data(), fds.size(), 2000), 0);
  int refused = 0;
  for (std::size_t i = 0; i < idle.size(); ++i) {
    if (!(fds[i].revents & POLLIN)) continue;
    std::string body;
    if (idle[i]->ReadAnswer(&body, 1000) == 503) ++refused;
  }
  EXPECT_GE(refused, 80 - 64);
  idle.clear();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  auto res = daemon_->MakeClient()->Get("/healthz");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
}

TEST_F(HostileHttpTest, InvalidTextIsRefusedAndListingsKeepWorking) {
  auto client = daemon_->MakeClient();
  struct Case {
    std::string path;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"/v1/materials/zz/model?robot=%C3", "robot"},
      {"/v1/materials/zz/model?robot=%FF%FE", "robot"},
      {std::string("/v1/materials/") + kKnown + "/predict?fn_n=%FF&v_mm_s=1",
       "fn_n"},
      {std::string("/v1/materials/") + kKnown + "/predict?fn_n=1&v_mm_s=%C3",
       "v_mm_s"},
      {"/v1/materials/%C3%28/model", "id"},
      {"/v1/materials?q=" + std::string(2000, 'a'), "q"},
      {"/v1/identifications?limit=%C3", "limit"},
      {"/v1/materials/zz/model?robot=a%0Ab", "robot"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.path.substr(0, 100));
    auto res = client->Get(c.path.c_str());
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400) << res->body;
    const json j = json::parse(res->body, nullptr, false);
    ASSERT_TRUE(j.is_object()) << res->body;
    EXPECT_EQ(j.value("field", ""), c.field) << res->body;
  }
  // Headers too.
  auto res = client->Get("/v1/materials/zz/model",
                         httplib::Headers{{"X-Robot-Id", "\xC3"}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400) << res->body;
  res = client->Get("/v1/materials",
                    httplib::Headers{{"X-Other", std::string(5000, 'x')}});
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400) << res->body;
  for (const char* listing : {"/v1/identifications",
                              "/v1/materials",
                              "/v1/fingertips",
                              "/healthz",
                              "/metrics"}) {
    res = client->Get(listing);
    ASSERT_TRUE(res) << listing;
    EXPECT_EQ(res->status, 200) << listing << ": " << res->body.substr(0, 300);
  }
}

TEST_F(HostileHttpTest, ChosenBootstrapTokenIsNotEchoed) {
  const std::string log = daemon_->ReadLog();
  EXPECT_NE(log.find("created operator token"), std::string::npos) << log;
  EXPECT_EQ(log.find(daemon_->options().operator_token), std::string::npos)
      << log;
}

TEST_F(HostileHttpTest, ReadsRecordAtMostOneRequestAndListingsPage) {
  auto client = daemon_->MakeClient();
  for (int i = 0; i < 3; ++i) {
    auto res = client->Get("/v1/materials/page-me-1/model?robot=pager");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 404);
  }
  for (int i = 2; i <= 5; ++i) {
    auto res = client->Get(
        ("/v1/materials/page-me-" + std::to_string(i) + "/model?robot=pager")
            .c_str());
    ASSERT_TRUE(res);
  }
  std::set<std::string> seen;
  std::string after;
  int pages = 0;
  for (;;) {
    auto res = client->Get(("/v1/identifications?limit=2" +
                            (after.empty() ? "" : "&after=" + after))
                               .c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    const json j = json::parse(res->body);
    ASSERT_LE(j["identifications"].size(), 2u);
    for (const json& job : j["identifications"]) {
      const std::string m = job.value("material", "");
      EXPECT_TRUE(seen.insert(m + "/" + job.value("fingertip", "")).second)
          << "listed twice: " << m;
    }
    ++pages;
    if (j["next_after"].is_null()) break;
    after = std::to_string(j["next_after"].get<std::int64_t>());
    ASSERT_LT(pages, 100);
  }
  for (int i = 1; i <= 5; ++i)
    EXPECT_EQ(seen.count("page-me-" + std::to_string(i) + "/default"), 1u);
  EXPECT_GE(pages, 3);
}

// Every route, in-process: invalid UTF-8 and overlong values in every
// parameter, capture and header give 4xx; bodies of garbage never a 500.
TEST(HostileDispatchTest, EveryRouteParameterAndHeader) {
  TempDir dir("hostile-dispatch");
  DaemonConfig c;
  c.db = dir.path() + "/lib.db";
  c.port = 0;
  c.data_dir = "none";
  c.threads = 1;
  const std::string boot = "hostile-operator-0123456789abcdef";
  c.bootstrap_token = boot;
  Daemon daemon(c);
  daemon.Start();
  const std::vector<std::string> params = {"after",
                                           "eta_pa_s",
                                           "fingertip",
                                           "fn_n",
                                           "folds",
                                           "format",
                                           "ft_n",
                                           "joint",
                                           "limit",
                                           "load_n",
                                           "mass_kg",
                                           "material",
                                           "max",
                                           "max_fn_n",
                                           "max_v_mm_s",
                                           "median_window_s",
                                           "name",
                                           "open",
                                           "q",
                                           "ratio",
                                           "reference",
                                           "risk",
                                           "robot",
                                           "rule",
                                           "seed",
                                           "slip_floor_mm_s",
                                           "slip_peak_mm_s",
                                           "store",
                                           "temp_c",
                                           "v_mm_s",
                                           "version",
                                           "x0_mm",
                                           "x_mm",
                                           "y0_mm",
                                           "y_mm",
                                           "z_mm",
                                           "zz_unknown"};
  const std::vector<std::string> bad = {
      "\xC3", "\xFF", "a\xED\xA0\x80", std::string(5000, 'a')};
  auto make = [&](const RouteKey& r, const std::string& capture) {
    HttpRequest q;
    q.method = r.method;
    std::string path;
    std::size_t i = 0;
    while (i < r.pattern.size()) {
      if (r.pattern[i] == '{') {
        path += capture;
        i = r.pattern.find('}', i) + 1;
      } else {
        path += r.pattern[i++];
      }
    }
    q.path = path;
    q.remote_addr = "127.0.0.1";
    q.headers.emplace("Authorization", "Bearer " + boot);
    return q;
  };
  int checked = 0;
  for (const RouteKey& r : daemon.http().Routes()) {
    SCOPED_TRACE(r.method + " " + r.pattern);
    // A feature this build leaves out (e.g. recognition without OpenCV, as
    // in the sanitizer job) answers every request 501 "not implemented".
    if (daemon.http().Dispatch(make(r, "some-id")).status == 501) continue;
    const bool has_capture = r.pattern.find('{') != std::string::npos;
    for (const std::string& v : bad) {
      for (const std::string& p : params) {
        HttpRequest q = make(r, "some-id");
        q.query.emplace(p, v);
        const HttpResponse out = daemon.http().Dispatch(q);
        EXPECT_GE(out.status, 400) << p << ": " << out.body.substr(0, 200);
        EXPECT_LT(out.status, 500) << p << ": " << out.body.substr(0, 200);
        ++checked;
      }
      for (const char* h : {"X-Robot-Id", "Content-Type", "User-Agent"}) {
        HttpRequest q = make(r, "some-id");
        q.headers.emplace(h, v);
        const HttpResponse out = daemon.http().Dispatch(q);
        EXPECT_GE(out.status, 400) << h << ": " << out.body.substr(0, 200);
        EXPECT_LT(out.status, 500) << h << ": " << out.body.substr(0, 200);
        ++checked;
      }
      {
        HttpRequest q = make(r, "some-id");
        q.headers.find("Authorization")->second = "Bearer " + v;
        const HttpResponse out = daemon.http().Dispatch(q);
        EXPECT_LT(out.status, 500) << out.body.substr(0, 200);
      }
      if (has_capture) {
        const HttpResponse out = daemon.http().Dispatch(make(r, v));
        EXPECT_GE(out.status, 400) << out.body.substr(0, 200);
        EXPECT_LT(out.status, 500) << out.body.substr(0, 200);
        ++checked;
      }
    }
    if (r.method != "GET") {
      for (const std::string& body :
           {std::string("\xC3\xFF{\"name\":1}"),
            std::string("{\"name\":\"") + std::string(100000, 'n') + "\"}",
            std::string("t_s,fn_n,ft_n,v_mm_s,\xC3\n0,1,1,1,1\n"),
            std::string(5000, '\0'),
            // Found by http_body_fuzzer: a number too large for a double
            // threw json::out_of_range, not parse_error (was a 500).
            std::string("2e+11117\x02m\x00{\"/", 15)}) {
        HttpRequest q = make(r, "some-id");
        q.body = body;
        const HttpResponse out = daemon.http().Dispatch(q);
        EXPECT_LT(out.status, 500) << out.body.substr(0, 200);
      }
    }
  }
  EXPECT_GT(checked, 1000);
  for (const char* listing :
       {"/v1/identifications", "/v1/materials", "/v1/fingertips", "/healthz"}) {
    HttpRequest q;
    q.method = "GET";
    q.path = listing;
    q.remote_addr = "127.0.0.1";
    q.headers.emplace("Authorization", "Bearer " + boot);
    EXPECT_EQ(daemon.http().Dispatch(q).status, 200) << listing;
  }
  daemon.Stop();
}

}  // namespace
}  // namespace frictiond
