// Joint friction and repeatability routes (issue 9 item 5), through
// HttpServer::Dispatch on an in-memory library: joint data simulated from a
// known mixed-lubrication truth, uploaded as CSV.
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/estimators/joint_friction.h"
#include "frictiond/estimators/joint_identification.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/library.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"

namespace frictiond {
namespace {

using nlohmann::json;

MixedFrictionTheta Truth() {
  return MakeMixedFrictionTheta(0.1, 0.004, 0.5, 0.6);
}

// 400 samples, speeds 5..2000 mm/s, loads 20..200 N, 20..80 C (seed 3).
std::string JointCsv(unsigned seed = 3) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> v, load, temp;
  for (int i = 0; i < 400; ++i) {
    v.push_back(5.0 * std::pow(400.0, u(rng)));
    load.push_back(20.0 + 180.0 * u(rng));
    temp.push_back(20.0 + 60.0 * u(rng));
  }
  const JointData d =
      SimulateJointData(Truth(), JointConfig{}, v, load, temp, 0.002, seed);
  std::ostringstream out;
  out.precision(10);
  out << "# simulated joint data\nv_mm_s,load_n,temp_c,mu\n";
  for (std::size_t i = 0; i < d.size(); ++i)
    out << d.v_mm_s[i] << ',' << d.load_n[i] << ',' << d.temp_c[i] << ','
        << d.mu[i] << '\n';
  return out.str();
}

const char* kArm = R"({
  "joints": [
    {"type": "revolute", "alpha_deg": 90, "d_mm": 300, "stiffness": 20000,
     "sigma_tau": 5},
    {"type": "revolute", "a_mm": 400, "stiffness": 20000, "sigma_tau": 5},
    {"type": "revolute", "a_mm": 350, "stiffness": 20000, "sigma_tau": 5}
  ],
  "q_home": [0, 20, -60]
})";

class JointRoutesTest : public ::testing::Test {
 protected:
  JointRoutesTest() : lib_(OpenStore(":memory:")) {
    RegisterCoreRoutes(http_, lib_);
    RegisterJointRoutes(http_, lib_);
    InstallQueryCheck(http_);  // as the daemon does
  }
  HttpResponse Send(const std::string& method,
                    const std::string& path,
                    std::multimap<std::string, std::string> query = {},
                    const std::string& body = "",
                    const std::string& content_type = "") {
    HttpRequest r;
    r.method = method;
    r.path = path;
    r.remote_addr = "127.0.0.1";
    r.query = std::move(query);
    r.body = body;
    if (!content_type.empty()) r.headers.emplace("Content-Type", content_type);
    return http_.Dispatch(r);
  }
  HttpResponse Upload(const std::string& csv,
                      std::multimap<std::string, std::string> query = {
                          {"joint", "j2"}}) {
    return Send(
        "POST", "/v1/materials/steel-oil/joint-data", query, csv, "text/csv");
  }
  static void ExpectField(const HttpResponse& r,
                          int status,
                          const std::string& field) {
    EXPECT_EQ(r.status, status) << r.body;
    const json j = json::parse(r.body);
    EXPECT_EQ(j.value("field", ""), field) << r.body;
  }
  FrictionLibrary lib_;
  HttpServer http_;
};

