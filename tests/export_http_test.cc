// Simulator export and the pair-level answer end to end (docs/export.md):
// the real `frictiond` on the bundled data plus simulated strokes, requests
// over loopback HTTP, every format parsed by a real parser (tinyxml2 for
// MJCF/SDF/URDF, the usda grammar checker, nlohmann for JSON), values
// checked against the model served by GET /model, and the `friction` CLI.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

// Eigen before httplib.h: <resolv.h> (via httplib) defines a macro _res
// that breaks Eigen's product kernels.
#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>
#include <tinyxml2.h>

#include "frictiond/estimators/contact_friction.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/model_json.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"
#include "frictiond/testing/usda_checker.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::DbFingerprint;
using testing::ExitStatus;
using testing::TempDir;

constexpr char kBundled[] = "microtribo-recip";

json Body(const httplib::Result& res) {
  if (!res) {
    ADD_FAILURE() << "no response: " << httplib::to_string(res.error());
    return json();
  }
  json j = json::parse(res->body, nullptr, false);
  if (j.is_discarded()) ADD_FAILURE() << "not JSON: " << res->body;
  return j;
}

std::string SimulatedCsv(std::uint64_t seed, double b0) {
  testing::SimulationSpec spec;
  spec.strokes = 6;
  spec.b0 = b0;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

double ToDouble(const char* text) {
  if (!text) {
    ADD_FAILURE() << "missing number";
    return std::nan("");
  }
  return std::strtod(text, nullptr);
}

void ExpectRel(double actual, double expected, const std::string& what) {
  EXPECT_LE(std::fabs(actual - expected), 1e-9 * std::fabs(expected))
      << what << ": actual " << actual << ", expected " << expected;
}

class ExportHttpTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("export_http_test");
    DaemonOptions options;
    options.db = dir_->path() + "/library.db";
    daemon_ = new DaemonProcess(options);
    daemon_->Start();
    auto c = daemon_->MakeClient();
    // Two materials measured with the default fingertip, and one pair.
    for (const auto& [path, csv] :
         std::vector<std::pair<std::string, std::string>>{
             {"/v1/materials/pad/strokes", SimulatedCsv(21, 1.1)},
             {"/v1/materials/cup/strokes", SimulatedCsv(22, 0.5)},
             {"/v1/materials/box/strokes", SimulatedCsv(24, 0.6)},
             {"/v1/materials/cup/strokes?fingertip=pad",
              SimulatedCsv(23, 0.7)}}) {
      auto res = c->Post(path.c_str(), csv, "text/csv");
      ASSERT_TRUE(res);
      ASSERT_EQ(res->status, 201) << path << ": " << res->body;
    }
  }
  static void TearDownTestSuite() {
    const ExitStatus s = daemon_->Stop(SIGTERM);
    EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
    delete daemon_;
    delete dir_;
    daemon_ = nullptr;
    dir_ = nullptr;
  }
  void SetUp() override { client_ = daemon_->MakeClient(); }

  /// The model served for (material, fingertip), decoded.
  StochasticFrictionModel Model(const std::string& id,
                                const std::string& fingertip = "default") {
    auto res = client_->Get(
        ("/v1/materials/" + id + "/model?fingertip=" + fingertip).c_str());
    EXPECT_TRUE(res && res->status == 200);
    return ModelSetFromJson(Body(res)).stochastic.value();
  }

  /// The risk quantile of mu computed independently of the export route.
  double Expected(const StochasticFrictionModel& m,
                  double risk,
                  double fn_n,
                  double v_mm_s) {
    return CalcMuDistribution(m, {{"fn_n", fn_n}, {"v_mm_s", v_mm_s}})
        .Quantile(risk);
  }

  httplib::Result Export(const std::string& id, const std::string& query) {
    return client_->Get(("/v1/materials/" + id + "/export?" + query).c_str());
  }

  static TempDir* dir_;
  static DaemonProcess* daemon_;
  std::unique_ptr<httplib::Client> client_;
};

TempDir* ExportHttpTest::dir_ = nullptr;
DaemonProcess* ExportHttpTest::daemon_ = nullptr;

