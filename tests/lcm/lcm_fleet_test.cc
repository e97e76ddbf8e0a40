// Fleet over LCM: a model version made through another daemon of the fleet
// (shared PostgreSQL library) is broadcast as model_update_v1 by this
// daemon too, once per version. PostgreSQL stopped in the middle of an LCM
// stroke upload: the daemon answers error_v1 "(store)", keeps serving,
// stores nothing half, and resumes when the server is back.
#include <algorithm>
#include <chrono>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

// Eigen (robot_simulator.h) before httplib.h: <resolv.h> (via httplib)
// defines a macro _res that breaks Eigen's product kernels.
#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "frictiond/crypto/hmac.h"
#include "frictiond/crypto/lcm_signing.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/storage/store.h"
#include "frictiond/stroke_chunk_v2.hpp"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/pg_server.h"
#include "frictiond/testing/stroke_simulator.h"

#include "lcm_test_inbox.h"
#include "robot_simulator.h"

namespace frictiond {
namespace {

namespace ft = frictiond::testing;

bool PgBackendBuilt() {
  try {
    OpenStore("postgresql://postgres@127.0.0.1:1/x?connect_timeout=1");
  } catch (const std::invalid_argument&) {
    return false;
  } catch (const std::exception&) {
  }
  return true;
}

TEST(LcmFleetTest, RemoteVersionsAreBroadcastOncePerVersion) {
  const std::string lcm_url = ft::MakeTestLcmUrl(41);
  std::string why;
  if (!ft::CheckLcmLoopback(lcm_url, &why)) GTEST_SKIP() << why;
  if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
  if (!ft::PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
  ft::PgServer pg;
  pg.Start();
  const std::string db = pg.CreateDatabase("lcm_fleet");
  ft::TempDir dir("lcm_fleet");
  ft::DaemonOptions oa;
  oa.db = db;
  oa.data = "none";
  oa.lcm = lcm_url;                         // A talks to the robots
  oa.extra_args = {"--lcm-send-unsigned"};  // the inbox reads unsigned
  oa.log_path = dir.path() + "/a.log";
  ft::DaemonProcess a(oa);
  a.Start();
  ft::DaemonOptions ob = oa;
  ob.lcm = "none";  // B only serves HTTP
  ob.log_path = dir.path() + "/b.log";
  ft::DaemonProcess b(ob);
  b.Start();

  ft::LcmInbox inbox(lcm_url);
  ASSERT_TRUE(inbox.good());
  for (int version = 1; version <= 2; ++version) {
    ft::SimulationSpec spec;
    spec.strokes = 4;
    auto res = b.MakeClient()->Post(
        "/v1/materials/felt/strokes",
        FormatStrokeCsv(ft::SimulateStrokes(spec, 50 + version)),
        "text/csv");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
    auto count = [&] {
      int n = 0;
      for (const auto& u : inbox.updates)
        n += u.model.material == "felt" && u.model.version == version;
      return n;
    };
    ASSERT_TRUE(inbox.WaitFor([&] { return count() >= 1; }, 3.0))
        << "daemon A did not broadcast version " << version
        << " made through daemon B\n"
        << a.ReadLog();
    inbox.WaitFor([] { return false; }, 0.5);  // any duplicate arrives now
    EXPECT_EQ(count(), 1) << "version " << version << " broadcast twice";
  }
}

// A stroke upload over LCM with PostgreSQL killed half-way (after some of
// the stroke's chunks were accepted), as a robot would see it.
TEST(LcmFleetTest, PostgresStoppedDuringLcmIngest) {
  const std::string lcm_url = ft::MakeTestLcmUrl(43);
  std::string why;
  if (!ft::CheckLcmLoopback(lcm_url, &why)) GTEST_SKIP() << why;
  if (!PgBackendBuilt()) GTEST_SKIP() << "built without PostgreSQL";
  if (!ft::PgServer::RequireOrSkip()) GTEST_SKIP() << "no PostgreSQL";
  ft::PgServer pg;
  pg.Start();
  const std::string db = pg.CreateDatabase("lcm_outage");
  ft::TempDir dir("lcm_outage");
  const std::string key = RandomBytes(32);
  const std::string keys = dir.path() + "/lcm_keys.json";
  std::ofstream(keys) << "{\"sim-robot\": \"" << ToHex(key) << "\"}";
  ft::DaemonOptions o;
  o.db = db;
  o.data = "none";
  o.lcm = lcm_url;
  // QueryMaterialOnce and the inbox read the unsigned forms.
  o.extra_args = {"--lcm-keys", keys, "--lcm-send-unsigned"};
  o.log_path = dir.path() + "/daemon.log";
  ft::DaemonProcess daemon(o);
  daemon.Start();
  ft::LcmInbox inbox(lcm_url);
  ASSERT_TRUE(inbox.good());

  // An identification job for "outage-felt", and the chunks of its first
  // stroke, signed with the robot's key.
  std::int64_t job_id = 0;
  ASSERT_EQ(ft::QueryMaterialOnce(lcm_url, "outage-felt", "", &job_id),
            +material_reply_v1::STATUS_UNKNOWN);
  ASSERT_GT(job_id, 0);
  ft::SimulationSpec spec;
  spec.strokes = 1;
  const StrokeData stroke = ft::SimulateStrokes(spec, 3);
  constexpr int kChunk = 100;
  const int n = static_cast<int>(stroke.size());
  const int total = (n + kChunk - 1) / kChunk;
  ASSERT_GE(total, 3);
  auto send_chunk = [&](int k) {
    stroke_chunk_v2 c{};
    c.job_id = job_id;
    c.stroke = 0;
    c.robot = "sim-robot";
    c.material = "outage-felt";
    c.fingertip = "default";
    c.seq = k;
    c.total_chunks = total;
    c.last = k == total - 1;
    const int b = k * kChunk;
    const int e = std::min(n, b + kChunk);
    c.t_s.assign(stroke.t_s.begin() + b, stroke.t_s.begin() + e);
    c.fn_n.assign(stroke.fn_n.begin() + b, stroke.fn_n.begin() + e);
    c.ft_n.assign(stroke.ft_n.begin() + b, stroke.ft_n.begin() + e);
    c.v_mm_s.assign(stroke.v_mm_s.begin() + b, stroke.v_mm_s.begin() + e);
    c.n_samples = e - b;
    SignLcmMessage(&c, key);
    inbox.lcm().publish(kLcmSignedStrokeChannel, &c);
  };
  // The first chunks arrive while the server is up ...
  for (int k = 0; k + 1 < total; ++k) send_chunk(k);
  ASSERT_TRUE(inbox.WaitFor([&] {
    for (const auto& p : inbox.progress)
      if (p.job_id == job_id && p.chunks_received >= total - 1) return true;
    return false;
  })) << daemon.ReadLog();
  // ... then it dies (SIGQUIT: no clean shutdown), and the stroke's last
  // chunk arrives.
  pg.Crash();
  const std::size_t errors_before = inbox.errors.size();
  send_chunk(total - 1);
  ASSERT_TRUE(
      inbox.WaitFor([&] { return inbox.errors.size() > errors_before; }, 10.0))
      << "no error_v1 for a chunk during the outage\n"
      << daemon.ReadLog();
  const error_v1& e = inbox.errors[errors_before];
  EXPECT_EQ(e.robot, "sim-robot");
  EXPECT_EQ(e.job_id, job_id);
  EXPECT_TRUE(e.field == "(store)" || e.field == "store")
      << e.field << ": " << e.reason;
  EXPECT_NE(e.reason.find("unavailable"), std::string::npos) << e.reason;
  // A query during the outage is answered (an error reply), not dropped.
  std::int64_t none = 0;
  EXPECT_EQ(ft::QueryMaterialOnce(lcm_url, "outage-cork", "", &none),
            +material_reply_v1::STATUS_ERROR);
  // The daemon is alive (HTTP and metrics) and counted the outage.
  auto res = daemon.MakeClient()->Get("/metrics");
  ASSERT_TRUE(res) << daemon.ReadLog();
  EXPECT_NE(
      res->body.find("frictiond_lcm_dropped_total{reason=\"unavailable\"}"),
      std::string::npos);

  // The server comes back: the robot sends the stroke again and the
  // daemon continues the same job as if nothing happened.
  pg.Start();
  for (int k = 0; k < total; ++k) send_chunk(k);
  ASSERT_TRUE(inbox.WaitFor(
      [&] {
        for (const auto& p : inbox.progress)
          if (p.job_id == job_id && p.stroke == 0 &&
              (p.state == "stroking" || p.state == "enough_coverage" ||
               p.state == "fitted") &&
              p.span_pct >= 0)
            return true;
        return false;
      },
      15.0))
      << "the stroke was not taken after the server came back\n"
      << daemon.ReadLog();
  // Nothing half-stored: no model version for the material from the
  // failed attempt, and the job's state is one the store wrote whole.
  auto c = daemon.MakeClient(10.0);
  res = c->Get("/v1/materials/outage-felt/models");
  ASSERT_TRUE(res);
  if (res->status == 200) {
    const auto j = nlohmann::json::parse(res->body);
    EXPECT_LE(j["versions"].size(), 1u) << res->body;
  } else {
    EXPECT_EQ(res->status, 404) << res->body;
  }
  res = c->Get("/v1/identifications");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;

  // And a whole robot conversation works again.
  ft::RobotSimOptions ro;
  ro.url = lcm_url;
  ro.material = "outage-rubber";
  ro.key = key;
  ro.seed = 5;
  ro.timeout_s = 60.0;
  const ft::RobotSimResult r = ft::RunRobotSimulation(ro);
  std::string log;
  for (const auto& line : r.log) log += line + "\n";
  ASSERT_TRUE(r.ok) << r.why << "\n" << log << daemon.ReadLog();
  EXPECT_GE(r.model_version, 1);
}

}  // namespace
}  // namespace frictiond
