#include <cmath>
#include <memory>
#include <random>
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

// Strokes whose mu falls 0.01 per degree of a temp_c covariate that changes
// from stroke to stroke and within strokes (seeded).
std::string PlantedTemperatureCsv(std::uint64_t seed, bool planted) {
  testing::SimulationSpec spec;
  spec.strokes = 30;
  spec.covariates.push_back({"temp_c", [](int stroke, double t, double u) {
                               return 20.0 + 0.5 * stroke + 2.0 * t + 0.2 * u;
                             }});
  if (planted) {
    spec.extra_mu = [](const testing::SimulationSpec::SampleView& s) {
      return -0.01 * ((*s.covariates)[0] - 27.0);
    };
  }
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

class DiagnosisRoutesTest : public ::testing::Test {
 protected:
  DiagnosisRoutesTest() : lib_(OpenStore(":memory:")) {
    RegisterCoreRoutes(http_, lib_);
    RegisterDiagnosisRoutes(http_, lib_);
    InstallQueryCheck(http_);  // as the daemon does
  }
  HttpResponse Call(const std::string& method,
                    const std::string& path,
                    std::multimap<std::string, std::string> query = {}) {
    HttpRequest r;
    r.method = method;
    r.path = path;
    r.query = std::move(query);
    return http_.Dispatch(r);
  }
  FrictionLibrary lib_;
  HttpServer http_;
};

TEST_F(DiagnosisRoutesTest, FindsPlantedCovariateAndStoresServedExtendedModel) {
  lib_.IngestStrokes("rubber", PlantedTemperatureCsv(11, true), {});
  const HttpResponse r =
      Call("POST", "/v1/materials/rubber/diagnose", {{"store", "1"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const json j = json::parse(r.body);
  const json& findings = j["diagnosis"]["findings"];
  ASSERT_FALSE(findings.empty()) << r.body;
  EXPECT_EQ(findings[0]["cause"], "temp_c");
  ASSERT_EQ(j["stored_version"], 2);
  // The extended model is served like any other version, keyed by its input.
  const json model =
      json::parse(Call("GET", "/v1/materials/rubber/model").body);
  EXPECT_EQ(model["version"], 2);
  EXPECT_EQ(model["reason"], "diagnosis");
  bool has_temp = false;
  for (auto it = model["stochastic"]["coefficients"].begin();
       it != model["stochastic"]["coefficients"].end();
       ++it) {
    if (it.key().find("temp_c") != std::string::npos) has_temp = true;
  }
  EXPECT_TRUE(has_temp) << model["stochastic"]["coefficients"].dump();
  // Predictions now depend on temperature.
  const json cold =
      json::parse(Call("GET",
                       "/v1/materials/rubber/predict",
                       {{"fn_n", "2"}, {"v_mm_s", "30"}, {"temp_c", "22"}})
                      .body);
  const json warm =
      json::parse(Call("GET",
                       "/v1/materials/rubber/predict",
                       {{"fn_n", "2"}, {"v_mm_s", "30"}, {"temp_c", "32"}})
                      .body);
  EXPECT_NEAR(cold["mu"].get<double>() - warm["mu"].get<double>(), 0.1, 0.03);
}

// Strokes whose v slope depends on Fn: mu gains -0.002 (Fn - 2.5)(v - 40).
std::string PlantedInteractionCsv(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 30;
  spec.sigma_eps = 0.03;
  spec.extra_mu = [](const testing::SimulationSpec::SampleView& s) {
    return -0.002 * (s.fn_n - 2.5) * (s.v_mm_s - 40.0);
  };
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

double Coefficient(const json& model, const std::string& term) {
  const json& c = model["stochastic"]["coefficients"];
  return c.contains(term) ? c[term].get<double>() : std::nan("");
}

TEST_F(DiagnosisRoutesTest, StoredInteractionIsKeptAndRefittedOnNewStrokes) {
  lib_.IngestStrokes("rubber", PlantedInteractionCsv(21), {});
  const HttpResponse r =
      Call("POST", "/v1/materials/rubber/diagnose", {{"store", "1"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const json j = json::parse(r.body);
  bool found = false;
  for (const json& f : j["diagnosis"]["findings"])
    found =
        found || (f["kind"] == "interaction" && f["cause"] == "fn_n*v_mm_s");
  ASSERT_TRUE(found) << j["diagnosis"]["findings"].dump();
  ASSERT_EQ(j["stored_version"], 2);
  const json v2 = json::parse(Call("GET", "/v1/materials/rubber/model").body);
  EXPECT_NEAR(Coefficient(v2, "fn_n*v_mm_s"), -0.002, 0.0005) << v2.dump();
  // A new stroke arrives: the daemon computes the product column from the
  // stroke data and refits the extended model (term kept, fitted).
  lib_.IngestStrokes("rubber", PlantedInteractionCsv(22), {});
  const json v3 = json::parse(Call("GET", "/v1/materials/rubber/model").body);
  ASSERT_EQ(v3["version"], 3);
  EXPECT_NEAR(Coefficient(v3, "fn_n*v_mm_s"), -0.002, 0.0004) << v3.dump();
  EXPECT_NE(Coefficient(v3, "fn_n*v_mm_s"), Coefficient(v2, "fn_n*v_mm_s"));
  // Predictions follow the interaction: the v slope at Fn = 4 is lower
  // than at Fn = 1 by about 0.002 x 3 per mm/s.
  auto mu = [&](const char* fn, const char* v) {
    return json::parse(Call("GET",
                            "/v1/materials/rubber/predict",
                            {{"fn_n", fn}, {"v_mm_s", v}})
                           .body)["mu"]
        .get<double>();
  };
  const double slope_1 = (mu("1", "60") - mu("1", "20")) / 40;
  const double slope_4 = (mu("4", "60") - mu("4", "20")) / 40;
  EXPECT_NEAR(slope_1 - slope_4, 0.006, 0.0015);
}

// Strokes whose eps sd grows with Fn (extra noise 0.015 Fn, seeded).
std::string PlantedSpreadCsv(std::uint64_t seed) {
  testing::SimulationSpec spec;
  spec.strokes = 30;
  spec.sigma_eps = 0.005;
  auto rng = std::make_shared<std::mt19937_64>(seed + 77);
  spec.extra_mu = [rng](const testing::SimulationSpec::SampleView& s) {
    std::normal_distribution<double> e(0.0, 1.0);
    return 0.015 * s.fn_n * e(*rng);
  };
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

TEST_F(DiagnosisRoutesTest, StoredSpreadWidensServedIntervalWithFn) {
  lib_.IngestStrokes("rubber", PlantedSpreadCsv(31), {});
  const HttpResponse r =
      Call("POST", "/v1/materials/rubber/diagnose", {{"store", "1"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const json j = json::parse(r.body);
  bool found = false;
  for (const json& f : j["diagnosis"]["findings"])
    found = found || (f["kind"] == "spread" && f["cause"] == "fn_n");
  ASSERT_TRUE(found) << j["diagnosis"]["findings"].dump();
  ASSERT_TRUE(j.contains("stored_version")) << r.body;
  const json model =
      json::parse(Call("GET", "/v1/materials/rubber/model").body);
  ASSERT_TRUE(model["stochastic"].contains("eps_scale")) << model.dump();
  EXPECT_EQ(model["stochastic"]["eps_scale"]["input"], "fn_n");
  auto width = [&](const char* fn) {
    const json p = json::parse(Call("GET",
                                    "/v1/materials/rubber/predict",
                                    {{"fn_n", fn}, {"v_mm_s", "40"}})
                                   .body);
    return p["interval95"][1].get<double>() - p["interval95"][0].get<double>();
  };
  // Truth: sd sqrt(0.005^2 + (0.015 Fn)^2): 0.016 at 1 N, 0.060 at 4 N.
  EXPECT_GT(width("4"), 2.5 * width("1"));
  // (The log-linear scale fitted to this linear-in-Fn sd overstates the
  // ends by ~15 %.)
  EXPECT_NEAR(width("4"), 2 * 1.96 * 0.060, 0.05);
  // A new stroke: the scale is refitted and kept.
  lib_.IngestStrokes("rubber", PlantedSpreadCsv(32), {});
  const json v3 = json::parse(Call("GET", "/v1/materials/rubber/model").body);
  ASSERT_EQ(v3["version"].get<int>(), j["stored_version"].get<int>() + 1);
  ASSERT_TRUE(v3["stochastic"].contains("eps_scale")) << v3.dump();
  EXPECT_GT(width("4"), 2.5 * width("1"));
}

TEST_F(DiagnosisRoutesTest, NullDataStoresNothingNew) {
  lib_.IngestStrokes("rubber", PlantedTemperatureCsv(12, false), {});
  const HttpResponse r =
      Call("POST", "/v1/materials/rubber/diagnose", {{"store", "1"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const json j = json::parse(r.body);
  EXPECT_TRUE(j["diagnosis"]["findings"].empty())
      << j["diagnosis"]["findings"].dump();
  EXPECT_FALSE(j.contains("stored_version"));
  EXPECT_EQ(lib_.store().ListModels("rubber", "default").size(), 1u);
}

TEST_F(DiagnosisRoutesTest, BadParametersAndUnknownMaterial) {
  EXPECT_EQ(Call("POST", "/v1/materials/nothing/diagnose").status, 404);
  lib_.IngestStrokes("rubber", PlantedTemperatureCsv(13, false), {});
  const HttpResponse r =
      Call("POST", "/v1/materials/rubber/diagnose", {{"store", "yes"}});
  EXPECT_EQ(r.status, 400);
  EXPECT_EQ(json::parse(r.body)["field"], "store");
}

}  // namespace
}  // namespace frictiond