TEST_F(JointRoutesTest, UploadFitsTheThreeModelsAndServesFriction) {
  const HttpResponse up = Upload(JointCsv());
  ASSERT_EQ(up.status, 201) << up.body;
  const json u = json::parse(up.body);
  EXPECT_EQ(u["version"], 1);
  const json& mixed = u["family"]["models"]["mixed"];
  EXPECT_EQ(mixed["status"], "converged") << mixed.dump();
  EXPECT_NEAR(mixed["theta"]["f_s"].get<double>(), 0.1, 2e-3);
  EXPECT_NEAR(mixed["theta"]["d_ref_um"].get<double>(), 0.5, 0.05);
  // The mixed model wins on held-out error.
  const json& models = u["family"]["models"];
  EXPECT_LT(mixed["heldout_rmse"].get<double>(),
            models["stribeck_viscous"]["heldout_rmse"].get<double>());
  EXPECT_LT(mixed["heldout_rmse"].get<double>(),
            models["lugre_steady_state"]["heldout_rmse"].get<double>());

  const HttpResponse q = Send("GET",
                              "/v1/materials/steel-oil/joint-friction",
                              {{"joint", "j2"},
                               {"v_mm_s", "200"},
                               {"load_n", "100"},
                               {"temp_c", "40"}});
  ASSERT_EQ(q.status, 200) << q.body;
  const json a = json::parse(q.body);
  const double eta = CalcViscosity(Lubricant{}, 40.0);
  const double s = CalcSommerfeldUm(eta, 200, 100, JointContact{});
  const double truth = CalcMixedFriction(Truth(), AsperitySurface{}, s, 100);
  EXPECT_NEAR(a["sommerfeld_um"].get<double>(), s, 1e-12);
  EXPECT_NEAR(a["mu"].get<double>(), truth, 3e-3) << q.body;
  EXPECT_GT(a["sigma"].get<double>(), 0.0);
  EXPECT_EQ(a["regime"], "mixed");
  EXPECT_TRUE(a["classic"]["stribeck_viscous"].is_number());
  // Hot oil thins the film: friction rises at the same speed and load.
  const HttpResponse hot = Send("GET",
                                "/v1/materials/steel-oil/joint-friction",
                                {{"joint", "j2"},
                                 {"v_mm_s", "200"},
                                 {"load_n", "100"},
                                 {"temp_c", "80"}});
  ASSERT_EQ(hot.status, 200) << hot.body;
  EXPECT_GT(json::parse(hot.body)["mu"].get<double>(), a["mu"].get<double>());
  // Wear drift: friction falls as the summits wear.
  const HttpResponse w = Send("GET",
                              "/v1/materials/steel-oil/joint-wear",
                              {{"joint", "j2"},
                               {"v_mm_s", "200"},
                               {"load_n", "100"},
                               {"temp_c", "40"},
                               {"distance_mm", "1e6"},
                               {"points", "5"}});
  ASSERT_EQ(w.status, 200) << w.body;
  const json pts = json::parse(w.body)["points"];
  ASSERT_EQ(pts.size(), 5u);
  EXPECT_LT(pts[4]["mu"].get<double>(), pts[0]["mu"].get<double>());
  // The family is part of the pair's model document.
  const HttpResponse m =
      Send("GET", "/v1/materials/steel-oil/model", {{"fingertip", "j2"}});
  ASSERT_EQ(m.status, 200) << m.body;
  EXPECT_TRUE(json::parse(m.body).contains("joint"));
}

TEST_F(JointRoutesTest, ServedIntervalNeverReachesBelowZero) {
  // A friction coefficient is a ratio of magnitudes: over states far
  // inside and far outside the data's span (full film to dry contact),
  // the mean is >= 0 and the interval's lower bound is floored at 0, and
  // says so.
  ASSERT_EQ(Upload(JointCsv()).status, 201);
  int answered = 0, floored = 0;
  for (const char* v : {"0.01", "1", "50", "1000", "1e5", "1e7"}) {
    for (const char* load : {"0.1", "10", "200", "1e4"}) {
      for (const char* temp : {"20", "80"}) {
        const HttpResponse r = Send("GET",
                                    "/v1/materials/steel-oil/joint-friction",
                                    {{"joint", "j2"},
                                     {"v_mm_s", v},
                                     {"load_n", load},
                                     {"temp_c", temp}});
        if (r.status != 200) {
          EXPECT_EQ(r.status, 422) << r.body;  // overflow: refused, named
          continue;
        }
        ++answered;
        const json a = json::parse(r.body);
        const double mu = a["mu"].get<double>();
        const double sigma = a["sigma"].get<double>();
        const double lo = a["interval95"][0].get<double>();
        const double hi = a["interval95"][1].get<double>();
        EXPECT_GE(mu, 0.0) << r.body;
        EXPECT_GE(lo, 0.0) << r.body;
        EXPECT_NEAR(hi, mu + 1.959964 * sigma, 1e-12) << r.body;
        const bool was_below = mu - 1.959964 * sigma < 0;
        EXPECT_EQ(a["floored_at_zero"].get<bool>(), was_below) << r.body;
        if (!was_below) {
          EXPECT_NEAR(lo, mu - 1.959964 * sigma, 1e-12);
        }
        floored += was_below;
      }
    }
  }
  std::printf(
      "joint-friction: %d states answered, %d floored\n", answered, floored);
  EXPECT_GT(answered, 30);
}

