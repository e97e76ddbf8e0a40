// fleet_lookup, fleet_propagation_p99: two `frictiond` daemons on one
// throw-away PostgreSQL 15 server (started here, like the tests' PgServer).
//
// fleet_lookup: model lookups (GET /v1/materials/{id}/model, keep-alive)
// spread over both daemons, beside one daemon on SQLite with the same
// clients (baseline): ratio = fleet / single SQLite daemon.
// fleet_propagation_p99: ms from an upload acknowledged by daemon A until
// daemon B serves the new version (B polls every ms); goal <= 1000 ms.
//
// Usage: fleet [--seconds S] [--clients N] [--rounds R]
// Needs FRICTIOND_BIN_DIR (bench/run sets it) and PostgreSQL 15 binaries.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/pg_server.h"
#include "frictiond/testing/stroke_simulator.h"

#include "bench_json.h"

namespace frictiond::bench {
namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kLookupGoal = "report (ratio to one SQLite daemon)";
constexpr const char* kPropagationGoal = "<= 1000 ms";

/// Lookups from `clients` threads for `seconds`, thread t on daemons[t % n].
double LookupRate(const std::vector<testing::DaemonProcess*>& daemons,
                  const std::string& path,
                  int clients,
                  double seconds,
                  std::size_t* errors) {
  std::atomic<std::size_t> ok{0}, bad{0};
  std::atomic<bool> go{false};
  std::vector<std::thread> pool;
  const auto duration = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(seconds));
  for (int t = 0; t < clients; ++t) {
    pool.emplace_back([&, t] {
      auto client =
          daemons[static_cast<std::size_t>(t) % daemons.size()]->MakeClient(
              5.0, /*keep_alive=*/true);
      while (!go) std::this_thread::yield();
      const auto end = Clock::now() + duration;
      std::size_t n = 0, e = 0;
      while (Clock::now() < end) {
        auto res = client->Get(path.c_str());
        (res && res->status == 200 ? n : e) += 1;
      }
      ok += n;
      bad += e;
    });
  }
  const auto start = Clock::now();
  go = true;
  for (auto& th : pool) th.join();
  const double s = std::chrono::duration<double>(Clock::now() - start).count();
  *errors = bad;
  return static_cast<double>(ok) / s;
}

int VersionOf(const httplib::Result& res) {
  if (!res || res->status != 200) return 0;
  const auto j = nlohmann::json::parse(res->body, nullptr, false);
  return j.is_object() ? j.value("version", 0) : 0;
}