TEST_F(ExportHttpTest, BundledMaterialInEveryFormatRoundTrips) {
  const StochasticFrictionModel m = Model(kBundled);
  const double fn = m.inputs.at("fn_n").mean;
  const double v = m.inputs.at("v_mm_s").mean;
  // Below the smallest risk the bundled data support (about 120 effectively
  // independent samples): 422 naming it, as on the grip-force route.
  {
    auto res = Export(kBundled, "risk=0.001&format=mjcf");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 422) << res->body;
    const json body = json::parse(res->body, nullptr, false);
    ASSERT_TRUE(body.contains("min_supported_risk")) << res->body;
    EXPECT_NEAR(body["min_supported_risk"].get<double>(),
                CalcMinSupportedRisk(m, 0.0),
                1e-12);
    EXPECT_EQ(body["field"], "risk");
  }
  for (double risk : {0.01, 0.05}) {
    const double want = Expected(m, risk, fn, v);
    const std::string q = "risk=" + std::to_string(risk) + "&format=";
    std::printf(
        "[ info ] %s: exported sliding mu at risk %g = %.6f "
        "(mean %.6f) at fn_n %.4g N, v_mm_s %.4g mm/s\n",
        kBundled,
        risk,
        want,
        CalcMuDistribution(m, {{"fn_n", fn}, {"v_mm_s", v}}).mean,
        fn,
        v);
    {
      auto res = Export(kBundled, q + "mjcf");
      ASSERT_TRUE(res);
      ASSERT_EQ(res->status, 200) << res->body;
      EXPECT_EQ(res->get_header_value("Content-Type"),
                "application/xml; charset=utf-8");
      tinyxml2::XMLDocument doc;
      ASSERT_EQ(doc.Parse(res->body.c_str(), res->body.size()),
                tinyxml2::XML_SUCCESS)
          << doc.ErrorStr() << "\n"
          << res->body;
      const auto* geom = doc.FirstChildElement("mujoco")
                             ->FirstChildElement("default")
                             ->FirstChildElement("default")
                             ->FirstChildElement("geom");
      ASSERT_NE(geom, nullptr) << res->body;
      ExpectRel(ToDouble(geom->Attribute("friction")), want, "mjcf");
    }
    {
      auto res = Export(kBundled, q + "sdf");
      ASSERT_TRUE(res && res->status == 200);
      tinyxml2::XMLDocument doc;
      ASSERT_EQ(doc.Parse(res->body.c_str()), tinyxml2::XML_SUCCESS);
      const auto* ode = doc.FirstChildElement("surface")
                            ->FirstChildElement("friction")
                            ->FirstChildElement("ode");
      ExpectRel(ToDouble(ode->FirstChildElement("mu")->GetText()), want, "sdf");
    }
    {
      auto res = Export(kBundled, q + "urdf&name=finger_link");
      ASSERT_TRUE(res && res->status == 200);
      tinyxml2::XMLDocument doc;
      ASSERT_EQ(doc.Parse(res->body.c_str()), tinyxml2::XML_SUCCESS);
      const auto* gz =
          doc.FirstChildElement("robot")->FirstChildElement("gazebo");
      EXPECT_STREQ(gz->Attribute("reference"), "finger_link");
      ExpectRel(
          ToDouble(gz->FirstChildElement("mu1")->GetText()), want, "urdf");
    }
    {
      auto res = Export(kBundled, q + "usd");
      ASSERT_TRUE(res && res->status == 200);
      EXPECT_EQ(res->get_header_value("Content-Type"),
                "model/vnd.usda; charset=utf-8");
      const usda::Layer layer = usda::Parse(res->body);
      const usda::Prim& p = layer.prims.at(0);
      EXPECT_EQ(p.name, "microtribo_recip");  // '-' is not a USD name char
      ExpectRel(
          ToDouble(
              p.attributes.at("physics:dynamicFriction").values[0].c_str()),
          want,
          "usd");
    }
    {
      auto res = Export(kBundled, q + "isaac");
      ASSERT_TRUE(res && res->status == 200);
      EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
      const json j = Body(res);
      ExpectRel(j["static_friction_range"][0].get<double>(), want, "isaac lo");
      ExpectRel(j["dynamic_friction_range"][1].get<double>(),
                Expected(m, 1 - risk, fn, v),
                "isaac hi");
    }
  }
}