TEST_F(JointRoutesTest, BadUploadsAnswer400NamingTheFieldAndStoreNothing) {
  ExpectField(Upload("v_mm_s,load_n,temp_c,mu\n10,-1,40,0.1\n"), 400, "load_n");
  ExpectField(Upload("v_mm_s,load_n,mu\n10,1,0.1\n"), 400, "temp_c");
  ExpectField(Upload("v_mm_s,load_n,temp_c,mu\n10,5,40,abc\n"), 400, "mu");
  ExpectField(
      Upload(JointCsv(), {{"joint", "j2"}, {"salt_um", "0"}}), 400, "salt_um");
  ExpectField(Upload(JointCsv(), {{"joint", "j2"}, {"area_mm2", "-5"}}),
              400,
              "area_mm2");
  ExpectField(Upload(JointCsv(), {{"joint", "j 2"}}), 400, "joint");
  ExpectField(
      Upload(JointCsv(), {{"joint", "j2"}, {"colour", "red"}}), 400, "colour");
  EXPECT_EQ(Send("POST",
                 "/v1/materials/steel-oil/joint-data",
                 {},
                 JointCsv(),
                 "application/json")
                .status,
            415);
  // Nothing stored: no material, no joint model.
  EXPECT_EQ(Send("GET", "/v1/materials/steel-oil").status, 404);
  EXPECT_EQ(
      Send(
          "GET",
          "/v1/materials/steel-oil/joint-friction",
          {{"joint", "j2"}, {"v_mm_s", "1"}, {"load_n", "1"}, {"temp_c", "40"}})
          .status,
      404);
}

TEST_F(JointRoutesTest, QueryParametersAreValidated) {
  ASSERT_EQ(Upload(JointCsv()).status, 201);
  const std::string path = "/v1/materials/steel-oil/joint-friction";
  ExpectField(Send("GET",
                   path,
                   {{"joint", "j2"},
                    {"v_mm_s", "-1"},
                    {"load_n", "1"},
                    {"temp_c", "40"}}),
              400,
              "v_mm_s");
  ExpectField(
      Send("GET", path, {{"joint", "j2"}, {"v_mm_s", "1"}, {"load_n", "1"}}),
      400,
      "temp_c");
  ExpectField(Send("GET",
                   path,
                   {{"joint", "j2"},
                    {"v_mm_s", "1"},
                    {"load_n", "1"},
                    {"temp_c", "-300"}}),
              400,
              "temp_c");
  // Valid but overflowing inputs: 422 naming the extreme one, never 200
  // with null numbers (outside attack run).
  ExpectField(Send("GET",
                   path,
                   {{"joint", "j2"},
                    {"v_mm_s", "10"},
                    {"load_n", "4.9e-324"},
                    {"temp_c", "40"}}),
              422,
              "load_n");
  ExpectField(Send("GET",
                   path,
                   {{"joint", "j2"},
                    {"v_mm_s", "1e300"},
                    {"load_n", "100"},
                    {"temp_c", "40"}}),
              422,
              "v_mm_s");
}

