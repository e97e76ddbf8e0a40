// End to end over LCM (paper 000, Fig. 11): the real frictiond process and
// simulated robots. A robot asks for an unknown material, performs the
// requested stroke from a hidden truth that is both a stochastic model
// (paper 000 eq. (1)) and LuGre dynamics (paper 001; testing::RobotTruth),
// ending it with the LuGre pair the identification_request_v2 asks for,
// streams it with duplicated, reordered and withheld chunks, gets a
// follow-up request when its first stroke covers too little span, and
// receives the fitted model: the stochastic coefficients and the LuGre
// family must match the truth, over LCM and over HTTP. A robot with another
// LuGre truth must get a model that does not match the first truth, and an
// old robot (identification_request_v1, no pair) a model without LuGre. A
// last test restarts the daemon in the middle of a job.
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>

// Eigen (robot_simulator.h) before httplib.h: <resolv.h> (via httplib)
// defines a macro _res that breaks Eigen's product kernels.
#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include "frictiond/crypto/hmac.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/material_reply_v1.hpp"
#include "frictiond/proto/lcm_channels.h"
#include "frictiond/proto/lcm_signed.h"
#include "frictiond/proto/lugre_json.h"
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

// Truth placed away from zero (STYLE §10): a do-nothing fit fails. The
// LuGre part (RobotTruth defaults): mu_s = mu_c + 0.3, v0 2.5 mm/s,
// sigma2 = b1, sigma0 50 /mm, sigma1 0.1 s/mm; at the plan's pair force
// (2.5 N, the middle of 0.5..4.5) theta = [1.05, 0.75, 2.5, 0.004, 50, 0.1].
ft::RobotTruth Truth() {
  ft::RobotTruth t;
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
void ExpectMatchesTruth(const ft::RobotSimResult& r, const ft::RobotTruth& t) {
  const std::pair<const char*, double> truth[] = {
      {"intercept", t.b0}, {"v_mm_s", t.b1}, {"fn_n", t.b2}};
  for (const auto& [term, value] : truth) {
    ASSERT_TRUE(r.coefficients.count(term)) << term;
    const double est = r.coefficients.at(term);
    const double se = r.std_errors.at(term);
    EXPECT_GT(se, 0) << term;
    EXPECT_NEAR(est, value, 5 * se) << term << " (se " << se << ")";
  }
  // eps plus the sensor noise (0.5 % more for the defaults).
  EXPECT_NEAR(r.sigma_eps, t.sigma_eps, 0.15 * t.sigma_eps);
}

std::string ThetaText(const LuGreTheta& theta) {
  std::string s;
  for (int i = 0; i < 6; ++i) {
    char buf[64];
    std::snprintf(buf,
                  sizeof buf,
                  "%s%s %.5g",
                  i ? ", " : "",
                  LuGreParameterName(i),
                  theta[i]);
    s += buf;
  }
  return s;
}

// The LuGre family received over LCM matches the truth at the pair's
// normal force (LuGreTolerances: mu_s, mu_c 3 %, v0 8 %, sigma2 30 %,
// sigma0 10 %, sigma1 100 %; calibrated in tests/robot_truth_test.cc).
void ExpectLuGreMatchesTruth(const ft::RobotSimResult& r,
                             const ft::RobotTruth& t) {
  ASSERT_GE(r.lugre_pairs, 1);
  ASSERT_TRUE(r.has_lugre) << r.lugre_mismatch;
  ASSERT_TRUE(r.lugre_checked);
  const LuGreTheta truth = t.ThetaAt(r.lugre_fn_n);
  for (int i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(r.lugre_truth[i], truth[i]);
  std::cout << "LuGre over LCM at Fn " << r.lugre_fn_n << " N:\n  got   "
            << ThetaText(r.lugre_theta) << "\n  truth " << ThetaText(truth)
            << "\n";
  EXPECT_EQ(r.lugre_mismatch, "");
  EXPECT_EQ(ft::CompareLuGreToTruth(r.lugre_theta, truth), "");
}

// The "lugre" object of GET /v1/materials/{id}/model, parsed.
LuGreFamily HttpLuGre(ft::DaemonProcess& daemon,
                      const std::string& material,
                      int version) {
  auto http = daemon.MakeClient();
  auto res = http->Get("/v1/materials/" + material + "/model");
  if (!res || res->status != 200)
    throw std::runtime_error("GET model of " + material + " failed");
  const auto body = nlohmann::json::parse(res->body);
  if (body["version"] != version)
    throw std::runtime_error("version " + body["version"].dump());
  if (!body.contains("lugre") || !body["lugre"].is_object())
    throw std::runtime_error("no lugre object: " + res->body.substr(0, 400));
  return LuGreFromJson(body["lugre"]);
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
    std::ofstream(keys) << nlohmann::json{
        {"sim-robot", ToHex(Key())},
        {"sim-robot-b",
         ToHex(Key())}}.dump();
    ft::DaemonOptions o;
    o.db = dir.path() + "/lib.db";
    o.data = "none";
    o.lcm = url_;
    // Signed robots read only signed messages; QueryMaterialOnce (no key)
    // reads the unsigned ones.
    o.extra_args = {"--lcm-keys", keys, "--lcm-send-unsigned"};
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
  // An attacker on the group forges, every 20 ms, a "known" reply to the
  // robot's query (a made-up model) and a model update, under the robot's
  // name but without its key: the robot must drop them all.
  std::atomic<bool> forging{true};
  std::thread forger([&] {
    lcm::LCM lcm(url_);
    const std::string fake_key = RandomBytes(32);
    material_reply_v1 reply{};
    reply.request_id = (o.robot + "-" + o.material) + "-q1";
    reply.robot = o.robot;
    reply.material = o.material;
    reply.fingertip = "default";
    reply.status = material_reply_v1::STATUS_KNOWN;
    reply.model.material = o.material;
    reply.model.version = 7;
    reply.model.n_terms = reply.model.n_quantiles = 0;
    reply.model.mu_coulomb = 1.5;
    model_update_v1 update{};
    update.reason = "upload";
    update.model = reply.model;
    while (forging) {
      for (const auto& [channel, bytes] :
           {std::pair<const char*, std::string>{kLcmReplyChannel,
                                                EncodeLcm(reply)},
            {kLcmModelUpdateChannel, EncodeLcm(update)}}) {
        const std::string forged =
            EncodeLcm(SignLcmPayload(bytes, channel, o.robot, fake_key));
        lcm.publish(LcmSignedChannel(channel),
                    forged.data(),
                    static_cast<unsigned>(forged.size()));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  const ft::RobotSimResult r = ft::RunRobotSimulation(o);
  forging = false;
  forger.join();
  ASSERT_TRUE(r.ok) << r.why << "\n" << JoinLog(r) << daemon.ReadLog();
  EXPECT_GT(r.forgeries_dropped, 0) << JoinLog(r);
  EXPECT_EQ(r.reply_status, +material_reply_v1::STATUS_UNKNOWN);
  EXPECT_EQ(r.strokes_sent, 2) << JoinLog(r);
  EXPECT_EQ(r.follow_ups, 1) << JoinLog(r);
  EXPECT_GE(r.resend_requests, 1) << JoinLog(r);
  EXPECT_GE(r.last_span_pct, 50.0);
  EXPECT_EQ(r.model_version, 1);
  ExpectMatchesTruth(r, o.truth);
  // Both requests (stroke 0 and the follow-up) asked for the LuGre pair.
  EXPECT_EQ(r.lugre_pairs, 2) << JoinLog(r);
  EXPECT_DOUBLE_EQ(r.lugre_fn_n, 2.5);
  ExpectLuGreMatchesTruth(r, o.truth);

  // The same model is served over HTTP (one core behind both endpoints).
  auto http = daemon.MakeClient();
  auto res = http->Get("/v1/materials/sim-rubber/model");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const auto body = nlohmann::json::parse(res->body);
  EXPECT_EQ(body["version"], r.model_version);
  EXPECT_DOUBLE_EQ(body["stochastic"]["coefficients"]["fn_n"].get<double>(),
                   r.coefficients.at("fn_n"));
  // ... with the same LuGre family, identified from the pairs: one slow
  // triangle per stroke for the quasi-static step, the newest four fast
  // ones for the dynamic step (LM-2).
  ASSERT_TRUE(body.contains("lugre") && body["lugre"].is_object()) << res->body;
  const LuGreFamily lugre = LuGreFromJson(body["lugre"]);
  for (int i = 0; i < 6; ++i)
    EXPECT_DOUBLE_EQ(lugre.theta[i], r.lugre_theta[i]) << LuGreParameterName(i);
  EXPECT_EQ(ft::CompareLuGreToTruth(lugre.theta, o.truth.ThetaAt(r.lugre_fn_n)),
            "");
  EXPECT_EQ(lugre.variant, "lm2");
  EXPECT_EQ(lugre.strokes_quasi_static, 2);
  EXPECT_EQ(lugre.strokes_dynamic, 4);
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
  // The write is audited: the robot (signed chunks), the version it made.
  bool audited = false;
  for (const AuditEntry& e : store->ListAudit(0, 100, "sim-rubber")) {
    if (e.action != "LCM stroke_chunk_v2") continue;
    audited = true;
    EXPECT_EQ(e.actor, "lcm:" + o.robot);
    EXPECT_EQ(e.role, "robot");
    const auto detail = nlohmann::json::parse(e.detail);
    EXPECT_EQ(detail["status"], 201) << e.detail;
    EXPECT_EQ(detail["version"], r.model_version) << e.detail;
    EXPECT_EQ(detail["job"], r.job_id) << e.detail;
    EXPECT_EQ(detail["signed"], true) << e.detail;
  }
  EXPECT_TRUE(audited);
}

// Two robots at once on one daemon (two names, two keys): one whose truth
// has other LuGre parameters (the same stochastic part), and an old robot
// that acts on identification_request_v1 and performs no pair. The first
// gets a LuGre family near its own truth that fails the first truth's
// tolerances (the check can fail); the second gets a stochastic model and
// no LuGre family.
TEST_F(LcmWorkflowTest, OtherLuGreTruthAndOldRobot) {
  ft::TempDir dir("lcm_workflow_two");
  ft::DaemonProcess daemon(Options(dir));
  daemon.Start();
  ft::RobotSimOptions a;
  a.url = url_;
  a.robot = "sim-robot";
  a.material = "sim-leather";
  a.truth = Truth();
  a.truth.static_excess = 0.15;
  a.truth.v0_mm_s = 3.5;
  a.truth.sigma0_per_mm = 25.0;
  a.seed = 21;
  a.key = Key();
  ft::RobotSimOptions b;
  b.url = url_;
  b.robot = "sim-robot-b";
  b.material = "sim-cotton";
  b.truth = Truth();
  b.seed = 31;
  b.key = Key();
  b.request_v2 = false;
  // Its first stream is lost whole (as a burst of other traffic on the
  // group can drop every datagram): its silence probe recovers it.
  b.lose_first_stream = true;
  ft::RobotSimResult ra, rb;
  std::thread ta([&] { ra = ft::RunRobotSimulation(a); });
  std::thread tb([&] { rb = ft::RunRobotSimulation(b); });
  ta.join();
  tb.join();
  ASSERT_TRUE(ra.ok) << ra.why << "\n" << JoinLog(ra) << daemon.ReadLog();
  ASSERT_TRUE(rb.ok) << rb.why << "\n" << JoinLog(rb) << daemon.ReadLog();
  EXPECT_NE(JoinLog(rb).find("last chunk sent again"), std::string::npos)
      << JoinLog(rb);

  // The other truth is recovered ...
  ExpectMatchesTruth(ra, a.truth);
  ExpectLuGreMatchesTruth(ra, a.truth);
  // ... and is not the first truth: the tolerances tell them apart.
  const LuGreTheta first = Truth().ThetaAt(ra.lugre_fn_n);
  const std::string off = ft::CompareLuGreToTruth(ra.lugre_theta, first);
  std::cout << "other truth against the first: " << off << "\n";
  EXPECT_NE(off.find("mu_s"), std::string::npos) << off;
  EXPECT_NE(off.find("v0_mm_s"), std::string::npos) << off;
  EXPECT_NE(off.find("sigma0_per_mm"), std::string::npos) << off;
  const LuGreFamily served = HttpLuGre(daemon, "sim-leather", 1);
  EXPECT_NE(ft::CompareLuGreToTruth(served.theta, first), "");
  EXPECT_EQ(ft::CompareLuGreToTruth(served.theta, a.truth.ThetaAt(2.5)), "");

  // The old robot: no pair asked on v1, none performed, no LuGre family,
  // and the stochastic model as before.
  EXPECT_EQ(rb.lugre_pairs, 0) << JoinLog(rb);
  EXPECT_FALSE(rb.has_lugre);
  EXPECT_FALSE(rb.lugre_checked);
  ExpectMatchesTruth(rb, b.truth);
  auto http = daemon.MakeClient();
  auto res = http->Get("/v1/materials/sim-cotton/model");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const auto body = nlohmann::json::parse(res->body);
  EXPECT_TRUE(!body.contains("lugre") || body["lugre"].is_null()) << res->body;
  const ft::ExitStatus s = daemon.Stop();
  EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
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
  // The job's plan was stored before the restart: it still asks for the
  // pair, and mu_c follows b0 (0.7 - 0.06 * 2.5 = 0.55).
  ExpectLuGreMatchesTruth(r, o.truth);
  EXPECT_NEAR(r.lugre_truth[LuGreIndex::kMuCoulomb], 0.55, 1e-12);
}

}  // namespace
}  // namespace frictiond
