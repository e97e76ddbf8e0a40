// The operator console's daemon side (docs/console.md) over loopback HTTP:
// the static files compiled into frictiond are the project's files, served
// with their content types and a CSP that forbids other origins, and
// GET /v1/materials/{id}/samples returns decimated slipping samples with
// their Fn-v hull and span coverage. The browser side is
// tests/browser/console_test.mjs.
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

// Eigen before httplib.h: <resolv.h> (via httplib) defines a macro _res
// that breaks Eigen's product kernels.
#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::TempDir;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

json Body(const httplib::Result& res) {
  if (!res) {
    ADD_FAILURE() << "no response: " << httplib::to_string(res.error());
    return json();
  }
  json j = json::parse(res->body, nullptr, false);
  if (j.is_discarded()) ADD_FAILURE() << "not JSON: " << res->body;
  return j;
}

class ConsoleHttpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    DaemonOptions options;
    options.db = dir_.path() + "/library.db";
    options.data = "none";
    daemon_ = std::make_unique<DaemonProcess>(options);
    daemon_->Start();
    client_ = daemon_->MakeClient(20.0);
  }

  TempDir dir_{"console_http_test"};
  std::unique_ptr<DaemonProcess> daemon_;
  std::unique_ptr<httplib::Client> client_;
};

TEST_F(ConsoleHttpTest, ServesTheProjectsConsoleFilesWithCsp) {
  const std::string src = testing::SourceDir() + "/server/console/";
  struct Case {
    std::string path, file, type;
  };
  const std::vector<Case> cases = {
      {"/", "index.html", "text/html"},
      {"/console/index.html", "index.html", "text/html"},
      {"/console/app.js", "app.js", "text/javascript"},
      {"/console/style.css", "style.css", "text/css"}};
  for (const Case& c : cases) {
    auto res = client_->Get(c.path);
    ASSERT_TRUE(res) << c.path;
    EXPECT_EQ(res->status, 200) << c.path;
    EXPECT_EQ(res->get_header_value("Content-Type"), c.type + "; charset=utf-8")
        << c.path;
    const std::string expected = ReadFile(src + c.file);
    ASSERT_FALSE(expected.empty()) << src + c.file;
    EXPECT_EQ(res->body, expected) << c.path << " differs from " << c.file;
    const std::string csp = res->get_header_value("Content-Security-Policy");
    EXPECT_NE(csp.find("default-src 'none'"), std::string::npos) << csp;
    EXPECT_NE(csp.find("script-src 'self'"), std::string::npos) << csp;
    EXPECT_NE(csp.find("connect-src 'self'"), std::string::npos) << csp;
    EXPECT_EQ(res->get_header_value("X-Content-Type-Options"), "nosniff");
  }
  // The page loads nothing from elsewhere.
  const std::string page = ReadFile(src + "index.html");
  EXPECT_EQ(page.find("http://"), std::string::npos);
  EXPECT_EQ(page.find("https://"), std::string::npos);
}

TEST_F(ConsoleHttpTest, UnknownConsoleFilesAre404WithoutLeavingTheBundle) {
  for (const std::string path :
       {"/console/nope.js", "/console/..%2FCMakeLists.txt", "/console/"}) {
    auto res = client_->Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 404) << path << ": " << res->body;
    EXPECT_EQ(Body(res).value("error", ""), "not found") << path;
  }
  auto res = client_->Post("/", "x", "text/plain");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 405);
}

