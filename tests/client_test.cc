// The C++ client (client/include/frictiond/client/*.h) and the `friction`
// CLI against the real `frictiond` binary on loopback (issue 3 item 5):
// one daemon with an empty library (--data none) for the suite; strokes are
// simulated from known truth (stroke_simulator, LuGre simulator).
#include "frictiond/client/client.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>

#include "frictiond/client/lugre_client.h"
#include "frictiond/estimators/breakaway.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::ExitStatus;
using testing::TempDir;

/// Simulated strokes (SimulationSpec defaults: b0 = 0.9, b1 = 0.004 per
/// mm/s, b2 = -0.06 per N) as stroke CSV text.
std::string SimulatedCsv(std::uint64_t seed, int strokes = 8) {
  testing::SimulationSpec spec;
  spec.strokes = strokes;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

// LuGre truth of docs/lugre.md (as server/test/lugre_routes_test.cc).
LuGreTheta LuGreTruth() {
  return MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1);
}

/// A low-acceleration stroke (0 -> 20 -> 0 mm/s at 2 mm/s^2) and, 10 s later,
/// a high-acceleration one (0 -> 10 -> 0 mm/s at 20 mm/s^2), simulated from
/// LuGreTruth() at 200 Hz, Fn = 5 N, noise 0.005 on mu (seeded).
std::string LuGreTwoStrokeCsv() {
  constexpr double kRate = 200.0, kFn = 5.0;
  StrokeData d;
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, 0.005);
  auto append = [&](const std::function<double(double)>& v_of_t,
                    double t0_s,
                    double duration_s) {
    const int n = static_cast<int>(std::round(duration_s * kRate)) + 1;
    Eigen::VectorXd t(n), v(n);
    for (int k = 0; k < n; ++k) {
      t[k] = k / kRate;
      v[k] = v_of_t(t[k]);
    }
    const VelocityDrivenResult r =
        SimulateVelocityDriven(LuGreTruth(), t, v, 0.0);
    EXPECT_EQ(r.status, SimulationStatus::kOk) << r.why;
    for (int k = 0; k < n; ++k) {
      d.t_s.push_back(t0_s + t[k]);
      d.fn_n.push_back(kFn);
      d.ft_n.push_back(std::abs(r.mu[k] + gauss(rng)) * kFn);
      d.v_mm_s.push_back(std::abs(v[k]));
    }
  };
  append([](double t) { return t < 10 ? 2.0 * t : 40.0 - 2.0 * t; }, 0, 20);
  append([](double t) { return t < 0.5 ? 20.0 * t : 20.0 - 20.0 * t; }, 30, 1);
  return FormatStrokeCsv(d);
}

struct CliRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

class ClientTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("client_test");
    DaemonOptions options;
    options.db = dir_->path() + "/library.db";
    options.data = "none";
    daemon_ = new DaemonProcess(options);
    daemon_->Start();
  }
  static void TearDownTestSuite() {
    const ExitStatus s = daemon_->Stop(SIGTERM);
    EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
    delete daemon_;
    delete dir_;
    daemon_ = nullptr;
    dir_ = nullptr;
  }

  static FrictionClient MakeClient() {
    ClientOptions o;
    o.base_url = daemon_->base_url();
    o.robot = "client-test";
    o.token = daemon_->options().operator_token;
    return FrictionClient(o);
  }

  /// Writes `text` to a file in the suite's directory; returns its path.
  static std::string Write(const std::string& name, const std::string& text) {
    const std::string path = dir_->path() + "/" + name;
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }

  /// Runs `friction ARGS` with --server pointing at the daemon.
  static CliRun Friction(const std::string& args) {
    CliRun r;
    const std::string out = dir_->path() + "/cli.out";
    const std::string err = dir_->path() + "/cli.err";
    const std::string cmd = testing::BinaryPath("friction") + " --server " +
                            daemon_->base_url() + " --token " +
                            daemon_->options().operator_token + " " + args +
                            " >" + out + " 2>" + err;
    const int status = std::system(cmd.c_str());
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = ReadAll(out);
    r.err = ReadAll(err);
    return r;
  }

  static TempDir* dir_;
  static DaemonProcess* daemon_;
};

