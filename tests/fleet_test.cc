// A fleet: several frictiond daemons on one throw-away PostgreSQL server.
// Writes through one daemon are served by the others within 1 s
// (LISTEN/NOTIFY), concurrent uploads lose no version, and the faults of
// issue 8: PostgreSQL stopped mid-upload (503 for writes, cached reads
// served, reconnect, no acknowledged write lost) and a daemon killed with
// SIGKILL while another keeps serving.
#include <atomic>
#include <chrono>
#include <cstdio>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/pg_server.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::PgServer;
using testing::TempDir;
using Clock = std::chrono::steady_clock;

std::string SimulatedCsv(std::uint64_t seed, int strokes = 4) {
  testing::SimulationSpec spec;
  spec.strokes = strokes;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

int VersionOf(const httplib::Result& res) {
  if (!res || res->status != 200) return 0;
  const json j = json::parse(res->body, nullptr, false);
  return j.is_object() ? j.value("version", 0) : 0;
}

/// False when this build has no PostgreSQL back end
/// (FRICTIOND_WITH_POSTGRES=OFF or no libpq): its tests are skipped then.
bool PgBackendBuilt() {
  try {
    OpenStore("postgresql://postgres@127.0.0.1:1/x?connect_timeout=1");
  } catch (const std::invalid_argument&) {
    return false;
  } catch (const std::exception&) {
  }
  return true;
}

/// One server for the suite (initdb is slow); a fresh database per test.
class FleetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (PgServer::BinDir().empty() || !PgBackendBuilt()) return;
    shared_ = new PgServer();
    shared_->Start();
  }
  static void TearDownTestSuite() {
    delete shared_;
    shared_ = nullptr;
  }
  void SetUp() override {
    if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
    if (!PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
    static int n = 0;
    url_ = shared_->CreateDatabase("fleet" + std::to_string(++n));
  }
  void TearDown() override { daemons_.clear(); }
  DaemonProcess& StartDaemon() {
    DaemonOptions o;
    o.db = url_;
    o.data = "none";
    o.log_path =
        dir_.path() + "/daemon" + std::to_string(daemons_.size()) + ".log";
    daemons_.push_back(std::make_unique<DaemonProcess>(o));
    daemons_.back()->Start();
    return *daemons_.back();
  }

  static httplib::Result Upload(const DaemonProcess& d,
                                const std::string& id,
                                std::uint64_t seed) {
    auto c = d.MakeClient();
    return c->Post(("/v1/materials/" + id + "/strokes?robot=fleet").c_str(),
                   SimulatedCsv(seed),
                   "text/csv");
  }

  static PgServer* shared_;
  TempDir dir_{"fleet_test"};
  std::string url_;
  std::vector<std::unique_ptr<DaemonProcess>> daemons_;
};

PgServer* FleetTest::shared_ = nullptr;

