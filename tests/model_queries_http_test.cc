// Model-query routes (paper 000) end to end (docs/paper000.md): the real
// `frictiond` over loopback HTTP, the client library calls and the `friction`
// CLI.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

// Eigen before httplib.h (see export_http_test.cc).
#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>

#include "frictiond/client/client.h"
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

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class ModelQueriesHttpTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("model_queries_http_test");
    DaemonOptions options;
    options.db = dir_->path() + "/library.db";
    options.data = "none";
    daemon_ = new DaemonProcess(options);
    daemon_->Start();
    testing::SimulationSpec spec;
    spec.strokes = 12;
    auto c = daemon_->MakeClient();
    auto res = c->Post("/v1/materials/pad/strokes",
                       FormatStrokeCsv(testing::SimulateStrokes(spec, 31)),
                       "text/csv");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 201) << res->body;
  }
  static void TearDownTestSuite() {
    const ExitStatus s = daemon_->Stop(SIGTERM);
    EXPECT_TRUE(s.exited && s.code == 0) << s.ToString();
    delete daemon_;
    delete dir_;
    daemon_ = nullptr;
    dir_ = nullptr;
  }
  FrictionClient Client() {
    ClientOptions o;
    o.base_url = daemon_->base_url();
    o.token = daemon_->options().operator_token;
    return FrictionClient(o);
  }
  // Runs the CLI; returns its exit code, stdout in *out, stderr in *err.
  int Cli(const std::string& args, std::string* out, std::string* err) {
    const std::string o = dir_->path() + "/out.txt";
    const std::string e = dir_->path() + "/err.txt";
    const int status = std::system(
        (testing::BinaryPath("friction") + " --server " + daemon_->base_url() +
         " --token " + daemon_->options().operator_token + " " + args + " >" +
         o + " 2>" + e)
            .c_str());
    *out = ReadText(o);
    *err = ReadText(e);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  static TempDir* dir_;
  static DaemonProcess* daemon_;
};

TempDir* ModelQueriesHttpTest::dir_ = nullptr;
DaemonProcess* ModelQueriesHttpTest::daemon_ = nullptr;

TEST_F(ModelQueriesHttpTest, ClientTargetForceAndSlidingSpeedRoundTrip) {
  FrictionClient c = Client();
  const testing::SimulationSpec truth;
  const json f = c.FetchTargetForce("pad", 3.0, 50.0);
  EXPECT_NEAR(f.at("ft_n").get<double>(),
              (truth.b0 + truth.b1 * 50 + truth.b2 * 3) * 3,
              0.02)
      << f.dump();
  const json s = c.FetchSlidingSpeed("pad", 3.0, f.at("ft_n").get<double>());
  EXPECT_NEAR(s.at("v_mm_s").get<double>(), 50.0, 1e-6) << s.dump();
  try {
    c.FetchTargetForce("pad", -1.0, 50.0);
    FAIL() << "no throw";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 400);
    EXPECT_NE(std::string(e.what()).find("fn_n"), std::string::npos)
        << e.what();
  }
}

TEST_F(ModelQueriesHttpTest, CliTargetForceAndSlidingSpeed) {
  std::string out, err;
  ASSERT_EQ(Cli("target-force pad --fn-n 2 --v-mm-s 30", &out, &err), 0) << err;
  const double ft = json::parse(out).at("ft_n").get<double>();
  ASSERT_EQ(Cli("sliding-speed pad --fn-n 2 --ft-n " + std::to_string(ft),
                &out,
                &err),
            0)
      << err;
  EXPECT_NEAR(json::parse(out).at("v_mm_s").get<double>(), 30.0, 1e-3) << out;
  EXPECT_EQ(Cli("sliding-speed pad --fn-n 0 --ft-n 1", &out, &err), 2);
  EXPECT_NE(err.find("--fn-n"), std::string::npos) << err;
  EXPECT_EQ(Cli("target-force nothing --fn-n 1 --v-mm-s 3", &out, &err), 1);
}