TempDir* ClientTest::dir_ = nullptr;
DaemonProcess* ClientTest::daemon_ = nullptr;

TEST_F(ClientTest, UploadListFetchAndPredictLocallyLikeTheServer) {
  FrictionClient client = MakeClient();
  const UploadReply up = client.UploadStrokes("cl-felt", SimulatedCsv(11));
  EXPECT_EQ(up.version, 1) << up.body.dump();
  EXPECT_GT(up.stroke_id, 0) << up.body.dump();
  // A second upload with a query parameter adds a version.
  const UploadReply up2 = client.UploadStrokes(
      "cl-felt", SimulatedCsv(12), {{"slip_peak_mm_s", "10"}});
  EXPECT_EQ(up2.version, 2) << up2.body.dump();

  bool listed = false;
  for (const MaterialInfo& m : client.ListMaterials()) {
    if (m.id != "cl-felt") continue;
    listed = true;
    ASSERT_TRUE(m.latest_version.has_value());
    EXPECT_EQ(*m.latest_version, 2);
  }
  EXPECT_TRUE(listed) << "cl-felt missing from ListMaterials";

  const ModelSet model = client.FetchModel("cl-felt");
  EXPECT_EQ(model.material, "cl-felt");
  EXPECT_EQ(model.version, 2);
  ASSERT_TRUE(model.stochastic.has_value());
  const ModelSet first = client.FetchModel("cl-felt", 1);
  EXPECT_EQ(first.version, 1);

  // Known truth: b0 = 0.9, b1 = 0.004, b2 = -0.06; a do-nothing model
  // (mu constant) is 0.06 * 3 N = 0.18 off across the Fn range.
  for (const auto& [fn, v] :
       {std::pair{1.0, 20.0}, std::pair{2.5, 50.0}, std::pair{4.0, 70.0}}) {
    const MuPrediction local = PredictMu(*model.stochastic, fn, v);
    EXPECT_NEAR(local.mu, 0.9 + 0.004 * v - 0.06 * fn, 0.03)
        << "fn " << fn << " v " << v;
    std::ostringstream path;
    path << "/v1/materials/cl-felt/predict?fn_n=" << fn << "&v_mm_s=" << v;
    const json server = client.GetJson(path.str());
    EXPECT_NEAR(local.mu, server.at("mu").get<double>(), 1e-9) << server;
    EXPECT_NEAR(local.sigma, server.at("sigma").get<double>(), 1e-9) << server;
    EXPECT_NEAR(local.lo95, server["interval95"][0].get<double>(), 1e-9);
    EXPECT_NEAR(local.hi95, server["interval95"][1].get<double>(), 1e-9);
  }
}

TEST_F(ClientTest, UnknownMaterialThrowsWithIdentificationRequest) {
  FrictionClient client = MakeClient();
  try {
    client.FetchModel("cl-no-such-material");
    FAIL() << "FetchModel of an unknown material did not throw";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 404) << e.what();
    ASSERT_TRUE(e.body().is_object()) << e.what();
    EXPECT_TRUE(e.body().contains("identification")) << e.body().dump();
  }
  // A rejected upload (fn_n <= 0) is a 400 naming the field.
  try {
    client.UploadStrokes("cl-bad", "t_s,fn_n,ft_n,v_mm_s\n0,-1,0.5,0\n");
    FAIL() << "upload with fn_n = -1 did not throw";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 400) << e.what();
    EXPECT_NE(std::string(e.what()).find("fn_n"), std::string::npos)
        << e.what();
  }
  // Unreachable daemon: status 0.
  ClientOptions o;
  o.base_url = "http://127.0.0.1:1";
  o.timeout_s = 1.0;
  FrictionClient dead(o);
  try {
    dead.ListMaterials();
    FAIL() << "ListMaterials on a closed port did not throw";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 0) << e.what();
  }
}