TEST_F(ExportHttpTest, OperatingPointAndFingertipFromQuery) {
  const StochasticFrictionModel m = Model("cup", "pad");
  auto res = Export("cup", "format=mjcf&fingertip=pad&fn_n=1.5&v_mm_s=30");
  ASSERT_TRUE(res && res->status == 200) << (res ? res->body : "");
  tinyxml2::XMLDocument doc;
  ASSERT_EQ(doc.Parse(res->body.c_str()), tinyxml2::XML_SUCCESS);
  const double got = ToDouble(doc.FirstChildElement("mujoco")
                                  ->FirstChildElement("default")
                                  ->FirstChildElement("default")
                                  ->FirstChildElement("geom")
                                  ->Attribute("friction"));
  ExpectRel(got, Expected(m, 0.05, 1.5, 30), "default risk 0.05");
  // The simulated truth is b0 = 0.7 at fingertip 'pad': the default-fingertip
  // model of cup (b0 = 0.5) would be far off.
  EXPECT_GT(got - Expected(Model("cup"), 0.05, 1.5, 30), 0.1);
  EXPECT_NE(res->body.find("fingertip 'pad'"), std::string::npos);
  EXPECT_NE(res->body.find("fn_n = 1.5 N, v_mm_s = 30 mm/s (query)"),
            std::string::npos)
      << res->body;
}

TEST_F(ExportHttpTest, BadParametersAre400NamingTheFieldAndStoreNothing) {
  struct Case {
    std::string query;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"", "format"},
      {"format=stl", "format"},
      {"format=mjcf&risk=0.9", "risk"},
      {"format=mjcf&risk=0.0001", "risk"},
      {"format=mjcf&risk=abc", "risk"},
      {"format=mjcf&fn_n=-1", "fn_n"},
      {"format=mjcf&fn_n=nan", "fn_n"},
      {"format=mjcf&v_mm_s=-3", "v_mm_s"},
      {"format=mjcf&name=a%20b", "name"},
      {"format=mjcf&version=0", "version"},
      {"format=mjcf&fingertip=..", "fingertip"},
      {"format=mjcf&riks=0.1", "riks"},
  };
  const std::string db = daemon_->options().db;
  client_->Get("/v1/materials");  // settles the WAL index
  const auto before = DbFingerprint(db);
  // Also for an unknown material: parameters are checked first, so no
  // identification is recorded for a malformed request.
  for (const std::string& id : {std::string(kBundled), std::string("nobody")}) {
    for (const Case& c : cases) {
      auto res = Export(id, c.query);
      ASSERT_TRUE(res);
      EXPECT_EQ(res->status, 400) << id << "?" << c.query << ": " << res->body;
      const json j = Body(res);
      EXPECT_EQ(j.value("field", ""), c.field) << c.query << ": " << res->body;
      EXPECT_FALSE(j.value("detail", "").empty());
    }
  }
  EXPECT_EQ(DbFingerprint(db), before);
  auto res = Export(kBundled, "format=mjcf&version=999");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404);
  EXPECT_EQ(Body(res).value("field", ""), "version");
}

TEST_F(ExportHttpTest, UnknownMaterialIs404WithIdentificationRequest) {
  auto res = Export("velvet", "format=sdf");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404);
  const json j = Body(res);
  EXPECT_EQ(j.value("known_material", true), false);
  EXPECT_TRUE(j["identification"].value("requested", false)) << j.dump();
}

TEST_F(ExportHttpTest, MeasuredPairIsAnsweredDirectly) {
  const StochasticFrictionModel m = Model("cup", "pad");
  auto res = client_->Get("/v1/pairs/pad/cup/friction?fn_n=2&v_mm_s=40");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const json j = Body(res);
  EXPECT_TRUE(j.value("measured", false));
  EXPECT_TRUE(j["rule"].is_null());
  EXPECT_EQ(j["source"].value("material", ""), "cup");
  EXPECT_EQ(j["source"].value("fingertip", ""), "pad");
  const MuDistribution d = CalcMuDistribution(m, {{"fn_n", 2}, {"v_mm_s", 40}});
  ExpectRel(j["mu"].get<double>(), d.mean, "mu");
  ExpectRel(j["sigma"].get<double>(), d.sigma, "sigma");
  ExpectRel(j["mu_at_risk"].get<double>(), d.Quantile(0.05), "mu_at_risk");
  // The same contact asked from the other side is the same measurement.
  const json k =
      Body(client_->Get("/v1/pairs/cup/pad/friction?fn_n=2&v_mm_s=40"));
  EXPECT_TRUE(k.value("measured", false));
  EXPECT_EQ(k["mu"], j["mu"]);
}