TEST_F(ConsoleHttpTest, SamplesRouteReturnsDecimatedSlipSamplesAndHull) {
  // No model yet: 404 naming the material, and no identification requested.
  auto none = client_->Get("/v1/materials/felt/samples");
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 404);
  EXPECT_NE(Body(none).value("detail", "").find("felt"), std::string::npos);
  EXPECT_TRUE(
      Body(client_->Get("/v1/identifications"))["identifications"].empty());

  testing::SimulationSpec spec;
  spec.strokes = 8;
  const std::string csv =
      FormatStrokeCsv(testing::SimulateStrokes(spec, /*seed=*/3));
  auto up = client_->Post("/v1/materials/felt/strokes", csv, "text/csv");
  ASSERT_TRUE(up);
  ASSERT_EQ(up->status, 201) << up->body;
  const json model = Body(client_->Get("/v1/materials/felt/model"));

  const json all = Body(client_->Get("/v1/materials/felt/samples?max=20000"));
  const json few = Body(client_->Get("/v1/materials/felt/samples?max=100"));
  const std::size_t n = all.at("slip_samples").get<std::size_t>();
  EXPECT_EQ(n, model["stochastic"]["samples_slip"].get<std::size_t>());
  EXPECT_EQ(all["returned"].get<std::size_t>(), n);
  EXPECT_EQ(all["stride"], 1);
  EXPECT_EQ(few["slip_samples"].get<std::size_t>(), n);
  EXPECT_LE(few["returned"].get<std::size_t>(), 100u);
  EXPECT_GE(few["returned"].get<std::size_t>(), 50u);
  EXPECT_EQ(few["fn_n"].size(), few["returned"].get<std::size_t>());
  EXPECT_EQ(few["mu"].size(), few["returned"].get<std::size_t>());
  EXPECT_EQ(few["stroke"].size(), few["returned"].get<std::size_t>());

  // Every sample lies inside (or on) the hull, which is convex and
  // counter-clockwise; the reported area is the hull polygon's.
  const auto& hf = all["hull"]["fn_n"];
  const auto& hv = all["hull"]["v_mm_s"];
  ASSERT_GE(hf.size(), 3u);
  double twice = 0.0;
  for (std::size_t k = 0; k < hf.size(); ++k) {
    const std::size_t j = (k + 1) % hf.size();
    twice += hf[k].get<double>() * hv[j].get<double>() -
             hf[j].get<double>() * hv[k].get<double>();
  }
  EXPECT_GT(twice, 0.0);
  EXPECT_NEAR(all["hull"]["area"].get<double>(), twice / 2, 1e-9 * twice);
  for (std::size_t i = 0; i < all["fn_n"].size(); ++i) {
    const double x = all["fn_n"][i], y = all["v_mm_s"][i];
    for (std::size_t k = 0; k < hf.size(); ++k) {
      const std::size_t j = (k + 1) % hf.size();
      const double cross = (hf[j].get<double>() - hf[k].get<double>()) *
                               (y - hv[k].get<double>()) -
                           (hv[j].get<double>() - hv[k].get<double>()) *
                               (x - hf[k].get<double>());
      ASSERT_GE(cross, -1e-9) << "sample " << i << " outside hull edge " << k;
    }
    // mu is Ft/Fn of a slipping sample: near the simulated law.
    const double mu = all["mu"][i];
    EXPECT_NEAR(mu, spec.b0 + spec.b1 * y + spec.b2 * x, 0.4) << i;
  }
  const double span = all["coverage"]["span_pct"];
  EXPECT_GT(span, 0.0);
  EXPECT_LE(span, 100.0);
  EXPECT_EQ(all["coverage"]["plan"]["fn_n"].size(), 2u);
}

TEST_F(ConsoleHttpTest, SamplesRouteRejectsBadParameters) {
  testing::SimulationSpec spec;
  spec.strokes = 4;
  ASSERT_EQ(client_
                ->Post("/v1/materials/felt/strokes",
                       FormatStrokeCsv(testing::SimulateStrokes(spec, 5)),
                       "text/csv")
                ->status,
            201);
  struct Case {
    std::string query;
    int status;
    std::string field;
  };
  for (const Case& c : std::vector<Case>{{"max=0", 400, "max"},
                                         {"max=2.5", 400, "max"},
                                         {"max=abc", 400, "max"},
                                         {"max=20001", 400, "max"},
                                         {"bogus=1", 400, "bogus"},
                                         {"version=0", 400, "version"},
                                         {"version=9", 404, "version"},
                                         {"fingertip=a%20b", 400, "fingertip"},
                                         {"version=1", 200, ""}}) {
    auto res = client_->Get("/v1/materials/felt/samples?" + c.query);
    ASSERT_TRUE(res) << c.query;
    EXPECT_EQ(res->status, c.status) << c.query << ": " << res->body;
    if (!c.field.empty()) {
      EXPECT_EQ(Body(res).value("field", ""), c.field) << c.query;
    }
  }
  auto bad_id = client_->Get("/v1/materials/bad%20id/samples");
  ASSERT_TRUE(bad_id);
  EXPECT_EQ(bad_id->status, 400);
}

}  // namespace
}  // namespace frictiond
