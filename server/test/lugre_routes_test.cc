// LuGre family fitter and the break-away route (issue 5 item 6), through
// HttpServer::Dispatch on an in-memory library: known truth simulated with
// the adaptive LuGre integrator, uploaded as stroke CSV.
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/estimators/breakaway.h"
#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"
#include "frictiond/testing/lugre_strokes.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;

constexpr double kFn = 5.0;       // normal force [N]
constexpr double kNoise = 0.005;  // sensor noise on mu, 1 sigma
constexpr double kRate = 200.0;   // sampling rate [Hz]

// Truth of docs/lugre.md, every entry well away from zero.
LuGreTheta Truth() { return MakeLuGreTheta(0.9, 0.6, 5.0, 0.004, 50.0, 0.1); }

// Appends one stroke of signed velocity v(t), duration_s long, starting at
// t0_s, simulated from z = 0 with Gaussian noise on mu (seeded). The CSV
// carries magnitudes (v_mm_s = |v|, ft_n = |mu| Fn); with_dir adds the
// dir_sign column (sign of v).
void AppendStroke(StrokeData* data,
                  const std::function<double(double)>& v_of_t,
                  double t0_s,
                  double duration_s,
                  unsigned seed,
                  bool with_dir) {
  const int n = static_cast<int>(std::round(duration_s * kRate)) + 1;
  Eigen::VectorXd t(n), v(n);
  for (int k = 0; k < n; ++k) {
    t[k] = k / kRate;
    v[k] = v_of_t(t[k]);
  }
  const VelocityDrivenResult r = SimulateVelocityDriven(Truth(), t, v, 0.0);
  ASSERT_EQ(r.status, SimulationStatus::kOk) << r.why;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, kNoise);
  if (with_dir && data->covariate_names.empty()) {
    data->covariate_names.push_back("dir_sign");
    data->covariates.emplace_back();
  }
  for (int k = 0; k < n; ++k) {
    const double mu = r.mu[k] + gauss(rng);
    data->t_s.push_back(t0_s + t[k]);
    data->fn_n.push_back(kFn);
    data->ft_n.push_back(std::abs(mu) * kFn);
    data->v_mm_s.push_back(std::abs(v[k]));
    if (with_dir)
      data->covariates[0].push_back(v[k] > 0 ? 1 : (v[k] < 0 ? -1 : 0));
  }
}

// Step 1 stroke: 0 -> 20 -> 0 mm/s at 2 mm/s^2 (20 s).
double SlowRamp(double t) { return t < 10 ? 2.0 * t : 40.0 - 2.0 * t; }
// Step 2 stroke: 0 -> 10 -> 0 mm/s at 20 mm/s^2 (1 s).
double FastRamp(double t) { return t < 0.5 ? 20.0 * t : 20.0 - 20.0 * t; }

std::string SlowCsv() {
  StrokeData d;
  AppendStroke(&d, SlowRamp, 0.0, 20.0, 7, false);
  return FormatStrokeCsv(d);
}
std::string FastCsv() {
  StrokeData d;
  AppendStroke(&d, FastRamp, 0.0, 1.0, 107, false);
  return FormatStrokeCsv(d);
}
// Both strokes in one upload, 10 s apart (a time gap separates them).
std::string TwoStrokeCsv() {
  StrokeData d;
  AppendStroke(&d, SlowRamp, 0.0, 20.0, 7, false);
  AppendStroke(&d, FastRamp, 30.0, 1.0, 107, false);
  return FormatStrokeCsv(d);
}