TEST_F(ExportHttpTest, UnmeasuredPairIsCombinedByANamedRule) {
  // pad and box were each measured with the default fingertip only.
  const StochasticFrictionModel a = Model("pad"), b = Model("box");
  const InputValues x{{"fn_n", 2}, {"v_mm_s", 40}};
  const MuDistribution da = CalcMuDistribution(a, x);
  const MuDistribution db = CalcMuDistribution(b, x);
  auto res = client_->Get("/v1/pairs/pad/box/friction?fn_n=2&v_mm_s=40");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const json j = Body(res);
  EXPECT_FALSE(j.value("measured", true));
  EXPECT_EQ(j.value("rule", ""), "harmonic");  // the documented default
  EXPECT_EQ(j.value("rule_engine", ""), "Drake");
  const MuDistribution hm =
      CombineMuDistributions(da, db, CombineRule::kHarmonicMean);
  ExpectRel(j["mu"].get<double>(), hm.mean, "harmonic mean");
  ExpectRel(j["sigma"].get<double>(), hm.sigma, "sigma");
  EXPECT_GT(j["sigma"].get<double>(), 0.0);
  EXPECT_EQ(j["inputs"].size(), 2u);
  const double mx = j["rules"]["max"]["mu"], av = j["rules"]["average"]["mu"];
  EXPECT_LT(j["mu"].get<double>(), av);
  EXPECT_LT(av, mx);
  EXPECT_NEAR(
      j["rule_spread"].get<double>(), mx - j["mu"].get<double>(), 1e-12);
  ExpectRel(j["inputs"][0]["mu"].get<double>(), da.mean, "pad alone");
  ExpectRel(j["inputs"][1]["mu"].get<double>(), db.mean, "box alone");
  const json k = Body(
      client_->Get("/v1/pairs/pad/box/friction?fn_n=2&v_mm_s=40&rule=max"));
  EXPECT_EQ(k.value("rule", ""), "max");
  EXPECT_EQ(k["mu"], j["rules"]["max"]["mu"]);
}

TEST_F(ExportHttpTest, PairBadInput) {
  struct Case {
    std::string path;
    int status;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"/v1/pairs/pad/cup/friction?rule=min", 400, "rule"},
      {"/v1/pairs/pad/cup/friction?fn_n=0", 400, "fn_n"},
      {"/v1/pairs/pad/cup/friction?risk=2", 400, "risk"},
      {"/v1/pairs/pad/cup/friction?reference=a%20b", 400, "reference"},
      {"/v1/pairs/pad/cup/friction?bogus=1", 400, "bogus"},
      {"/v1/pairs/p%20d/cup/friction", 400, "fingertip"},
      {"/v1/pairs/pad/nothing-here/friction", 404, "object"},
  };
  for (const Case& c : cases) {
    auto res = client_->Get(c.path.c_str());
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, c.status) << c.path << ": " << res->body;
    EXPECT_EQ(Body(res).value("field", ""), c.field) << c.path;
  }
}

std::string ReadAll(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST_F(ExportHttpTest, CliExportWritesAParsableFile) {
  const std::filesystem::path out = dir_->path() + "/cup.sdf";
  const std::filesystem::path err = dir_->path() + "/err.txt";
  const std::string base = testing::BinaryPath("friction") + " --server " +
                           daemon_->base_url() + " --fingertip pad ";
  int status = std::system((base + "export cup --format sdf --risk 0.01 -o " +
                            out.string() + " 2>" + err.string())
                               .c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << ReadAll(err);
  tinyxml2::XMLDocument doc;
  const std::string text = ReadAll(out);
  ASSERT_EQ(doc.Parse(text.c_str()), tinyxml2::XML_SUCCESS) << text;
  ExpectRel(ToDouble(doc.FirstChildElement("surface")
                         ->FirstChildElement("friction")
                         ->FirstChildElement("ode")
                         ->FirstChildElement("mu")
                         ->GetText()),
            Expected(Model("cup", "pad"),
                     0.01,
                     Model("cup", "pad").inputs.at("fn_n").mean,
                     Model("cup", "pad").inputs.at("v_mm_s").mean),
            "cli sdf");
  status = std::system(
      (base + "export cup --format stl >/dev/null 2>" + err.string()).c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1);
  EXPECT_NE(ReadAll(err).find("format = 'stl'"), std::string::npos)
      << ReadAll(err);
}

}  // namespace
}  // namespace frictiond
