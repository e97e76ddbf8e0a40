// Model query routes (docs/paper000.md) through HttpServer::Dispatch on an
// in-memory library, with strokes simulated from a known model.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;

class ModelQueryRoutesTest : public ::testing::Test {
 protected:
  ModelQueryRoutesTest() : lib_(OpenStore(":memory:")) {
    RegisterCoreRoutes(http_, lib_);
    RegisterModelQueryRoutes(http_, lib_);
    RegisterExportRoutes(http_, lib_);
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
  void Upload(const std::string& id, const testing::SimulationSpec& spec) {
    HttpRequest r;
    r.method = "POST";
    r.path = "/v1/materials/" + id + "/strokes";
    r.body = FormatStrokeCsv(testing::SimulateStrokes(spec, 5));
    r.headers.emplace("Content-Type", "text/csv");
    const HttpResponse out = http_.Dispatch(r);
    ASSERT_EQ(out.status, 201) << out.body;
  }
  json GetOk(const std::string& path,
             std::multimap<std::string, std::string> query) {
    const HttpResponse r = Get(path, std::move(query));
    EXPECT_EQ(r.status, 200) << r.body;
    return json::parse(r.body);
  }
  void ExpectBad(const std::string& path,
                 std::multimap<std::string, std::string> query,
                 const std::string& field) {
    const HttpResponse r = Get(path, std::move(query));
    EXPECT_EQ(r.status, 400) << r.body;
    const json j = json::parse(r.body);
    EXPECT_EQ(j.value("field", ""), field) << r.body;
    EXPECT_NE(j.value("detail", "").find(field), std::string::npos) << r.body;
  }
  // 422 naming `field` (the answer of a valid request the model cannot
  // serve).
  void ExpectUnservable(const std::string& path,
                        std::multimap<std::string, std::string> query,
                        const std::string& field) {
    const HttpResponse r = Get(path, std::move(query));
    EXPECT_EQ(r.status, 422) << r.body;
    EXPECT_EQ(json::parse(r.body).value("field", ""), field) << r.body;
  }
  FrictionLibrary lib_;
  HttpServer http_;
};

TEST_F(ModelQueryRoutesTest, TargetForceAndSlidingSpeedRoundTrip) {
  testing::SimulationSpec spec;  // b0 0.9, b1 0.004, b2 -0.06
  Upload("felt", spec);
  const json f = GetOk("/v1/materials/felt/target-force",
                       {{"fn_n", "2.5"}, {"v_mm_s", "40"}});
  const double truth = (spec.b0 + spec.b1 * 40 + spec.b2 * 2.5) * 2.5;
  EXPECT_NEAR(f["ft_n"].get<double>(), truth, 0.02) << f.dump();
  EXPECT_LT(f["interval95_n"][0].get<double>(), f["ft_n"].get<double>());
  EXPECT_FALSE(f["extrapolated"].get<bool>());
  const json s = GetOk(
      "/v1/materials/felt/sliding-speed",
      {{"fn_n", "2.5"}, {"ft_n", std::to_string(f["ft_n"].get<double>())}});
  EXPECT_NEAR(s["v_mm_s"].get<double>(), 40.0, 1e-3) << s.dump();
  EXPECT_GT(s["b1_t"].get<double>(), 10.0) << s.dump();
}

TEST_F(ModelQueryRoutesTest, BadParametersAnswer400NamingTheField) {
  Upload("felt", {});
  const std::string t = "/v1/materials/felt/target-force";
  const std::string s = "/v1/materials/felt/sliding-speed";
  ExpectBad(t, {{"v_mm_s", "10"}}, "fn_n");
  ExpectBad(t, {{"fn_n", "-1"}, {"v_mm_s", "10"}}, "fn_n");
  ExpectBad(t, {{"fn_n", "1"}, {"v_mm_s", "abc"}}, "v_mm_s");
  ExpectBad(t, {{"fn_n", "1"}, {"v_mm_s", "-3"}}, "v_mm_s");
  ExpectBad(t, {{"fn_n", "1"}, {"v_mm_s", "3"}, {"temp_c", "20"}}, "temp_c");
  ExpectBad(s, {{"fn_n", "1"}}, "ft_n");
  ExpectBad(s, {{"fn_n", "nan"}, {"ft_n", "1"}}, "fn_n");
  ExpectBad(s, {{"fn_n", "1"}, {"ft_n", "-1"}}, "ft_n");
}

TEST_F(ModelQueryRoutesTest, SlidingSpeedWithoutSpeedSlopeIs422) {
  // Constant sliding speed (like data/microtribo_recip): b1 is not
  // identified, so eq. (4) cannot tell the speed.
  StrokeData d;
  for (int i = 0; i < 400; ++i) {
    const double fn = 1.0 + 3.0 * i / 400.0;
    d.t_s.push_back(0.01 * i);
    d.fn_n.push_back(fn);
    d.ft_n.push_back((0.9 - 0.06 * fn + 0.03 * std::sin(1.7 * i)) * fn);
    d.v_mm_s.push_back(30.0);
    d.slip.push_back(1);
    d.stroke.push_back(0);
  }
  HttpRequest up;
  up.method = "POST";
  up.path = "/v1/materials/paper/strokes";
  up.body = FormatStrokeCsv(d);
  up.headers.emplace("Content-Type", "text/csv");
  ASSERT_EQ(http_.Dispatch(up).status, 201);
  const HttpResponse r = Get("/v1/materials/paper/sliding-speed",
                             {{"fn_n", "2"}, {"ft_n", "1.6"}});
  EXPECT_EQ(r.status, 422) << r.body;
  EXPECT_NE(r.body.find("no_speed_term"), std::string::npos) << r.body;
  // eq. (3) still answers: mu does not depend on v in this model.
  const json f = GetOk("/v1/materials/paper/target-force",
                       {{"fn_n", "2"}, {"v_mm_s", "30"}});
  EXPECT_NEAR(f["mu"].get<double>(), 0.9 - 0.06 * 2, 0.01) << f.dump();
}

TEST_F(ModelQueryRoutesTest, ConditionalSlipLikelihoodFlagsExtrapolation) {
  testing::SimulationSpec spec;
  spec.strokes = 30;
  Upload("felt", spec);
  const json model = GetOk("/v1/materials/felt/model", {});
  ASSERT_TRUE(model.contains("slip_likelihood_fn")) << model.dump();
  const json& fam = model["slip_likelihood_fn"];
  EXPECT_DOUBLE_EQ(fam["step_n"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(fam["window_n"].get<double>(), 0.6);
  ASSERT_GE(fam["knots"].size(), 3u) << fam.dump();
  const std::string path = "/v1/materials/felt/conditional-slip-likelihood";
  const json in = GetOk(path, {{"fn_n", "2.5"}, {"ratio", "0.9"}});
  EXPECT_FALSE(in["extrapolated"].get<bool>()) << in.dump();
  EXPECT_GE(in["likelihood"].get<double>(), 0.0);
  EXPECT_LE(in["likelihood"].get<double>(), 1.0);
  const json out = GetOk(path, {{"fn_n", "9"}, {"ft_n", "8"}});
  EXPECT_TRUE(out["extrapolated"].get<bool>()) << out.dump();
  EXPECT_NEAR(out["ratio"].get<double>(), 8.0 / 9.0, 1e-12);
  // L rises with the ratio at fixed Fn.
  const json lo = GetOk(path, {{"fn_n", "2.5"}, {"ratio", "0.3"}});
  const json hi = GetOk(path, {{"fn_n", "2.5"}, {"ratio", "1.5"}});
  EXPECT_LT(lo["likelihood"].get<double>(), 0.05) << lo.dump();
  EXPECT_GT(hi["likelihood"].get<double>(), 0.95) << hi.dump();
  ExpectBad(path, {{"fn_n", "2"}}, "ft_n");
  ExpectBad(path, {{"fn_n", "2"}, {"ft_n", "1"}, {"ratio", "0.5"}}, "ft_n");
  ExpectBad(path, {{"fn_n", "0"}, {"ratio", "0.5"}}, "fn_n");
  ExpectBad(path, {{"fn_n", "1"}, {"ratio", "-0.5"}}, "ratio");
  ExpectBad(path, {{"fn_n", "1"}, {"ratio", "0.5"}, {"x", "1"}}, "x");
  // The contract's route is unchanged.
  const json core = GetOk("/v1/materials/felt/slip-likelihood",
                          {{"fn_n", "2.5"}, {"ft_n", "2.0"}});
  EXPECT_TRUE(core.contains("likelihood"));
}

TEST_F(ModelQueryRoutesTest, FormsAreComparedOnHeldOutStrokes) {
  testing::SimulationSpec spec;  // mu linear in Fn (b2 = -0.06)
  spec.strokes = 20;
  Upload("felt", spec);
  const json f = GetOk("/v1/materials/felt/forms", {});
  ASSERT_TRUE(f["compared"].get<bool>()) << f.dump();
  EXPECT_EQ(f["folds"].get<int>(), 5);
  ASSERT_EQ(f["forms"].size(), 6u);
  EXPECT_EQ(f["forms"][0]["form"], "linear");
  EXPECT_NEAR(f["forms"][0]["a"].get<double>(), spec.b2, 0.01) << f.dump();
  double coulomb = 0, linear = f["forms"][0]["cv_mae"].get<double>();
  for (const json& x : f["forms"])
    if (x["form"] == "coulomb") coulomb = x["cv_mae"].get<double>();
  EXPECT_LT(linear, coulomb) << f.dump();
  ExpectBad("/v1/materials/felt/forms", {{"folds", "1"}}, "folds");
  ExpectBad("/v1/materials/felt/forms", {{"bogus", "1"}}, "bogus");
}

TEST_F(ModelQueryRoutesTest, MuSpreadNarrowsWithWindows) {
  testing::SimulationSpec spec;  // sigma_eps 0.05
  spec.strokes = 60;
  Upload("felt", spec);
  const json r = GetOk("/v1/materials/felt/mu-spread",
                       {{"fn_n", "2.5"},
                        {"v_mm_s", "40"},
                        {"fn_widths_n", "inf,2,0.6"},
                        {"v_widths_mm_s", "inf,40,12"}});
  const json& both = r["both_windows"];
  ASSERT_EQ(both.size(), 3u) << r.dump();
  EXPECT_TRUE(both[0]["fn_width_n"].is_null());
  EXPECT_GT(both[0]["std_mu"].get<double>(), both[2]["std_mu"].get<double>());
  EXPECT_NEAR(both[2]["std_mu"].get<double>(), spec.sigma_eps, 0.01)
      << r.dump();
  EXPECT_EQ(r["fn_windows"].size(), 3u);
  // Default widths: all data, then the fitted range and its halves.
  const json d =
      GetOk("/v1/materials/felt/mu-spread", {{"fn_n", "2"}, {"v_mm_s", "30"}});
  EXPECT_EQ(d["fn_windows"].size(), 5u) << d.dump();
  const std::string path = "/v1/materials/felt/mu-spread";
  ExpectBad(path, {{"v_mm_s", "30"}}, "fn_n");
  ExpectBad(path,
            {{"fn_n", "2"}, {"v_mm_s", "30"}, {"fn_widths_n", "1,-2"}},
            "fn_widths_n");
  ExpectBad(path,
            {{"fn_n", "2"}, {"v_mm_s", "30"}, {"v_widths_mm_s", "1,x"}},
            "v_widths_mm_s");
}

TEST_F(ModelQueryRoutesTest, SpanVariabilityBins) {
  testing::SimulationSpec spec;
  spec.strokes = 30;
  Upload("felt", spec);
  const json r = GetOk("/v1/materials/felt/span-variability",
                       {{"subsets", "60"}, {"seed", "3"}, {"bin_pct", "25"}});
  ASSERT_TRUE(r["valid"].get<bool>()) << r.dump();
  EXPECT_EQ(r["strokes"].get<int>(), 30);
  ASSERT_EQ(r["bins"].size(), 4u);
  int total = 0;
  for (const json& b : r["bins"]) total += b["subsets"].get<int>();
  EXPECT_GT(total, 40) << r.dump();
  EXPECT_LE(total, 60);
  const std::string path = "/v1/materials/felt/span-variability";
  ExpectBad(path, {{"subsets", "0"}}, "subsets");
  ExpectBad(path, {{"subsets", "5000"}}, "subsets");
  ExpectBad(path, {{"seed", "1.5"}}, "seed");
  ExpectBad(path, {{"what", "1"}}, "what");
}

// Strokes with correlated noise and per-stroke offsets: the served model
// carries stroke-clustered standard errors beside the i.i.d. ones, and they
// are the larger (the i.i.d. ones under-cover on such data), stored and read
// back unchanged.
TEST_F(ModelQueryRoutesTest, ModelServesStrokeClusteredStandardErrors) {
  testing::SimulationSpec spec;
  spec.strokes = 12;
  spec.ar_rho = 0.95;
  spec.stroke_offset_sd = 0.03;
  Upload("rubber", spec);
  const json model = GetOk("/v1/materials/rubber/model", {});
  const json& mu = model.at("stochastic");
  ASSERT_TRUE(mu.contains("std_errors_stroke")) << mu.dump();
  EXPECT_EQ(mu.at("stroke_clusters").get<int>(), 12);
  for (const char* term : {"v_mm_s", "fn_n"}) {
    EXPECT_GT(mu["std_errors_stroke"][term].get<double>(),
              2.0 * mu["std_errors"][term].get<double>())
        << term << ": " << mu.dump();
  }
}

// mu = |Ft|/Fn >= 0 (mu_admissibility.h): a linear model whose terms carry
// a trend below 0 is not served there, and a bound below 0 is floored.
TEST_F(ModelQueryRoutesTest, NegativeMuIsNeverServed) {
  testing::SimulationSpec spec;
  spec.b2 = -0.15;  // mu 0.9 - 0.15 Fn + 0.004 v: below 0 past Fn ~ 6.5 N
  Upload("soft", spec);
  const json model = GetOk("/v1/materials/soft/model", {});
  const json& c = model["stochastic"]["coefficients"];
  const double b0 = c["intercept"].get<double>(),
               b1 = c["v_mm_s"].get<double>(), b2 = c["fn_n"].get<double>();
  ASSERT_LT(b2, -0.1) << c.dump();
  const std::string predict = "/v1/materials/soft/predict";
  // The mean below 0 (beyond the fitted Fn): 422 naming fn_n, the input
  // whose move to its fitted mean raises mu (not v_mm_s, given too).
  const double fn_negative = (-0.2 - b0 - b1 * 20) / b2;  // mean -0.2
  for (const std::string& path :
       {predict, std::string("/v1/materials/soft/target-force")}) {
    ExpectUnservable(path,
                     {{"fn_n", std::to_string(fn_negative)}, {"v_mm_s", "20"}},
                     "fn_n");
    // Terms that overflow: not finite, 422 (never 200 with null).
    ExpectUnservable(path, {{"fn_n", "2"}, {"v_mm_s", "1e308"}}, "v_mm_s");
  }
  ExpectUnservable("/v1/materials/soft/export",
                   {{"format", "mjcf"},
                    {"risk", "0.05"},
                    {"fn_n", std::to_string(fn_negative)},
                    {"v_mm_s", "20"}},
                   "fn_n");
  // The mean just above 0: served, the interval floored at 0.
  const double fn_small = (0.02 - b0 - b1 * 20) / b2;  // mean 0.02
  const json p =
      GetOk(predict, {{"fn_n", std::to_string(fn_small)}, {"v_mm_s", "20"}});
  EXPECT_NEAR(p["mu"].get<double>(), 0.02, 1e-6) << p.dump();
  EXPECT_EQ(p["interval95"][0].get<double>(), 0.0) << p.dump();
  EXPECT_TRUE(p["floored_at_zero"].get<bool>()) << p.dump();
  const json f = GetOk("/v1/materials/soft/target-force",
                       {{"fn_n", std::to_string(fn_small)}, {"v_mm_s", "20"}});
  EXPECT_EQ(f["interval95_n"][0].get<double>(), 0.0) << f.dump();
  EXPECT_TRUE(f["floored_at_zero"].get<bool>()) << f.dump();
  // Inside the data nothing is floored.
  const json in = GetOk(predict, {{"fn_n", "2"}, {"v_mm_s", "40"}});
  EXPECT_FALSE(in["floored_at_zero"].get<bool>()) << in.dump();
  EXPECT_GT(in["interval95"][0].get<double>(), 0.0) << in.dump();
  // No tangential force drives no sliding, even where the line's mu at rest
  // (b0 + b2 Fn) is below 0 and so puts Ft = 0 at a positive speed.
  const double fn_rest_negative = (-0.1 - b0) / b2;
  const json s =
      GetOk("/v1/materials/soft/sliding-speed",
            {{"fn_n", std::to_string(fn_rest_negative)}, {"ft_n", "0"}});
  EXPECT_GT(s["v_mm_s"].get<double>(), 0.0) << s.dump();
  EXPECT_TRUE(s["below_model_range"].get<bool>()) << s.dump();
  ExpectUnservable("/v1/materials/soft/sliding-speed",
                   {{"fn_n", "1e-300"}, {"ft_n", "1e300"}},
                   "ft_n");
}

TEST_F(ModelQueryRoutesTest, SlipLikelihoodFlagsExtrapolation) {
  Upload("felt", {});  // Fn 0.5-4.5 N
  const std::string path = "/v1/materials/felt/slip-likelihood";
  const json in = GetOk(path, {{"fn_n", "2"}, {"ft_n", "1"}});
  EXPECT_FALSE(in["extrapolated"].get<bool>()) << in.dump();
  const json out = GetOk(path, {{"fn_n", "50"}, {"ft_n", "1"}});
  EXPECT_TRUE(out["extrapolated"].get<bool>()) << out.dump();
  EXPECT_EQ(out["extrapolated_inputs"], json::array({"fn_n"})) << out.dump();
  ExpectUnservable(path, {{"fn_n", "1e-300"}, {"ft_n", "1e300"}}, "ft_n");
}

// slip-likelihood given the grasp's state (v_mm_s, hold_s) is grip-force's
// forward model: at the grip force for (load, risk) it answers the risk, so
// a client can check a served grip force with the library itself.
TEST_F(ModelQueryRoutesTest, SlipLikelihoodAtTheGraspStateInvertsGripForce) {
  Upload("felt", {});  // b0 0.9, b1 0.004, b2 -0.06; Fn 0.5-4.5 N
  const std::string grip = "/v1/materials/felt/grip-force";
  const std::string slip = "/v1/materials/felt/slip-likelihood";
  int checked = 0;
  for (const char* v : {"0", "20", "60"}) {
    for (const char* hold : {"0", "1.5"}) {
      for (const double risk : {0.01, 0.05, 0.3}) {
        const std::string load = "1.2";
        const HttpResponse g = Get(grip,
                                   {{"load_n", load},
                                    {"risk", std::to_string(risk)},
                                    {"v_mm_s", v},
                                    {"hold_s", hold}});
        if (g.status != 200) {  // a risk below what the data support
          EXPECT_EQ(g.status, 422) << g.body;
          continue;
        }
        const double fn = json::parse(g.body)["fn_n"].get<double>();
        auto at = [&](double f) {
          const json j = GetOk(slip,
                               {{"fn_n", json(f).dump()},
                                {"ft_n", load},
                                {"v_mm_s", v},
                                {"hold_s", hold}});
          EXPECT_EQ(j["method"], "eq1_hold") << j.dump();
          return j["likelihood"].get<double>();
        };
        EXPECT_NEAR(at(fn), risk, 1e-4 * risk)
            << "v " << v << " hold " << hold << " risk " << risk;
        // More grip, less slip; less grip, more.
        EXPECT_LT(at(1.1 * fn), risk);
        EXPECT_GT(at(0.9 * fn), risk);
        ++checked;
      }
    }
  }
  EXPECT_GE(checked, 12);
  // No load, no slip; the speed-free likelihood is unchanged without a
  // state; the state's inputs are checked as grip-force checks them.
  EXPECT_EQ(
      GetOk(slip,
            {{"fn_n", "2"}, {"ft_n", "0"}, {"v_mm_s", "20"}})["likelihood"]
          .get<double>(),
      0.0);
  EXPECT_NE(GetOk(slip, {{"fn_n", "2"}, {"ft_n", "1"}})["method"], "eq1_hold");
  ExpectBad(slip, {{"fn_n", "2"}, {"ft_n", "1"}, {"v_mm_s", "-1"}}, "v_mm_s");
  ExpectBad(slip, {{"fn_n", "2"}, {"ft_n", "1"}, {"hold_s", "1e9"}}, "hold_s");
}

TEST_F(ModelQueryRoutesTest, IdentificationsOpenFlagIsValidated) {
  ExpectBad("/v1/identifications", {{"open", "banana"}}, "open");
  for (const char* v : {"0", "1", "true", "false"})
    GetOk("/v1/identifications", {{"open", v}});
}

TEST_F(ModelQueryRoutesTest, UnknownMaterialIs404) {
  const HttpResponse r = Get("/v1/materials/nothing/target-force",
                             {{"fn_n", "1"}, {"v_mm_s", "3"}});
  EXPECT_EQ(r.status, 404) << r.body;
}

}  // namespace
}  // namespace frictiond
