// The daemon end to end over real HTTP on loopback (CONTRACT.md, "HTTP API"
// and "Daemon"): the real `frictiond` binary runs as a child process on a
// temporary database; requests go through cpp-httplib to 127.0.0.1.
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/sanitizers.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::ExitStatus;
using testing::TempDir;

/// Parses a response body as JSON; a non-JSON body fails the test with the
/// body shown.
json Body(const httplib::Result& res) {
  if (!res) {
    ADD_FAILURE() << "no response: " << httplib::to_string(res.error());
    return json();
  }
  json j = json::parse(res->body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) ADD_FAILURE() << "not JSON: " << res->body;
  return j;
}

/// Simulated strokes (paper 000 eq. (1) truth, SimulationSpec defaults:
/// b0 = 0.9, b1 = 0.004 per mm/s, b2 = -0.06 per N) as stroke CSV text.
std::string SimulatedCsv(std::uint64_t seed, int strokes = 8) {
  testing::SimulationSpec spec;
  spec.strokes = strokes;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

std::string Query(const std::string& path,
                  const std::vector<std::pair<std::string, std::string>>& q) {
  std::string out = path;
  char sep = '?';
  for (const auto& [k, v] : q) {
    out += sep + k + "=" + v;
    sep = '&';
  }
  return out;
}

/// One daemon for the suite, on the bundled data (default --data).
class HttpApiTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("http_api_test");
    DaemonOptions options;
    options.db = dir_->path() + "/library.db";
    daemon_ = new DaemonProcess(options);
    daemon_->Start();
  }
  static void TearDownTestSuite() {
    const ExitStatus s = daemon_->Stop(SIGTERM);
    EXPECT_TRUE(s.exited && s.code == 0)
        << "SIGTERM should stop the daemon cleanly, got " << s.ToString()
        << "\n"
        << daemon_->ReadLog();
    delete daemon_;
    delete dir_;
    daemon_ = nullptr;
    dir_ = nullptr;
  }
  void SetUp() override { client_ = daemon_->MakeClient(); }

  /// Uploads a CSV; returns the response.
  httplib::Result Upload(const std::string& id,
                         const std::string& csv,
                         const std::string& robot = "test-robot") {
    return client_->Post(
        ("/v1/materials/" + id + "/strokes?robot=" + robot).c_str(),
        csv,
        "text/csv");
  }

  static TempDir* dir_;
  static DaemonProcess* daemon_;
  std::unique_ptr<httplib::Client> client_;
};

TempDir* HttpApiTest::dir_ = nullptr;
DaemonProcess* HttpApiTest::daemon_ = nullptr;

TEST_F(HttpApiTest, HealthzAnswersOk) {
  auto res = client_->Get("/healthz");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(Body(res).value("status", ""), "ok");
}