TEST_F(FleetTest, WriteThroughOneDaemonIsServedByTheOtherWithinOneSecond) {
  DaemonProcess& a = StartDaemon();
  DaemonProcess& b = StartDaemon();
  auto cb = b.MakeClient(5.0, /*keep_alive=*/true);
  double worst_ms = 0;
  for (int round = 1; round <= 4; ++round) {
    // B has the previous version cached (round 1: the 404 path).
    if (round > 1) {
      ASSERT_EQ(VersionOf(cb->Get("/v1/materials/felt/model")), round - 1);
    }
    auto res = Upload(a, "felt", 100 + round);
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    const auto acked = Clock::now();
    int seen = 0;
    while (seen != round && Clock::now() - acked < std::chrono::seconds(3)) {
      seen = VersionOf(cb->Get("/v1/materials/felt/model"));
      if (seen != round)
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    const double ms =
        std::chrono::duration<double, std::milli>(Clock::now() - acked).count();
    ASSERT_EQ(seen, round) << "daemon B still serves version " << seen
                           << " 3 s after A acknowledged " << round;
    worst_ms = std::max(worst_ms, ms);
  }
  std::printf("fleet: write on A served by B after at most %.1f ms\n",
              worst_ms);
  EXPECT_LE(worst_ms, 1000.0);
}

TEST_F(FleetTest, ConcurrentUploadsThroughTwoDaemonsLoseNoVersion) {
  DaemonProcess& a = StartDaemon();
  DaemonProcess& b = StartDaemon();
  constexpr int kEach = 5;
  std::mutex mu;
  std::vector<int> versions;
  std::vector<std::string> failures;
  auto run = [&](DaemonProcess* d, std::uint64_t seed0) {
    for (int i = 0; i < kEach; ++i) {
      auto res = Upload(*d, "shared", seed0 + i);
      std::lock_guard<std::mutex> lock(mu);
      if (!res || res->status != 201) {
        failures.push_back(res ? res->body : "no response");
        continue;
      }
      versions.push_back(json::parse(res->body).value("version", 0));
    }
  };
  std::thread ta(run, &a, 1000);
  std::thread tb(run, &b, 2000);
  ta.join();
  tb.join();
  ASSERT_TRUE(failures.empty()) << failures.front();
  const std::set<int> distinct(versions.begin(), versions.end());
  EXPECT_EQ(distinct.size(), 2u * kEach) << "a version was given twice";
  EXPECT_EQ(*distinct.begin(), 1);
  EXPECT_EQ(*distinct.rbegin(), 2 * kEach);
  for (DaemonProcess* d : {&a, &b}) {
    auto res = d->MakeClient()->Get("/v1/materials/shared/models");
    ASSERT_TRUE(res);
    const json j = json::parse(res->body);
    EXPECT_EQ(j["versions"].size(), 2u * kEach);
    res = d->MakeClient()->Get("/v1/materials/shared/strokes");
    ASSERT_TRUE(res);
  }
}

TEST_F(FleetTest, PostgresStoppedMidUploadThenBack) {
  // The shared server: stopped here, running again at the end.
  PgServer& pg = *shared_;
  DaemonProcess& a = StartDaemon();
  ASSERT_EQ(Upload(a, "cork", 1)->status, 201);
  auto c = a.MakeClient(10.0);
  ASSERT_EQ(VersionOf(c->Get("/v1/materials/cork/model")), 1);  // cached

  // Uploads keep coming while PostgreSQL goes away.
  std::atomic<bool> stop{false};
  std::mutex mu;
  std::vector<int> acked;
  std::vector<int> statuses;
  std::thread writer([&] {
    std::uint64_t seed = 10;
    while (!stop) {
      auto res = Upload(a, "cork", seed++);
      std::lock_guard<std::mutex> lock(mu);
      statuses.push_back(res ? res->status : -1);
      if (res && res->status == 201)
        acked.push_back(json::parse(res->body).value("version", 0));
      if (res && res->status == 503) {
        const json j = json::parse(res->body, nullptr, false);
        EXPECT_EQ(j.value("error", ""), "unavailable") << res->body;
      }
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  pg.Stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  // Writes: 503 JSON. Cached reads: still served.
  auto res = Upload(a, "cork", 99);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 503) << res->body;
  EXPECT_EQ(json::parse(res->body, nullptr, false).value("error", ""),
            "unavailable");
  res = c->Put("/v1/materials/cork", R"({"name":"Cork"})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 503) << res->body;
  res = c->Get("/v1/materials/cork/model");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  stop = true;
  writer.join();
  {
    std::lock_guard<std::mutex> lock(mu);
    EXPECT_FALSE(acked.empty()) << "no upload succeeded before the stop";
    for (int s : statuses) EXPECT_TRUE(s == 201 || s == 503) << "status " << s;
  }

  pg.Start();  // same data and port: the daemon reconnects on next use
  res = Upload(a, "cork", 7);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 201) << res->body;
  const int after = json::parse(res->body).value("version", 0);
  // Every acknowledged version is there, in order, none lost.
  res = c->Get("/v1/materials/cork/models");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  std::set<int> stored;
  const json list = json::parse(res->body);
  for (const json& v : list["versions"]) stored.insert(v.value("version", 0));
  ASSERT_FALSE(stored.empty()) << res->body;
  std::lock_guard<std::mutex> lock(mu);
  for (int v : acked) EXPECT_TRUE(stored.count(v)) << "lost version " << v;
  EXPECT_EQ(static_cast<int>(stored.size()), after);
  EXPECT_EQ(*stored.rbegin(), after);
}

TEST_F(FleetTest, DaemonKilledWhileAnotherKeepsServing) {
  DaemonProcess& a = StartDaemon();
  DaemonProcess& b = StartDaemon();
  ASSERT_EQ(Upload(a, "steel", 1)->status, 201);
  const testing::ExitStatus s = a.Kill();
  EXPECT_EQ(s.signal, SIGKILL) << s.ToString();
  auto cb = b.MakeClient();
  EXPECT_EQ(VersionOf(cb->Get("/v1/materials/steel/model")), 1);
  auto res = Upload(b, "steel", 2);
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 201) << res->body;
  EXPECT_EQ(VersionOf(cb->Get("/v1/materials/steel/model")), 2);
  // A restarted daemon serves what B wrote meanwhile.
  a.Start();
  EXPECT_EQ(VersionOf(a.MakeClient()->Get("/v1/materials/steel/model")), 2);
}

}  // namespace
}  // namespace frictiond