TEST_F(ClientTest, LuGreBreakawayRemoteMatchesLocalAndTruth) {
  FrictionClient client = MakeClient();
  client.UploadStrokes("cl-steel", LuGreTwoStrokeCsv());
  const ModelSet model = client.FetchModel("cl-steel");
  const std::optional<LuGreTheta> theta = LuGreFromModel(model);
  ASSERT_TRUE(theta.has_value()) << model.other.dump();
  EXPECT_NEAR((*theta)[0], 0.9, 0.018) << "mu_s";
  EXPECT_NEAR((*theta)[1], 0.6, 0.012) << "mu_c";

  for (double rho : {0.05, 5.0}) {
    const BreakawayReply remote = FetchBreakaway(client, "cl-steel", rho, 5.0);
    ASSERT_EQ(remote.status, "ok") << remote.body.dump();
    EXPECT_EQ(remote.material, "cl-steel");
    EXPECT_EQ(remote.version, model.version);
    ForceDrivenOptions options;
    options.mass_kg = remote.mass_kg;
    const ForceDrivenResult local =
        PredictBreakawayRatio(*theta, rho, 5.0, options);
    ASSERT_EQ(local.status, SimulationStatus::kOk) << local.why;
    EXPECT_NEAR(remote.bf_ratio, local.bf_ratio, 1e-9) << "rho " << rho;
    const ForceDrivenResult truth =
        PredictBreakawayRatio(LuGreTruth(), rho, 5.0, options);
    ASSERT_EQ(truth.status, SimulationStatus::kOk) << truth.why;
    EXPECT_NEAR(remote.bf_ratio, truth.bf_ratio, 0.03 * truth.bf_ratio)
        << "rho " << rho;
  }
  // Bad input is rejected before sending; a material without LuGre is 422.
  EXPECT_THROW(FetchBreakaway(client, "cl-steel", -1.0, 5.0),
               std::invalid_argument);
  client.UploadStrokes("cl-stoch-only", SimulatedCsv(21));
  try {
    FetchBreakaway(client, "cl-stoch-only", 0.5, 5.0);
    FAIL() << "break-away of a model without LuGre family did not throw";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 422) << e.what();
  }
}

// `friction upload` sends the global --token (it built its own client
// options without it, so every upload was refused with 401 once uploads
// needed a token), the robot id and the labelling parameters.
TEST_F(ClientTest, CliUploadSendsTheTokenAndRobot) {
  const std::string csv = Write("cli_upload.csv", SimulatedCsv(41));
  CliRun r = Friction("upload cl-cli-up " + csv + " --robot arm-7");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  nlohmann::json body = nlohmann::json::parse(r.out, nullptr, false);
  ASSERT_TRUE(body.is_object()) << r.out;
  EXPECT_EQ(body.value("version", 0), 1) << r.out;
  r = Friction("upload cl-cli-up " + csv + " --slip-peak-mm-s 10");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  body = nlohmann::json::parse(r.out, nullptr, false);
  EXPECT_EQ(body.value("version", 0), 2) << r.out;
  // Without a token the daemon refuses it, and the CLI says why.
  const std::string cmd = testing::BinaryPath("friction") + " --server " +
                          daemon_->base_url() + " upload cl-cli-up " + csv +
                          " >/dev/null 2>" + dir_->path() + "/noauth.err";
  const int status = std::system(cmd.c_str());
  EXPECT_NE(WIFEXITED(status) ? WEXITSTATUS(status) : -1, 0);
  EXPECT_NE(ReadAll(dir_->path() + "/noauth.err").find("401"),
            std::string::npos);
}

