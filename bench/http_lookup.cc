// http_lookup, http_lookup_p50, http_lookup_p99: model lookups (GET
// /v1/materials/{id}/model) over HTTP keep-alive on loopback against a real
// `frictiond` started on a temporary database with the bundled data, versus the
// same lookup done in-process straight from SQLite (Store::GetLatestModel on
// the same file).
//
// Usage: http_lookup [--seconds S] [--clients N] [--material ID]
// Needs FRICTIOND_BIN_DIR (bench/run sets it to build/bin).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <signal.h>

#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"

#include "bench_json.h"

namespace frictiond::bench {
namespace {

using Clock = std::chrono::steady_clock;

struct LoadResult {
  std::size_t ok = 0;
  std::size_t errors = 0;
  double seconds = 0.0;
  std::vector<double> latencies_s;  ///< of successful operations

  double rate() const {
    return seconds > 0 ? static_cast<double>(ok) / seconds : 0;
  }
  double Percentile(double p) {
    if (latencies_s.empty()) return std::nan("");
    std::sort(latencies_s.begin(), latencies_s.end());
    const auto k = static_cast<std::size_t>(
        p * static_cast<double>(latencies_s.size() - 1));
    return latencies_s[k];
  }
};

/// Runs `op` (returns success) from `threads` threads for `seconds`.
template <typename MakeOp>
LoadResult RunLoad(int threads, double seconds, MakeOp make_op) {
  std::vector<LoadResult> parts(static_cast<std::size_t>(threads));
  std::vector<std::thread> pool;
  std::atomic<bool> go{false};
  const auto duration = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(seconds));
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      auto op = make_op();
      LoadResult& part = parts[static_cast<std::size_t>(t)];
      part.latencies_s.reserve(1 << 20);
      while (!go.load()) std::this_thread::yield();
      const auto start = Clock::now();
      const auto end = start + duration;
      auto now = start;
      while (now < end) {
        const auto t0 = now;
        const bool ok = op();
        now = Clock::now();
        if (ok) {
          ++part.ok;
          part.latencies_s.push_back(
              std::chrono::duration<double>(now - t0).count());
        } else {
          ++part.errors;
        }
      }
      part.seconds = std::chrono::duration<double>(now - start).count();
    });
  }
  go.store(true);
  for (auto& th : pool) th.join();
  LoadResult all;
  for (LoadResult& p : parts) {
    all.ok += p.ok;
    all.errors += p.errors;
    all.seconds = std::max(all.seconds, p.seconds);
    all.latencies_s.insert(
        all.latencies_s.end(), p.latencies_s.begin(), p.latencies_s.end());
  }
  return all;
}