TEST_F(HttpApiTest, MaterialsCrud) {
  const std::string path = "/v1/materials/crud-steel_1.0";
  // Create.
  auto res = client_->Put(
      path.c_str(),
      R"({"name": "Brushed steel", "description": "304, brushed", "tags": ["metal", "dry"]})",
      "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 201) << res->body;
  json j = Body(res);
  EXPECT_EQ(j.value("id", ""), "crud-steel_1.0");
  EXPECT_EQ(j.value("name", ""), "Brushed steel");
  // Update: only the given fields change.
  res = client_->Put(
      path.c_str(), R"({"description": "304, polished"})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  // Read back.
  res = client_->Get(path.c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  j = Body(res);
  EXPECT_EQ(j.value("name", ""), "Brushed steel");
  EXPECT_EQ(j.value("description", ""), "304, polished");
  EXPECT_EQ(j["tags"], json::array({"metal", "dry"}));
  // Listed.
  res = client_->Get("/v1/materials");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  bool listed = false;
  const json materials = Body(res).at("materials");
  for (const json& m : materials)
    listed = listed || m.value("id", "") == "crud-steel_1.0";
  EXPECT_TRUE(listed) << res->body;
  // Delete, then delete again.
  res = client_->Delete(path.c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  res = client_->Delete(path.c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404) << res->body;
  j = Body(res);
  EXPECT_TRUE(j.contains("error") && j.contains("detail")) << res->body;
  // Gone from the list.
  res = client_->Get("/v1/materials");
  ASSERT_TRUE(res);
  const json remaining = Body(res).at("materials");
  for (const json& m : remaining)
    EXPECT_NE(m.value("id", ""), "crud-steel_1.0");
}

TEST_F(HttpApiTest, UploadsCreateModelVersions) {
  const std::string id = "upload-rubber";
  auto res = Upload(id, SimulatedCsv(/*seed=*/11));
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  json j = Body(res);
  EXPECT_EQ(j.value("version", 0), 1) << res->body;
  EXPECT_TRUE(j.value("material_created", false));
  EXPECT_GT(j.value("stroke_id", 0), 0);

  res = Upload(id, SimulatedCsv(/*seed=*/12));
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  EXPECT_EQ(Body(res).value("version", 0), 2) << res->body;

  // The newest model, in the contract's shape.
  res = client_->Get(("/v1/materials/" + id + "/model").c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  j = Body(res);
  EXPECT_EQ(j.value("material", ""), id);
  EXPECT_EQ(j.value("version", 0), 2);
  ASSERT_TRUE(j.contains("stochastic")) << res->body;
  const json& s = j["stochastic"];
  ASSERT_TRUE(s.contains("coefficients")) << res->body;
  const json& c = s["coefficients"];
  for (const char* key : {"intercept", "v_mm_s", "fn_n"})
    ASSERT_TRUE(c.contains(key) && c[key].is_number()) << key << ": " << c;
  // Two uploads of 8 simulated strokes each recover the planted truth.
  EXPECT_NEAR(c["intercept"].get<double>(), 0.9, 0.05) << c;
  EXPECT_NEAR(c["v_mm_s"].get<double>(), 0.004, 0.001) << c;
  EXPECT_NEAR(c["fn_n"].get<double>(), -0.06, 0.015) << c;
  ASSERT_TRUE(s.contains("sigma_eps") && s["sigma_eps"].is_number());
  EXPECT_NEAR(s["sigma_eps"].get<double>(), 0.05, 0.015);
  ASSERT_TRUE(s.contains("r2") && s["r2"].is_number());
  EXPECT_GT(s["r2"].get<double>(), 0.0);
  EXPECT_LE(s["r2"].get<double>(), 1.0);
  ASSERT_TRUE(s.contains("samples") && s["samples"].is_number_integer());
  EXPECT_GT(s["samples"].get<int>(), 100);
  const int samples_v2 = s["samples"].get<int>();

  // Version 1 is still served, and fitted on fewer samples.
  res = client_->Get(("/v1/materials/" + id + "/model?version=1").c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  j = Body(res);
  EXPECT_EQ(j.value("version", 0), 1);
  EXPECT_LT(j["stochastic"].value("samples", 0), samples_v2);
  // A version that does not exist.
  res = client_->Get(("/v1/materials/" + id + "/model?version=3").c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404) << res->body;

  // The strokes are listed.
  res = client_->Get(("/v1/materials/" + id + "/strokes").c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  EXPECT_EQ(Body(res)["strokes"].size(), 2u) << res->body;
}

TEST_F(HttpApiTest, EvaluationRoutes) {
  const std::string id = "eval-felt";
  auto res = Upload(id, SimulatedCsv(/*seed=*/21, /*strokes=*/16));
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  const std::string base = "/v1/materials/" + id;

  // predict: mu = 0.9 + 0.004 * 40 - 0.06 * 2 = 0.94 (truth).
  res = client_->Get(
      Query(base + "/predict", {{"fn_n", "2"}, {"v_mm_s", "40"}}).c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  json j = Body(res);
  ASSERT_TRUE(j.contains("mu") && j.contains("sigma") &&
              j.contains("interval95"))
      << res->body;
  const double mu = j["mu"].get<double>();
  EXPECT_NEAR(mu, 0.94, 0.05) << res->body;
  EXPECT_GT(j["sigma"].get<double>(), 0.0);
  ASSERT_EQ(j["interval95"].size(), 2u);
  const double lo = j["interval95"][0].get<double>();
  const double hi = j["interval95"][1].get<double>();
  EXPECT_LT(lo, mu);
  EXPECT_LT(mu, hi);

  // slip-likelihood: in [0, 1] and increasing in ft_n.
  double previous = -1.0;
  double first = 0.0;
  double last = 0.0;
  for (double ft : {0.2, 0.8, 1.4, 1.8, 2.2, 3.0}) {
    res = client_->Get(Query(base + "/slip-likelihood",
                             {{"fn_n", "2"}, {"ft_n", std::to_string(ft)}})
                           .c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    const double p = Body(res).value("likelihood", -1.0);
    EXPECT_GE(p, 0.0) << "ft_n = " << ft;
    EXPECT_LE(p, 1.0) << "ft_n = " << ft;
    EXPECT_GE(p, previous) << "ft_n = " << ft << " (not increasing)";
    if (previous < 0) first = p;
    previous = p;
    last = p;
  }
  EXPECT_LT(first, 0.1) << "ft/fn = 0.1 is far below mu ~ 0.9";
  EXPECT_GT(last, 0.9) << "ft/fn = 1.5 is far above mu ~ 0.9";

  // grip-force: a lower risk needs a larger normal force.
  std::vector<double> fn;
  for (const char* risk : {"0.3", "0.05", "0.01"}) {
    res = client_->Get(
        Query(base + "/grip-force", {{"load_n", "1"}, {"risk", risk}}).c_str());
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    j = Body(res);
    ASSERT_TRUE(j.contains("fn_n")) << res->body;
    fn.push_back(j["fn_n"].get<double>());
    // Holding 1 N needs at least 1 / mu_max, mu < 1.5 here.
    EXPECT_GT(fn.back(), 1.0 / 1.5) << "risk " << risk;
  }
  EXPECT_LT(fn[0], fn[1]) << "risk 0.3 vs 0.05";
  EXPECT_LT(fn[1], fn[2]) << "risk 0.05 vs 0.01";
}

TEST_F(HttpApiTest, UnknownMaterialRequestsIdentification) {
  const std::string id = "never-seen-cork";
  auto res = client_->Get(("/v1/materials/" + id + "/model").c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 404) << res->body;
  EXPECT_NE(res->get_header_value("Content-Type").find("application/json"),
            std::string::npos);
  json j = Body(res);
  ASSERT_TRUE(j.contains("error") && j.contains("detail")) << res->body;
  EXPECT_NE(j["detail"].get<std::string>().find("identification"),
            std::string::npos)
      << res->body;
  ASSERT_TRUE(j.contains("identification")) << res->body;
  const json& ident = j["identification"];
  EXPECT_TRUE(ident.value("requested", false)) << res->body;
  ASSERT_TRUE(ident.contains("stroke")) << res->body;
  const json& stroke = ident["stroke"];
  for (const char* range : {"fn_n", "v_mm_s"}) {
    ASSERT_TRUE(stroke.contains(range) && stroke[range].is_array() &&
                stroke[range].size() == 2)
        << range << ": " << stroke;
    EXPECT_GT(stroke[range][0].get<double>(), 0.0) << range;
    EXPECT_LT(stroke[range][0].get<double>(), stroke[range][1].get<double>())
        << range;
  }

  // Predict on an unknown material also answers 404 with the request.
  res = client_->Get(
      ("/v1/materials/" + id + "/predict?fn_n=1&v_mm_s=10").c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404) << res->body;

  // The job is listed (once: the open job is reused).
  res = client_->Get("/v1/identifications");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  int jobs = 0;
  const json identifications = Body(res).at("identifications");
  for (const json& job : identifications) {
    if (job.value("material", "") != id) continue;
    ++jobs;
    EXPECT_EQ(job.value("state", ""), "requested") << job;
    EXPECT_TRUE(job["stroke"].contains("fn_n")) << job;
  }
  EXPECT_EQ(jobs, 1) << res->body;
}

TEST_F(HttpApiTest, MetricsCountRequestsAndLatency) {
  const std::string route = "/v1/materials/{id}/model";
  for (int i = 0; i < 3; ++i) {
    auto res = client_->Get("/v1/materials/microtribo-recip/model");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
  }
  auto res = client_->Get("/metrics");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  const std::string& text = res->body;
  // Counted by route pattern (never the raw path), method and status.
  const std::string counter = "frictiond_http_requests_total{route=\"" + route +
                              "\",method=\"GET\",status=\"200\"} ";
  const auto at = text.find(counter);
  ASSERT_NE(at, std::string::npos) << text;
  EXPECT_GE(std::stoll(text.substr(at + counter.size())), 3) << text;
  EXPECT_EQ(text.find("route=\"/v1/materials/microtribo-recip/model\""),
            std::string::npos)
      << "raw paths must not become metric labels";
  // The latency histogram of the route.
  EXPECT_NE(
      text.find("frictiond_http_request_duration_seconds_bucket{route=\"" +
                route + "\",le=\"+Inf\"}"),
      std::string::npos)
      << text;
  EXPECT_NE(text.find("frictiond_http_request_duration_seconds_count{route=\"" +
                      route + "\"}"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("frictiond_http_request_duration_seconds_sum{route=\"" +
                      route + "\"}"),
            std::string::npos)
      << text;
  // Process gauges: the heap (in use, kept free) and the stroke cache.
  for (const char* gauge : {"\nfrictiond_heap_in_use_bytes ",
                            "\nfrictiond_heap_free_bytes ",
                            "\nfrictiond_stroke_cache_samples ",
                            "\nfrictiond_stroke_cache_store_reads_total "}) {
    const auto g = text.find(gauge);
    ASSERT_NE(g, std::string::npos) << gauge << text;
    EXPECT_GE(std::stod(text.substr(g + std::strlen(gauge))), 0) << gauge;
  }
  // The heap in use is read from the allocator that runs (a daemon serving
  // the bundled data holds megabytes), and its help names that allocator.
  const std::string in_use = "\nfrictiond_heap_in_use_bytes ";
#ifndef FRICTIOND_TEST_ASAN
  EXPECT_GT(std::stod(text.substr(text.find(in_use) + in_use.size())), 1e6);
#endif
#ifdef FRICTIOND_DAEMON_JEMALLOC
  const char* allocator = "(jemalloc: stats.allocated)";
#else
  const char* allocator = "(glibc: mallinfo2 uordblks + hblkhd)";
#endif
  EXPECT_NE(text.find(allocator), std::string::npos) << text;
}

TEST_F(HttpApiTest, BundledDatasetIsServed) {
  auto res = client_->Get("/v1/materials");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  bool found = false;
  const json materials = Body(res).at("materials");
  for (const json& m : materials) {
    if (m.value("id", "") != "microtribo-recip") continue;
    found = true;
    EXPECT_TRUE(m["latest_version"].is_number_integer()) << m;
  }
  EXPECT_TRUE(found) << res->body;
  res = client_->Get("/v1/materials/microtribo-recip/model");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const json j = Body(res);
  EXPECT_EQ(j.value("material", ""), "microtribo-recip");
  EXPECT_GT(j["stochastic"].value("samples", 0), 0) << res->body;
}

TEST(HttpApiDaemonTest, DataNoneStartsEmptyAndStopsCleanly) {
  TempDir dir("http_api_none");
  DaemonOptions options;
  options.db = dir.path() + "/empty.db";
  options.data = "none";
  DaemonProcess daemon(options);
  daemon.Start();
  auto client = daemon.MakeClient();
  auto res = client->Get("/v1/materials");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(Body(res)["materials"], json::array()) << res->body;
  const ExitStatus s = daemon.Stop(SIGTERM);
  EXPECT_TRUE(s.exited && s.code == 0) << s.ToString() << "\n"
                                       << daemon.ReadLog();
  EXPECT_FALSE(s.timed_out);
}

TEST(HttpApiDaemonTest, DataSurvivesRestart) {
  TempDir dir("http_api_restart");
  DaemonOptions options;
  options.db = dir.path() + "/restart.db";
  options.data = "none";
  DaemonProcess daemon(options);
  daemon.Start();
  auto res = daemon.MakeClient()->Post(
      "/v1/materials/restart-pla/strokes", SimulatedCsv(31), "text/csv");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  ASSERT_TRUE(daemon.Stop().exited);
  daemon.Start();  // same db, possibly another port
  res = daemon.MakeClient()->Get("/v1/materials/restart-pla/model");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 200) << res->body;
  EXPECT_EQ(Body(res).value("version", 0), 1);
}

}  // namespace
}  // namespace frictiond
