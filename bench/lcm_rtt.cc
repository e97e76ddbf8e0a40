// lcm_rtt_p99, lcm_rtt_p50: query -> reply round trip over LCM against a
// real `frictiond` (bundled data, so the material is known and the reply
// carries its model) versus a bare LCM ping-pong with messages of exactly
// the same sizes (the floor: an echo thread with its own LCM instance that
// does nothing but answer). Sequential round trips, interleaved in blocks so
// both see the same machine load. Needs multicast on loopback: bench/run
// runs this program in a private network namespace (docs/lcm.md).
//
// Usage: lcm_rtt [--rounds N] [--material ID]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <unistd.h>

#include "frictiond/material_query_v1.hpp"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/testing/daemon_process.h"

#include "bench_json.h"

namespace frictiond::bench {
namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kPing = "FRICTIOND_BENCH_PING";
constexpr const char* kPong = "FRICTIOND_BENCH_PONG";
constexpr const char* kGoal = "p99 <= 2x bare LCM ping-pong";

// Waits for replies; `want` is the request id (daemon) or the ping number.
struct Receiver {
  std::string want;
  bool got = false;
  int reply_bytes = 0;
  int8_t status = -1;
  std::string reason;
  void OnReply(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    material_reply_v1 r;
    if (r.decode(rbuf->data, 0, rbuf->data_size) < 0) return;
    if (r.request_id != want) return;
    got = true;
    status = r.status;
    reason = r.reason;
    reply_bytes = static_cast<int>(rbuf->data_size);
  }
  void OnPong(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    if (rbuf->data_size >= want.size() &&
        std::memcmp(rbuf->data, want.data(), want.size()) == 0)
      got = true;
  }
};

double Percentile(std::vector<double> x, double p) {
  std::sort(x.begin(), x.end());
  return x[static_cast<std::size_t>(p * static_cast<double>(x.size() - 1))];
}

int Run(int rounds, const std::string& material) {
  const std::string url =
      "udpm://239.255.76.67:" + std::to_string(21000 + getpid() % 20000) +
      "?ttl=0";
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    const std::string why =
        "cannot create LCM provider " + url +
        " (needs multicast on lo; bench/run runs this in `unshare -n`)";
    std::printf("%s\n%s\n",
                FormatBenchError("lcm_rtt_p99", why, kGoal).c_str(),
                FormatBenchError("lcm_rtt_p50", why, kGoal).c_str());
    return 1;
  }
  testing::TempDir dir("lcm_rtt");
  testing::DaemonOptions options;
  options.db = dir.path() + "/lib.db";
  options.lcm = url;
  // The unsigned reply (the signed path adds one HMAC per message).
  options.extra_args = {"--lcm-send-unsigned"};
  testing::DaemonProcess daemon(options);
  daemon.Start();

  Receiver rx;
  lcm.subscribe(kLcmReplyChannel, &Receiver::OnReply, &rx);
  lcm.subscribe(kPong, &Receiver::OnPong, &rx);