TEST_F(ClientTest, CliFitPredictGrip) {
  const std::string csv = Write("cli_stroke.csv", SimulatedCsv(31));
  // fit: offline, no daemon needed.
  CliRun r = Friction("fit " + csv + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json fitted = json::parse(r.out, nullptr, false);
  ASSERT_FALSE(fitted.is_discarded()) << r.out;
  const json& coef = fitted["stochastic"]["coefficients"];
  EXPECT_NEAR(coef["fn_n"].get<double>(), -0.06, 0.02) << coef;
  EXPECT_NEAR(coef["v_mm_s"].get<double>(), 0.004, 0.001) << coef;
  r = Friction("fit " + csv);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("mu = "), std::string::npos) << r.out;

  // fit: bad input names the line and the field; missing file fails too.
  const std::string bad =
      Write("cli_bad.csv", "t_s,fn_n,ft_n,v_mm_s\n0,1,0.5,0\n0.01,0,0.5,1\n");
  r = Friction("fit " + bad);
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("line 3"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("fn_n"), std::string::npos) << r.err;
  r = Friction("fit " + dir_->path() + "/missing.csv");
  EXPECT_NE(r.exit_code, 0);

  // predict / grip against the daemon.
  FrictionClient client = MakeClient();
  client.UploadStrokes("cl-cli", SimulatedCsv(32));
  r = Friction("predict cl-cli --fn-n 2 --v-mm-s 40");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json predicted = json::parse(r.out, nullptr, false);
  ASSERT_FALSE(predicted.is_discarded()) << r.out;
  const json server =
      client.GetJson("/v1/materials/cl-cli/predict?fn_n=2&v_mm_s=40");
  EXPECT_NEAR(predicted["mu"].get<double>(), server["mu"].get<double>(), 1e-9);
  r = Friction("predict cl-cli --fn-n -1 --v-mm-s 40");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("--fn-n"), std::string::npos) << r.err;
  r = Friction("predict cl-cli-unknown --fn-n 2 --v-mm-s 40");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.err.find("identification requested"), std::string::npos) << r.err;
  r = Friction("predict cl-cli --fn-n 2");  // --v-mm-s is required
  EXPECT_NE(r.exit_code, 0) << r.out;

  r = Friction("grip cl-cli --load-n 1 --risk 0.01");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json grip = json::parse(r.out, nullptr, false);
  ASSERT_FALSE(grip.is_discarded()) << r.out;
  const double fn_grip = grip["fn_n"].get<double>();
  const json server_grip =
      client.GetJson("/v1/materials/cl-cli/grip-force?load_n=1&risk=0.01");
  EXPECT_NEAR(fn_grip, server_grip["fn_n"].get<double>(), 1e-6 * fn_grip);
  // A hold of 10 ms at rest (4 samples at 300 Hz): the CLI evaluates
  // locally what the daemon serves, and a hold needs more force than an
  // instant at the same risk.
  r = Friction("grip cl-cli --load-n 1 --risk 0.05 --hold-s 0.01 --v-mm-s 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double fn_hold = json::parse(r.out)["fn_n"].get<double>();
  const json server_hold = client.GetJson(
      "/v1/materials/cl-cli/"
      "grip-force?load_n=1&risk=0.05&hold_s=0.01&v_mm_s=0");
  EXPECT_NEAR(fn_hold, server_hold["fn_n"].get<double>(), 1e-6 * fn_hold);
  EXPECT_EQ(server_hold["hold_samples"].get<int>(), 4);
  const json server_instant =
      client.GetJson("/v1/materials/cl-cli/grip-force?load_n=1&risk=0.05");
  EXPECT_GT(fn_hold, server_instant["fn_n"].get<double>());
  // The simulator's eps is white at 300 Hz: a 1 s hold is 301 independent
  // draws, so no risk below about 1 - (1 - p_min)^301 is supported.
  r = Friction("grip cl-cli --load-n 1 --risk 0.01 --hold-s 1");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.err.find("min_supported_risk"), std::string::npos) << r.err;
  // A risk below what 32 strokes support is refused alike on both routes,
  // naming the smallest supported risk (no silent clamp).
  r = Friction("grip cl-cli --load-n 1 --risk 0.001");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.err.find("min_supported_risk"), std::string::npos) << r.err;
  try {
    client.GetJson("/v1/materials/cl-cli/grip-force?load_n=1&risk=0.001");
    ADD_FAILURE() << "risk 0.001 was served";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 422);
    ASSERT_TRUE(e.body().contains("min_supported_risk")) << e.body();
    const double min_risk = e.body()["min_supported_risk"].get<double>();
    EXPECT_GT(min_risk, 0.001);
    EXPECT_NE(r.err.find(std::to_string(min_risk).substr(0, 6)),
              std::string::npos)
        << r.err;
  }
  // A riskier grip needs less force.
  r = Friction("grip cl-cli --load-n 1 --risk 0.2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_LT(json::parse(r.out)["fn_n"].get<double>(), fn_grip);
  r = Friction("grip cl-cli --load-n 1 --risk 2");  // risk outside (0, 1)
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("risk"), std::string::npos) << r.err;
  r = Friction("grip cl-cli-unknown --load-n 1");
  EXPECT_EQ(r.exit_code, 1) << r.out;
}

}  // namespace
}  // namespace frictiond