std::string FingertipCsv(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 8;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

double RelErr(double estimate, double truth) {
  return std::abs(estimate - truth) / std::abs(truth);
}

class LuGreRoutesTest : public ::testing::Test {
 protected:
  LuGreRoutesTest() : lib_(OpenStore(":memory:")) {
    RegisterCoreRoutes(http_, lib_);
    RegisterLuGreFeature(http_, lib_);
    RegisterDiagnosisRoutes(http_, lib_);
    InstallQueryCheck(http_);  // as the daemon does
  }
  HttpResponse Get(const std::string& path,
                   std::multimap<std::string, std::string> query = {}) {
    HttpRequest r;
    r.method = "GET";
    r.path = path;
    r.remote_addr = "127.0.0.1";
    r.query = std::move(query);
    return http_.Dispatch(r);
  }
  json Upload(const std::string& id, const std::string& csv) {
    HttpRequest r;
    r.method = "POST";
    r.path = "/v1/materials/" + id + "/strokes";
    r.body = csv;
    r.headers.emplace("Content-Type", "text/csv");
    const HttpResponse out = http_.Dispatch(r);
    EXPECT_EQ(out.status, 201) << out.body;
    return json::parse(out.body);
  }
  json Model(const std::string& id) {
    const HttpResponse r = Get("/v1/materials/" + id + "/model");
    EXPECT_EQ(r.status, 200) << r.body;
    return json::parse(r.body);
  }
  // Expects a 400 naming `param` (field and detail).
  void ExpectBadParam(std::multimap<std::string, std::string> query,
                      const std::string& param) {
    const HttpResponse r = Get("/v1/materials/steel/breakaway", query);
    EXPECT_EQ(r.status, 400) << r.body;
    const json j = json::parse(r.body);
    EXPECT_EQ(j.value("field", ""), param) << r.body;
    EXPECT_NE(j.value("detail", "").find(param), std::string::npos) << r.body;
  }
  FrictionLibrary lib_;
  HttpServer http_;
};

void ExpectNearTruth(const json& lugre) {
  const LuGreFamily f = LuGreFromJson(lugre);  // also checks the format
  const LuGreTheta truth = Truth();
  std::cout << "lugre family: theta = " << f.theta.transpose() << "\n"
            << "  std = " << f.P_theta.diagonal().cwiseSqrt().transpose()
            << "\n  variant " << f.variant << ", iterations " << f.iterations
            << ", rms " << f.residual_rms << " (quasi-static "
            << f.quasi_static_residual_rms << "), strokes "
            << f.strokes_quasi_static << " + " << f.strokes_dynamic << "\n";
  EXPECT_EQ(f.status, "converged");
  EXPECT_EQ(f.variant, "lm2");
  EXPECT_LT(RelErr(f.theta[0], truth[0]), 0.02)
      << "mu_s expected 0.9, got " << f.theta[0];
  EXPECT_LT(RelErr(f.theta[1], truth[1]), 0.02)
      << "mu_c expected 0.6, got " << f.theta[1];
  EXPECT_LT(RelErr(f.theta[2], truth[2]), 0.05)
      << "v0 expected 5 mm/s, got " << f.theta[2];
  EXPECT_LT(RelErr(f.theta[4], truth[4]), 0.05)
      << "sigma0 expected 50 /mm, got " << f.theta[4];
  // sigma1 is the weakest parameter (docs/lugre.md: 0.106 +- 0.016).
  EXPECT_LT(std::abs(f.theta[5] - truth[5]),
            4 * std::sqrt(f.P_theta(5, 5)) + 0.01)
      << "sigma1 expected 0.1 s/mm, got " << f.theta[5];
  for (int i = 0; i < 6; ++i) {
    EXPECT_GT(f.P_theta(i, i), 0) << LuGreParameterName(i);
    EXPECT_GT(lugre["std_errors"][LuGreParameterName(i)].get<double>(), 0);
  }
  EXPECT_EQ(lugre["covariance"].size(), 6u);
  EXPECT_GT(f.residual_rms, 0.5 * kNoise);
  EXPECT_LT(f.residual_rms, 2.0 * kNoise);
}

TEST_F(LuGreRoutesTest, TwoStrokeUploadStoresLuGreNearTruth) {
  const auto t0 = std::chrono::steady_clock::now();
  const json up = Upload("steel", TwoStrokeCsv());
  std::cout << "upload + refit (stochastic + lugre): "
            << std::chrono::duration<double, std::milli>(
                   std::chrono::steady_clock::now() - t0)
                   .count()
            << " ms\n";
  EXPECT_EQ(up.value("version", 0), 1);
  const json model = Model("steel");
  ASSERT_TRUE(model.contains("lugre")) << model.dump();
  ASSERT_TRUE(model["lugre"].is_object()) << model.dump();
  EXPECT_TRUE(model.contains("stochastic"));
  ExpectNearTruth(model["lugre"]);
  EXPECT_EQ(model["lugre"]["strokes_used"]["quasi_static"], 1);
  EXPECT_EQ(model["lugre"]["strokes_used"]["dynamic"], 1);
}

TEST_F(LuGreRoutesTest, DiagnoseReplaysTheStoredLuGreModel) {
  Upload("steel", TwoStrokeCsv());  // identifies LuGre
  // Eight more strokes of the same truth, so diagnosis has strokes to
  // cross-validate over (the LuGre family of the first upload carries over).
  Upload("steel",
         FormatStrokeCsv(
             testing::SimulateLuGreStrokes(testing::LuGreStrokeSpec{}, 4)));
  ASSERT_TRUE(Model("steel").contains("lugre"));
  HttpRequest r;
  r.method = "POST";
  r.path = "/v1/materials/steel/diagnose";
  const HttpResponse out = http_.Dispatch(r);
  ASSERT_EQ(out.status, 200) << out.body;
  const json d = json::parse(out.body)["diagnosis"];
  std::map<std::string, double> mae;
  for (const json& m : d["replay"])
    mae[m["model"].get<std::string>()] = m["overall"]["mu_mae"].get<double>();
  ASSERT_EQ(mae.count("lugre"), 1u) << d["replay"].dump();
  ASSERT_EQ(mae.count("coulomb"), 1u);
  // The data are LuGre with noise kNoise: the replayed LuGre model must be
  // near the noise floor and far better than Coulomb's constant.
  EXPECT_LT(mae["lugre"], 1.5 * kNoise);
  EXPECT_LT(mae["lugre"], 0.5 * mae["coulomb"]);
  EXPECT_TRUE(d["replay_skipped"].empty()) << d["replay_skipped"].dump();
}

TEST_F(LuGreRoutesTest, StrokesFromSeparateUploadsAreCombined) {
  const json first = Upload("steel", SlowCsv());
  EXPECT_NE(first.value("note", "").find("lugre: no high-acceleration stroke"),
            std::string::npos)
      << first.dump();
  EXPECT_FALSE(Model("steel").contains("lugre"));
  const json second = Upload("steel", FastCsv());
  EXPECT_EQ(second.value("version", 0), 2);
  const json model = Model("steel");
  ASSERT_TRUE(model.contains("lugre")) << second.dump();
  ExpectNearTruth(model["lugre"]);
  // A later stochastic-only upload keeps the identified family.
  Upload("steel", FingertipCsv(3));
  const json third = Model("steel");
  EXPECT_EQ(third["version"], 3);
  EXPECT_EQ(third["lugre"], model["lugre"]);
}

TEST_F(LuGreRoutesTest, ReciprocatingStrokesWithDirSignAreSigned) {
  // 0 -> 20 -> -20 -> 0 mm/s at 2 mm/s^2 and 0 -> 10 -> -10 -> 0 at
  // 20 mm/s^2: the force reverses after the motion (hysteresis), and
  // v_mm_s, ft_n are magnitudes with the direction in dir_sign.
  StrokeData d;
  AppendStroke(
      &d,
      [](double t) {
        return t < 10 ? 2.0 * t : (t < 30 ? 40.0 - 2.0 * t : 2.0 * t - 80.0);
      },
      0.0,
      40.0,
      11,
      true);
  AppendStroke(
      &d,
      [](double t) {
        return t < 0.5 ? 20.0 * t
                       : (t < 1.5 ? 20.0 - 20.0 * t : 20.0 * t - 40.0);
      },
      50.0,
      2.0,
      111,
      true);
  Upload("steel", FormatStrokeCsv(d));
  const json model = Model("steel");
  ASSERT_TRUE(model.contains("lugre")) << model.dump();
  const LuGreFamily f = LuGreFromJson(model["lugre"]);
  std::cout << "reciprocating: theta = " << f.theta.transpose() << "\n";
  EXPECT_LT(RelErr(f.theta[0], 0.9), 0.03) << f.theta[0];
  EXPECT_LT(RelErr(f.theta[1], 0.6), 0.03) << f.theta[1];
  EXPECT_LT(RelErr(f.theta[4], 50.0), 0.1) << f.theta[4];
}

TEST_F(LuGreRoutesTest, BreakawayMatchesTruthPrediction) {
  Upload("steel", TwoStrokeCsv());
  for (double rho : {0.05, 0.5, 5.0}) {
    const HttpResponse r = Get("/v1/materials/steel/breakaway",
                               {{"rho", std::to_string(rho)}, {"fn_n", "5"}});
    ASSERT_EQ(r.status, 200) << r.body;
    const json j = json::parse(r.body);
    const ForceDrivenResult truth = PredictBreakawayRatio(Truth(), rho, kFn);
    ASSERT_EQ(truth.status, SimulationStatus::kOk) << truth.why;
    std::cout << "rho " << rho << ": bf " << j["bf_ratio"] << " (truth "
              << truth.bf_ratio << "), t " << j["t_breakaway_s"] << " s\n";
    EXPECT_EQ(j["status"], "ok");
    EXPECT_EQ(j["material"], "steel");
    EXPECT_EQ(j["version"], 1);
    EXPECT_DOUBLE_EQ(j["rho"].get<double>(), rho);
    EXPECT_DOUBLE_EQ(j["fn_n"].get<double>(), kFn);
    EXPECT_LT(RelErr(j["bf_ratio"].get<double>(), truth.bf_ratio), 0.03)
        << "expected " << truth.bf_ratio << ", got " << j["bf_ratio"];
    EXPECT_LT(RelErr(j["t_breakaway_s"].get<double>(), truth.t_breakaway_s),
              0.05);
  }
  // mass_kg is passed to the simulation.
  const HttpResponse heavy =
      Get("/v1/materials/steel/breakaway",
          {{"rho", "0.5"}, {"fn_n", "5"}, {"mass_kg", "1.5"}});
  ASSERT_EQ(heavy.status, 200) << heavy.body;
  EXPECT_DOUBLE_EQ(json::parse(heavy.body)["mass_kg"].get<double>(), 1.5);
}

TEST_F(LuGreRoutesTest, BreakawayFromTheMeasuredStateMatchesTruth) {
  // A grasp already carrying mu_applied = 0.3 (held, v = 0): the route's
  // prediction from that state (eq. (16)) against the truth's.
  Upload("steel", TwoStrokeCsv());
  for (double rho : {0.05, 0.5}) {
    const HttpResponse r = Get(
        "/v1/materials/steel/breakaway",
        {{"rho", std::to_string(rho)}, {"fn_n", "5"}, {"mu_applied", "0.3"}});
    ASSERT_EQ(r.status, 200) << r.body;
    const json j = json::parse(r.body);
    EXPECT_EQ(j["from_measured_state"], true);
    const ForceDrivenResult truth =
        PredictBreakawayRatioFromState(Truth(), 0.3, 0.0, rho, kFn);
    ASSERT_EQ(truth.status, SimulationStatus::kOk) << truth.why;
    EXPECT_LT(RelErr(j["bf_ratio"].get<double>(), truth.bf_ratio), 0.03)
        << "expected " << truth.bf_ratio << ", got " << j["bf_ratio"];
  }
  ExpectBadParam({{"rho", "0.5"}, {"fn_n", "5"}, {"v_mm_s", "1"}}, "v_mm_s");
  ExpectBadParam({{"rho", "0.5"}, {"fn_n", "5"}, {"mu_applied", "-1"}},
                 "mu_applied");
}

TEST_F(LuGreRoutesTest, UnknownMaterialIs404WithIdentificationRequest) {
  const HttpResponse r = Get("/v1/materials/unobtainium/breakaway",
                             {{"rho", "0.5"}, {"fn_n", "5"}});
  EXPECT_EQ(r.status, 404) << r.body;
  const json j = json::parse(r.body);
  EXPECT_TRUE(j.contains("identification")) << r.body;
  EXPECT_FALSE(lib_.store().ListJobs(true).empty());
}

TEST_F(LuGreRoutesTest, BadParametersAre400NamingTheParameter) {
  Upload("steel", TwoStrokeCsv());
  ExpectBadParam({{"fn_n", "5"}}, "rho");
  ExpectBadParam({{"rho", "0"}, {"fn_n", "5"}}, "rho");
  ExpectBadParam({{"rho", "-1"}, {"fn_n", "5"}}, "rho");
  ExpectBadParam({{"rho", "abc"}, {"fn_n", "5"}}, "rho");
  ExpectBadParam({{"rho", "nan"}, {"fn_n", "5"}}, "rho");
  ExpectBadParam({{"rho", "0.5"}}, "fn_n");
  ExpectBadParam({{"rho", "0.5"}, {"fn_n", "0"}}, "fn_n");
  ExpectBadParam({{"rho", "0.5"}, {"fn_n", "inf"}}, "fn_n");
  ExpectBadParam({{"rho", "0.5"}, {"fn_n", "5"}, {"mass_kg", "0"}}, "mass_kg");
  ExpectBadParam({{"rho", "0.5"}, {"fn_n", "5"}, {"rho_per_s", "1"}},
                 "rho_per_s");
}

TEST_F(LuGreRoutesTest, StochasticOnlyUploadHasNoLuGreAndBreakawayIs422) {
  const json up = Upload("felt", FingertipCsv(1));
  EXPECT_EQ(up.value("version", 0), 1);
  const std::string note = up.value("note", "");
  std::cout << "note: " << note << "\n";
  EXPECT_NE(note.find("lugre: no low-acceleration stroke"), std::string::npos)
      << up.dump();
  const json model = Model("felt");
  EXPECT_TRUE(model.contains("stochastic"));
  EXPECT_TRUE(!model.contains("lugre") || model["lugre"].is_null());
  const HttpResponse r =
      Get("/v1/materials/felt/breakaway", {{"rho", "0.5"}, {"fn_n", "5"}});
  EXPECT_EQ(r.status, 422) << r.body;
  const json j = json::parse(r.body);
  EXPECT_EQ(j.value("field", ""), "lugre");
  EXPECT_NE(j.value("detail", "").find("lugre"), std::string::npos) << r.body;
}

TEST_F(LuGreRoutesTest, UnusableDataNeverFailsTheUpload) {
  // Constant speed (no acceleration at all, no Stribeck span): recognised as
  // quasi-static only; the stochastic model is still stored.
  std::string csv = "t_s,fn_n,ft_n,v_mm_s\n";
  for (int k = 0; k < 400; ++k)
    csv += std::to_string(k * 0.005) + ",2," +
           std::to_string(1.0 + 0.01 * (k % 7)) + "," + (k < 5 ? "0" : "30") +
           "\n";
  const json up = Upload("odd", csv);
  EXPECT_EQ(up.value("version", 0), 1);
  EXPECT_NE(up.value("note", "").find("lugre:"), std::string::npos)
      << up.dump();
  EXPECT_FALSE(Model("odd").contains("lugre"));
}

TEST_F(LuGreRoutesTest, MeasuredTribometerRecordHasNoDynamicStroke) {
  // The bundled micro-tribometer record (docs/lugre.md, "Measured data"):
  // ~100 one-way strokes at <= 0.26 mm/s, all recognised as low-acceleration
  // (95th percentile |dv/dt| ~2.5-2.9 mm/s^2), so Step 2 has no stroke.
  const char* root = std::getenv("FRICTIOND_SOURCE_DIR");
  if (!root) GTEST_SKIP() << "FRICTIOND_SOURCE_DIR not set";
  std::ifstream in(std::string(root) +
                   "/data/microtribo_recip/test_data_2.strokes.csv");
  ASSERT_TRUE(in) << root;
  std::stringstream csv;
  csv << in.rdbuf();
  HttpRequest r;
  r.method = "POST";
  r.path = "/v1/materials/tribo/strokes";
  r.body = csv.str();
  r.query = {{"slip_peak_mm_s", "0.1"}, {"slip_floor_mm_s", "0.02"}};
  r.headers.emplace("Content-Type", "text/csv");
  const HttpResponse out = http_.Dispatch(r);
  ASSERT_EQ(out.status, 201) << out.body.substr(0, 500);
  const std::string note = json::parse(out.body).value("note", "");
  std::cout << "note: " << note << "\n";
  EXPECT_NE(note.find("lugre: no high-acceleration stroke"), std::string::npos)
      << note;
  EXPECT_FALSE(Model("tribo").contains("lugre"));
}

TEST(LuGreJsonTest, RoundTripAndFieldNamesInErrors) {
  LuGreFamily f;
  f.theta = Truth();
  for (int i = 0; i < 6; ++i) f.P_theta(i, i) = 1e-4 * (i + 1);
  f.P_theta(4, 5) = f.P_theta(5, 4) = 2e-5;
  f.iterations = 12;
  f.residual_rms = 0.005;
  f.strokes_quasi_static = 2;
  f.strokes_dynamic = 1;
  const json j = LuGreToJson(f);
  EXPECT_DOUBLE_EQ(j["theta"]["v0_mm_s"].get<double>(), 5.0);
  EXPECT_DOUBLE_EQ(j["std_errors"]["mu_s"].get<double>(), 1e-2);
  const LuGreFamily g = LuGreFromJson(json::parse(j.dump()));
  EXPECT_TRUE(g.theta.isApprox(f.theta));
  EXPECT_TRUE(g.P_theta.isApprox(f.P_theta));
  EXPECT_EQ(g.iterations, 12);
  EXPECT_EQ(g.strokes_quasi_static, 2);
  EXPECT_EQ(g.variant, "lm2");

  auto expect_error = [](json bad, const std::string& expected) {
    try {
      LuGreFromJson(bad);
      ADD_FAILURE() << "accepted " << bad.dump();
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << e.what();
    }
  };
  json missing = j;
  missing["theta"].erase("sigma0_per_mm");
  expect_error(missing, "lugre.theta.sigma0_per_mm: missing");
  json negative = j;
  negative["theta"]["v0_mm_s"] = -1.0;
  expect_error(negative, "lugre.theta.v0_mm_s = -1");
  json text = j;
  text["theta"]["mu_c"] = "0.6";
  expect_error(text, "lugre.theta.mu_c: expected a number");
  json cov = j;
  cov["covariance"][2][3] = "x";
  expect_error(cov, "lugre.covariance[2][3]");
  json no_status = j;
  no_status.erase("status");
  expect_error(no_status, "lugre.status: missing");
  expect_error(json::array(), "lugre: expected a JSON object");
}

}  // namespace
}  // namespace frictiond