  material_query_v1 q;
  q.utime = 0;
  q.robot = "bench";
  q.material = material;
  q.fingertip = "default";
  q.image_size = 0;
  auto query_once = [&](int i) -> double {
    q.request_id = "bench-" + std::to_string(i);
    rx.want = q.request_id;
    rx.got = false;
    const auto t0 = Clock::now();
    lcm.publish(kLcmQueryChannel, &q);
    while (!rx.got) {
      if (lcm.handleTimeout(1000) <= 0) return std::nan("");
    }
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  // Warm up and learn the sizes the floor must use.
  for (int i = 0; i < 50; ++i) {
    if (std::isnan(query_once(-1 - i))) {
      std::printf(
          "%s\n",
          FormatBenchError("lcm_rtt_p99", "no reply from the daemon", kGoal)
              .c_str());
      return 1;
    }
  }
  if (rx.status != material_reply_v1::STATUS_KNOWN) {
    std::printf(
        "%s\n",
        FormatBenchError("lcm_rtt_p99",
                         "material " + material + " not known: " + rx.reason,
                         kGoal)
            .c_str());
    return 1;
  }
  q.request_id = "bench-0000000";
  const int query_bytes = q.getEncodedSize();
  const int reply_bytes = rx.reply_bytes;

  // The floor: an echo with its own LCM instance answering a ping of the
  // query's size with a pong of the reply's size (the ping's first bytes).
  std::atomic<bool> stop{false};
  std::thread echo([&] {
    lcm::LCM e(url);
    struct Echo {
      lcm::LCM* lcm;
      std::vector<char> pong;
      void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
        std::memcpy(pong.data(),
                    rbuf->data,
                    std::min<std::size_t>(rbuf->data_size, pong.size()));
        lcm->publish(kPong, pong.data(), static_cast<unsigned>(pong.size()));
      }
    } handler{&e, std::vector<char>(static_cast<std::size_t>(reply_bytes))};
    e.subscribe(kPing, &Echo::On, &handler);
    while (!stop) e.handleTimeout(50);
  });
  std::vector<char> ping(static_cast<std::size_t>(query_bytes), 'x');
  auto ping_once = [&](int i) -> double {
    const std::string tag = "p" + std::to_string(i) + ":";
    std::memcpy(ping.data(), tag.data(), tag.size());
    rx.want = tag;
    rx.got = false;
    const auto t0 = Clock::now();
    lcm.publish(kPing, ping.data(), static_cast<unsigned>(ping.size()));
    while (!rx.got) {
      if (lcm.handleTimeout(1000) <= 0) return std::nan("");
    }
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  for (int i = 0; i < 50; ++i) ping_once(-1 - i);

  std::vector<double> daemon_s, floor_s;
  const int block = 100;
  for (int done = 0; done < rounds; done += block) {
    for (int i = 0; i < block; ++i) {
      const double t = query_once(done + i);
      if (!std::isnan(t)) daemon_s.push_back(t);
    }
    for (int i = 0; i < block; ++i) {
      const double t = ping_once(done + i);
      if (!std::isnan(t)) floor_s.push_back(t);
    }
  }
  stop = true;
  echo.join();
  daemon.Stop();
  if (daemon_s.size() < 100 || floor_s.size() < 100) {
    std::printf(
        "%s\n",
        FormatBenchError("lcm_rtt_p99", "too many lost round trips", kGoal)
            .c_str());
    return 1;
  }
  const std::string note =
      std::to_string(daemon_s.size()) + " sequential round trips each; " +
      "query " + std::to_string(query_bytes) + " B, reply " +
      std::to_string(reply_bytes) + " B; floor: echo thread, same sizes; " +
      std::to_string(rounds - static_cast<int>(daemon_s.size())) +
      " daemon and " +
      std::to_string(rounds - static_cast<int>(floor_s.size())) +
      " floor round trips lost (1 s timeout)";
  for (const double p : {0.99, 0.50}) {
    BenchResult r;
    r.bench = p > 0.9 ? "lcm_rtt_p99" : "lcm_rtt_p50";
    r.value = Percentile(daemon_s, p) * 1e3;
    r.unit = "ms";
    r.baseline = Percentile(floor_s, p) * 1e3;
    r.baseline_name = "bare LCM ping-pong of the same message sizes";
    r.lower_is_better = true;
    r.goal = p > 0.9 ? kGoal : "p50 <= 2x bare LCM ping-pong";
    r.note = note;
    PrintBenchLine(r);
  }
  return 0;
}

}  // namespace
}  // namespace frictiond::bench

int main(int argc, char** argv) {
  int rounds = 2000;
  std::string material = "microtribo-recip";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--rounds") rounds = std::max(100, std::atoi(argv[i + 1]));
    if (a == "--material") material = argv[i + 1];
  }
  try {
    return frictiond::bench::Run(rounds, material);
  } catch (const std::exception& e) {
    std::printf(
        "%s\n",
        frictiond::bench::FormatBenchError("lcm_rtt_p99", e.what()).c_str());
    return 1;
  }
}
