// End to end over LCM (paper 000, Fig. 11): the real frictiond process and
// a simulated robot. The robot asks for an unknown material, performs the
// requested stroke from a hidden true model, streams it with duplicated,
// reordered and withheld chunks, gets a follow-up request when its first
// stroke covers too little span, and receives the fitted model, which must
// match the truth. A second test restarts the daemon in the middle of a job.
#include <cmath>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "frictiond/crypto/hmac.h"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/storage/store.h"
#include "frictiond/testing/daemon_process.h"

#include "robot_simulator.h"

namespace frictiond {
namespace {

namespace ft = frictiond::testing;

std::string JoinLog(const ft::RobotSimResult& r) {
  std::string s;
  for (const std::string& line : r.log) s += "  " + line + "\n";
  return s;
}

// Truth placed away from zero (STYLE §10): a do-nothing fit fails.
ft::SimulationSpec Truth() {
  ft::SimulationSpec t;
  t.b0 = 0.9;
  t.b1 = 0.004;
  t.b2 = -0.06;
  t.sigma_eps = 0.05;
  t.strokes = 16;
  t.rate_hz = 200.0;
  return t;
}

// |estimate - truth| within 5 standard errors (white noise: the OLS
// standard errors are valid, so this fails with probability < 1e-5 per
// coefficient), and at most a fixed absolute bound too.
void ExpectMatchesTruth(const ft::RobotSimResult& r,
                        const ft::SimulationSpec& t) {
  const std::pair<const char*, double> truth[] = {
      {"intercept", t.b0}, {"v_mm_s", t.b1}, {"fn_n", t.b2}};
  for (const auto& [term, value] : truth) {
    ASSERT_TRUE(r.coefficients.count(term)) << term;
    const double est = r.coefficients.at(term);
    const double se = r.std_errors.at(term);
    EXPECT_GT(se, 0) << term;
    EXPECT_NEAR(est, value, 5 * se) << term << " (se " << se << ")";
  }
  EXPECT_NEAR(r.sigma_eps, t.sigma_eps, 0.15 * t.sigma_eps);
}

class LcmWorkflowTest : public ::testing::Test {
 protected:
  void SetUp() override {
    url_ = ft::MakeTestLcmUrl(23);
    std::string why;
    if (!ft::CheckLcmLoopback(url_, &why)) GTEST_SKIP() << why;
  }
  // The daemon knows the simulated robot's key (signed writes only).
  ft::DaemonOptions Options(const ft::TempDir& dir) const {
    const std::string keys = dir.path() + "/lcm_keys.json";
    std::ofstream(keys) << nlohmann::json{{"sim-robot", ToHex(Key())}}.dump();
    ft::DaemonOptions o;
    o.db = dir.path() + "/lib.db";
    o.data = "none";
    o.lcm = url_;
    o.extra_args = {"--lcm-keys", keys};
    return o;
  }
  static std::string Key() { return RandomKeyOnce(); }
  static const std::string& RandomKeyOnce() {
    static const std::string k = RandomBytes(32);
    return k;
  }
  std::string url_;
};

TEST_F(LcmWorkflowTest, UnknownMaterialIsIdentifiedFromASimulatedStroke) {
  ft::TempDir dir("lcm_workflow");
  ft::DaemonProcess daemon(Options(dir));
  daemon.Start();
  ft::RobotSimOptions o;
  o.url = url_;
  o.material = "sim-rubber";
  o.truth = Truth();
  o.seed = 11;
  o.duplicate = true;
  o.reorder = true;
  o.hold_back = true;
  o.narrow_first_stroke = true;
  o.key = Key();
  const ft::RobotSimResult r = ft::RunRobotSimulation(o);
  ASSERT_TRUE(r.ok) << r.why << "\n" << JoinLog(r) << daemon.ReadLog();
  EXPECT_EQ(r.reply_status, +material_reply_v1::STATUS_UNKNOWN);
  EXPECT_EQ(r.strokes_sent, 2) << JoinLog(r);
  EXPECT_EQ(r.follow_ups, 1) << JoinLog(r);
  EXPECT_GE(r.resend_requests, 1) << JoinLog(r);
  EXPECT_GE(r.last_span_pct, 50.0);
  EXPECT_EQ(r.model_version, 1);
  ExpectMatchesTruth(r, o.truth);

  // The same model is served over HTTP (one core behind both endpoints).
  auto http = daemon.MakeClient();
  auto res = http->Get("/v1/materials/sim-rubber/model");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const auto body = nlohmann::json::parse(res->body);
  EXPECT_EQ(body["version"], r.model_version);
  EXPECT_DOUBLE_EQ(body["stochastic"]["coefficients"]["fn_n"].get<double>(),
                   r.coefficients.at("fn_n"));
  // The duplicated chunks repeated signed bytes: dropped as replays, and
  // counted; nothing was forged.
  auto metrics = http->Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("frictiond_lcm_signed_accepted_total "),
            std::string::npos);
  EXPECT_EQ(
      metrics->body.find("frictiond_lcm_dropped_total{reason=\"replayed\"} 0"),
      std::string::npos)
      << metrics->body;
  EXPECT_NE(
      metrics->body.find("frictiond_lcm_dropped_total{reason=\"forged\"} 0"),
      std::string::npos)
      << metrics->body;
  // A known material now answers with the model.
  std::int64_t job = -1;
  EXPECT_EQ(ft::QueryMaterialOnce(url_, "sim-rubber", "default", &job),
            +material_reply_v1::STATUS_KNOWN);
  const ft::ExitStatus s = daemon.Stop();
  EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
  auto store = OpenStore(dir.path() + "/lib.db");
  auto j = store->GetJob(r.job_id);
  ASSERT_TRUE(j);
  EXPECT_EQ(j->state, "fitted");
  EXPECT_NE(j->detail.find("span"), std::string::npos) << j->detail;
  EXPECT_EQ(store->ListStrokes("sim-rubber", "default").size(), 1u);
}

TEST_F(LcmWorkflowTest, JobSurvivesADaemonRestart) {
  ft::TempDir dir("lcm_restart");
  std::int64_t job = 0;
  {
    ft::DaemonProcess daemon(Options(dir));
    daemon.Start();
    ASSERT_EQ(ft::QueryMaterialOnce(url_, "sim-cork", "default", &job),
              +material_reply_v1::STATUS_UNKNOWN)
        << daemon.ReadLog();
    ASSERT_GT(job, 0);
    const ft::ExitStatus s = daemon.Stop();
    EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
  }
  {
    auto store = OpenStore(dir.path() + "/lib.db");
    auto j = store->GetJob(job);
    ASSERT_TRUE(j);
    EXPECT_EQ(j->state, "requested");
  }
  ft::DaemonProcess daemon(Options(dir));
  daemon.Start();
  // The restarted daemon still has the open job: the robot continues it.
  ft::RobotSimOptions o;
  o.url = url_;
  o.material = "sim-cork";
  o.truth = Truth();
  o.truth.b0 = 0.7;
  o.seed = 5;
  o.key = Key();
  const ft::RobotSimResult r = ft::RunRobotSimulation(o);
  ASSERT_TRUE(r.ok) << r.why << "\n" << JoinLog(r) << daemon.ReadLog();
  EXPECT_EQ(r.job_id, job);
  EXPECT_EQ(r.follow_ups, 0);
  ExpectMatchesTruth(r, o.truth);
}

}  // namespace
}  // namespace frictiond
