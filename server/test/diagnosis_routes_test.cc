#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
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