TEST_F(ModelQueriesHttpTest, ClientAndCliConditionalSlipAndForms) {
  FrictionClient c = Client();
  const json in = c.FetchConditionalSlipLikelihood("pad", 2.5, 0.9);
  EXPECT_FALSE(in.at("extrapolated").get<bool>()) << in.dump();
  const json out = c.FetchConditionalSlipLikelihood("pad", 20.0, 0.9);
  EXPECT_TRUE(out.at("extrapolated").get<bool>()) << out.dump();
  const json forms = c.FetchForms("pad", 4);
  EXPECT_EQ(forms.at("folds").get<int>(), 4) << forms.dump();
  EXPECT_EQ(forms.at("forms").size(), 6u);
  std::string o, err;
  ASSERT_EQ(Cli("conditional-slip pad --fn-n 9 --ratio 0.5", &o, &err), 0)
      << err;
  EXPECT_TRUE(json::parse(o).at("extrapolated").get<bool>()) << o;
  ASSERT_EQ(Cli("forms pad", &o, &err), 0) << err;
  EXPECT_TRUE(json::parse(o).at("compared").get<bool>()) << o;
  EXPECT_EQ(Cli("forms pad --folds 1", &o, &err), 1);
  EXPECT_NE(err.find("folds"), std::string::npos) << err;
}

TEST_F(ModelQueriesHttpTest, ClientAndCliMuSpreadAndSpanVariability) {
  FrictionClient c = Client();
  const json m =
      c.FetchMuSpread("pad",
                      2.5,
                      40.0,
                      {{"fn_widths_n", "inf,1"}, {"v_widths_mm_s", "inf,20"}});
  ASSERT_EQ(m.at("both_windows").size(), 2u) << m.dump();
  EXPECT_LT(m["both_windows"][1]["std_mu"].get<double>(),
            m["both_windows"][0]["std_mu"].get<double>());
  const json s = c.FetchSpanVariability("pad", {{"subsets", "30"}});
  EXPECT_TRUE(s.at("valid").get<bool>()) << s.dump();
  std::string o, err;
  ASSERT_EQ(Cli("span-variability pad --subsets 20 --seed 2", &o, &err), 0)
      << err;
  EXPECT_EQ(json::parse(o).at("subsets").get<int>(), 20) << o;
  ASSERT_EQ(Cli("mu-spread pad --fn-n 2 --v-mm-s 30", &o, &err), 0) << err;
  EXPECT_TRUE(json::parse(o).contains("fn_windows")) << o;
  EXPECT_EQ(Cli("span-variability pad --subsets 0", &o, &err), 1);
  EXPECT_NE(err.find("subsets"), std::string::npos) << err;
}

int CountOf(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t p = text.find(what); p != std::string::npos;
       p = text.find(what, p + 1))
    ++n;
  return n;
}

TEST(FrictionReport, SimulatedAndMeasuredData) {
  TempDir dir("friction_report_test");
  testing::SimulationSpec spec;
  spec.strokes = 20;
  const std::string csv = dir.path() + "/sim.csv";
  {
    std::ofstream o(csv);
    o << FormatStrokeCsv(testing::SimulateStrokes(spec, 9));
  }
  const std::string html = dir.path() + "/sim.html";
  const std::string bin = testing::BinaryPath("friction");
  int st = std::system(
      (bin + " report " + csv + " -o " + html + " >/dev/null").c_str());
  ASSERT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0);
  std::string text = ReadText(html);
  EXPECT_EQ(CountOf(text, "<svg"), 5) << text.substr(0, 2000);
  EXPECT_EQ(CountOf(text, "<tr>"), 7);  // header + 6 claims
  // Simulated from eq. (1) with an Fn slope: the Fn claims are testable.
  EXPECT_EQ(CountOf(text, "cannot be tested"), 0) << text.substr(0, 4000);
  // The measured constant-load data: Fn claims cannot be tested.
  const std::string measured =
      testing::SourceDir() + "/data/microtribo_recip/test_data_2.strokes.csv";
  st = std::system((bin + " report " + measured + " -o " + html +
                    " --slip-peak-mm-s 0.1 --slip-floor-mm-s 0.02 "
                    "--median-window-s 0.05 >/dev/null")
                       .c_str());
  ASSERT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 0);
  text = ReadText(html);
  EXPECT_GE(CountOf(text, "cannot be tested"), 2) << text.substr(0, 4000);
  EXPECT_NE(text.find("does not increase"), std::string::npos);
  st = std::system((bin + " report " + dir.path() + "/missing.csv -o " + html +
                    " 2>/dev/null")
                       .c_str());
  EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) == 2);
}

}  // namespace
}  // namespace frictiond