TEST_F(JointRoutesTest, RobotRepeatabilityWithGivenAndModelledFriction) {
  // Bad robots are rejected naming the field and not stored.
  json bad = json::parse(kArm);
  bad["joints"][1]["stiffness"] = 0;
  ExpectField(Send("PUT", "/v1/robots/arm1", {}, bad.dump()),
              400,
              "joints[1].stiffness");
  bad = json::parse(kArm);
  bad["joints"][2]["type"] = "screw";
  ExpectField(
      Send("PUT", "/v1/robots/arm1", {}, bad.dump()), 400, "joints[2].type");
  ExpectField(Send("PUT", "/v1/robots/arm1", {}, "{not json"), 400, "body");
  EXPECT_EQ(Send("GET", "/v1/robots/arm1").status, 404);

  ASSERT_EQ(Send("PUT", "/v1/robots/arm1", {}, kArm).status, 201);
  const HttpResponse r =
      Send("GET",
           "/v1/robots/arm1/repeatability",
           {{"x_mm", "350"}, {"y_mm", "150"}, {"z_mm", "100"}});
  ASSERT_EQ(r.status, 200) << r.body;
  const json e = json::parse(r.body);
  EXPECT_EQ(e["rank"], 3);
  EXPECT_LT(e["ik_error_mm"].get<double>(), 1e-6);
  // sd of a joint deflection: 5 / 20000 rad over ~0.4 m -> ~100 um scale.
  const double big = e["semi_axes_um"][2].get<double>();
  EXPECT_GT(big, 20.0);
  EXPECT_LT(big, 2000.0);
  ExpectField(Send("GET",
                   "/v1/robots/arm1/repeatability",
                   {{"x_mm", "350"}, {"y_mm", "150"}}),
              400,
              "z_mm");
  EXPECT_EQ(Send("GET",
                 "/v1/robots/arm1/repeatability",
                 {{"x_mm", "3000"}, {"y_mm", "0"}, {"z_mm", "0"}})
                .status,
            422);

  // Joint 2 takes its friction scatter from the uploaded joint model.
  json linked = json::parse(kArm);
  linked["joints"][1].erase("sigma_tau");
  linked["joints"][1]["friction"] = {{"material", "steel-oil"},
                                     {"joint", "j2"},
                                     {"v_mm_s", 200},
                                     {"load_n", 2000},
                                     {"temp_c", 40},
                                     {"radius_mm", 30}};
  ASSERT_EQ(Send("PUT", "/v1/robots/arm1", {}, linked.dump()).status, 200);
  EXPECT_EQ(Send("GET",
                 "/v1/robots/arm1/repeatability",
                 {{"x_mm", "350"}, {"y_mm", "150"}, {"z_mm", "100"}})
                .status,
            422);  // no joint model yet
  ASSERT_EQ(Upload(JointCsv()).status, 201);
  const HttpResponse r2 =
      Send("GET",
           "/v1/robots/arm1/repeatability",
           {{"x_mm", "350"}, {"y_mm", "150"}, {"z_mm", "100"}});
  ASSERT_EQ(r2.status, 200) << r2.body;
  const json e2 = json::parse(r2.body);
  EXPECT_EQ(e2["joints"][1]["source"], "joint model");
  const double sigma_tau = e2["joints"][1]["sigma_tau"].get<double>();
  const double sigma_mu = e2["joints"][1]["sigma_mu"].get<double>();
  EXPECT_NEAR(sigma_tau, sigma_mu * 2000 * 0.03, 1e-12);
  EXPECT_GT(sigma_tau, 0);

  const HttpResponse g =
      Send("GET",
           "/v1/robots/arm1/repeatability-grid",
           {{"z_mm", "0"}, {"x0_mm", "200"}, {"y0_mm", "-200"}, {"n", "4"}});
  ASSERT_EQ(g.status, 200) << g.body;
  EXPECT_EQ(json::parse(g.body)["points"].size(), 16u);
}

}  // namespace
}  // namespace frictiond