int Main(int argc, char** argv) {
  double seconds = 10.0;
  int clients = 2;
  std::string material = "microtribo-recip";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else if (flag == "--clients")
      clients = std::atoi(argv[i + 1]);
    else if (flag == "--material")
      material = argv[i + 1];
    else
      throw std::invalid_argument("unknown flag " + flag);
  }
  if (!(seconds > 0 && seconds <= 20))
    throw std::invalid_argument("--seconds must be in (0, 20]");
  if (!(clients >= 1 && clients <= 64))
    throw std::invalid_argument("--clients must be in 1..64");

  testing::TempDir dir("bench_http_lookup");
  testing::DaemonOptions options;
  options.db = dir.path() + "/library.db";  // bundled data: daemon default
  testing::DaemonProcess daemon(options);
  daemon.Start();
  const std::string path = "/v1/materials/" + material + "/model";
  {
    auto probe = daemon.MakeClient();
    auto res = probe->Get(path.c_str());
    if (!res || res->status != 200)
      throw std::runtime_error(
          "GET " + path + " does not answer 200: " +
          (res ? res->body.substr(0, 200) : "no response"));
    std::cerr << "http_lookup: model document " << res->body.size()
              << " bytes\n";
  }
  auto make_http_op = [&] {
    auto client =
        daemon.MakeClient(/*read_timeout_s=*/5.0, /*keep_alive=*/true);
    return
        [client = std::shared_ptr<httplib::Client>(std::move(client)), path] {
          auto res = client->Get(path.c_str());
          return res && res->status == 200 && !res->body.empty();
        };
  };
  RunLoad(clients, std::min(1.0, seconds / 5), make_http_op);  // warm-up
  LoadResult http = RunLoad(clients, seconds, make_http_op);
  const testing::ExitStatus stopped = daemon.Stop(SIGTERM);
  if (!(stopped.exited && stopped.code == 0))
    std::cerr << "http_lookup: daemon stop: " << stopped.ToString() << "\n";

  // Baseline: the same lookup in-process, straight from SQLite.
  std::unique_ptr<Store> store = OpenStore(options.db);
  auto make_sqlite_op = [&] {
    return [&store, &material] {
      auto record = store->GetLatestModel(material, "default");
      return record.has_value() && !record->json.empty();
    };
  };
  RunLoad(clients, std::min(1.0, seconds / 5), make_sqlite_op);  // warm-up
  LoadResult sqlite = RunLoad(clients, seconds, make_sqlite_op);

  const double http_p50 = http.Percentile(0.50) * 1e3;
  const double http_p99 = http.Percentile(0.99) * 1e3;
  const double sqlite_p50 = sqlite.Percentile(0.50) * 1e3;
  const double sqlite_p99 = sqlite.Percentile(0.99) * 1e3;
  std::cerr << "http_lookup: http " << http.ok << " ok, " << http.errors
            << " errors in " << http.seconds << " s; p50 " << http_p50
            << " ms, p99 " << http_p99 << " ms, max "
            << http.Percentile(1.0) * 1e3 << " ms\n"
            << "http_lookup: sqlite " << sqlite.ok << " ok, " << sqlite.errors
            << " errors in " << sqlite.seconds << " s; p50 " << sqlite_p50
            << " ms, p99 " << sqlite_p99 << " ms\n";
  const std::string how =
      std::to_string(clients) +
      " client threads, HTTP/1.1 keep-alive on 127.0.0.1, " +
      std::to_string(static_cast<int>(seconds)) + " s, GET " + path + "; " +
      std::to_string(http.errors) + " errors";
  BenchResult rate;
  rate.bench = "http_lookup";
  rate.value = http.errors == 0 ? http.rate() : 0.0;
  rate.unit = "req/s";
  rate.baseline = sqlite.rate();
  rate.baseline_name = "in-process sqlite read";
  rate.goal = ">= 15000 req/s";
  rate.note = how;
  PrintBenchLine(rate);
  BenchResult p50;
  p50.bench = "http_lookup_p50";
  p50.value = http_p50;
  p50.unit = "ms";
  p50.baseline = sqlite_p50;
  p50.baseline_name = "in-process sqlite read";
  p50.lower_is_better = true;
  p50.goal = "report (p99 goal <= 0.5 ms)";
  p50.note = "p50 client-side round trip; " + how;
  PrintBenchLine(p50);
  BenchResult p99;
  p99.bench = "http_lookup_p99";
  p99.value = http_p99;
  p99.unit = "ms";
  p99.baseline = sqlite_p99;
  p99.baseline_name = "in-process sqlite read";
  p99.lower_is_better = true;
  p99.goal = "<= 0.5 ms";
  p99.note = "p99 client-side round trip; " + how;
  PrintBenchLine(p99);
  return http.errors == 0 ? 0 : 1;
}

}  // namespace
}  // namespace frictiond::bench

int main(int argc, char** argv) {
  signal(SIGPIPE, SIG_IGN);
  try {
    return frictiond::bench::Main(argc, argv);
  } catch (const std::exception& e) {
    std::printf("%s\n",
                frictiond::bench::FormatBenchError(
                    "http_lookup", e.what(), ">= 15000 req/s")
                    .c_str());
    std::printf("%s\n",
                frictiond::bench::FormatBenchError(
                    "http_lookup_p50", e.what(), "report (p99 goal <= 0.5 ms)")
                    .c_str());
    std::printf("%s\n",
                frictiond::bench::FormatBenchError(
                    "http_lookup_p99", e.what(), "<= 0.5 ms")
                    .c_str());
    return 1;
  }
}