int Main(int argc, char** argv) {
  double seconds = 5.0;
  int clients = 4;
  int rounds = 40;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else if (flag == "--clients")
      clients = std::atoi(argv[i + 1]);
    else if (flag == "--rounds")
      rounds = std::atoi(argv[i + 1]);
    else
      throw std::invalid_argument("unknown flag " + flag);
  }
  if (!(seconds > 0 && seconds <= 20))
    throw std::invalid_argument("--seconds must be in (0, 20]");
  if (!(clients >= 2 && clients <= 64))
    throw std::invalid_argument("--clients must be in 2..64");
  if (!(rounds >= 5 && rounds <= 1000))
    throw std::invalid_argument("--rounds must be in 5..1000");
  if (testing::PgServer::BinDir().empty())
    throw std::runtime_error(
        "PostgreSQL 15 binaries not found (apt-get install postgresql)");

  testing::TempDir dir("bench_fleet");
  const std::string material = "microtribo-recip";
  const std::string path = "/v1/materials/" + material + "/model";

  // Baseline: one daemon on SQLite with the bundled data.
  double sqlite_rate = 0;
  std::size_t sqlite_errors = 0;
  {
    testing::DaemonOptions o;
    o.db = dir.path() + "/library.db";
    testing::DaemonProcess d(o);
    d.Start();
    LookupRate({&d}, path, clients, std::min(1.0, seconds / 5), &sqlite_errors);
    sqlite_rate = LookupRate({&d}, path, clients, seconds, &sqlite_errors);
    d.Stop(SIGTERM);
  }

  testing::PgServer pg;
  pg.Start();
  const std::string url = pg.CreateDatabase("fleet");
  testing::DaemonOptions oa;
  oa.db = url;  // A loads the bundled data into the empty library
  oa.log_path = dir.path() + "/a.log";
  testing::DaemonProcess a(oa);
  a.Start();
  testing::DaemonOptions ob = oa;
  ob.data = "none";
  ob.log_path = dir.path() + "/b.log";
  testing::DaemonProcess b(ob);
  b.Start();

  std::size_t fleet_errors = 0;
  LookupRate(
      {&a, &b}, path, clients, std::min(1.0, seconds / 5), &fleet_errors);
  const double fleet_rate =
      LookupRate({&a, &b}, path, clients, seconds, &fleet_errors);

  // Propagation: upload via A, poll B until it serves the new version.
  auto ca = a.MakeClient(30.0, true);
  auto cb = b.MakeClient(5.0, true);
  std::vector<double> ms;
  testing::SimulationSpec spec;
  spec.strokes = 2;
  for (int r = 0; r < rounds; ++r) {
    const std::string csv = FormatStrokeCsv(
        testing::SimulateStrokes(spec, static_cast<std::uint64_t>(r + 1)));
    VersionOf(cb->Get("/v1/materials/prop/model"));  // B caches the old one
    auto res = ca->Post("/v1/materials/prop/strokes", csv, "text/csv");
    if (!res || res->status != 201)
      throw std::runtime_error("upload via A failed: " +
                               (res ? res->body.substr(0, 200) : "no answer"));
    const auto acked = Clock::now();
    const int version = nlohmann::json::parse(res->body).value("version", 0);
    while (VersionOf(cb->Get("/v1/materials/prop/model")) < version) {
      if (Clock::now() - acked > std::chrono::seconds(5))
        throw std::runtime_error("B did not serve version " +
                                 std::to_string(version) + " within 5 s");
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - acked)
                     .count());
  }
  std::sort(ms.begin(), ms.end());
  const auto pct = [&](double p) {
    return ms[static_cast<std::size_t>(p * static_cast<double>(ms.size() - 1))];
  };
  a.Stop(SIGTERM);
  b.Stop(SIGTERM);
  pg.Stop();

  std::cerr << "fleet: lookups fleet " << fleet_rate << " req/s ("
            << fleet_errors << " errors), one sqlite daemon " << sqlite_rate
            << " req/s (" << sqlite_errors << " errors); propagation p50 "
            << pct(0.5) << " ms, p99 " << pct(0.99) << " ms, max " << ms.back()
            << " ms\n";
  BenchResult look;
  look.bench = "fleet_lookup";
  look.value = fleet_errors == 0 ? fleet_rate : 0.0;
  look.unit = "req/s";
  look.baseline = sqlite_rate;
  look.baseline_name = "one daemon on SQLite";
  look.goal = kLookupGoal;
  look.note = std::to_string(clients) +
              " keep-alive clients split over 2 daemons on one PostgreSQL 15 "
              "(same clients on one SQLite daemon for the baseline), " +
              std::to_string(static_cast<int>(seconds)) + " s, GET " + path +
              "; all on one machine";
  PrintBenchLine(look);
  BenchResult prop;
  prop.bench = "fleet_propagation_p99";
  prop.value = pct(0.99);
  prop.unit = "ms";
  prop.baseline = 1000.0;
  prop.baseline_name = "goal (1 s)";
  prop.lower_is_better = true;
  prop.goal = kPropagationGoal;
  char p50[32];
  std::snprintf(p50, sizeof p50, "%.2f", pct(0.5));
  prop.note = std::to_string(rounds) +
              " uploads via daemon A; time from A's 201 until daemon B "
              "serves the version (B polled every ms); p50 " +
              std::string(p50) + " ms";
  PrintBenchLine(prop);
  return fleet_errors == 0 ? 0 : 1;
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
                    "fleet_lookup", e.what(), frictiond::bench::kLookupGoal)
                    .c_str());
    std::printf(
        "%s\n",
        frictiond::bench::FormatBenchError("fleet_propagation_p99",
                                           e.what(),
                                           frictiond::bench::kPropagationGoal)
            .c_str());
    return 1;
  }
}
