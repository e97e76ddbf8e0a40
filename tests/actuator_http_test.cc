// Actuator routes and CLI end to end (docs/actuator.md): the real
// `frictiond` over loopback HTTP and the `friction actuator` commands.
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include "frictiond/testing/daemon_process.h"

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

std::string LogPath(const std::string& name) {
  return testing::SourceDir() + "/data/bam_xl330/logs/xl330_" + name + ".json";
}

// A bundled log cut to its first `n` entries (keeps the test fast).
json ShortLog(const std::string& name, std::size_t n) {
  json j = json::parse(ReadText(LogPath(name)));
  json& e = j["entries"];
  e.erase(e.begin() + static_cast<long>(n), e.end());
  return j;
}

class ActuatorHttpTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("actuator_http_test");
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
  int Cli(const std::string& args, std::string* out, std::string* err) {
    const std::string o = dir_->path() + "/out.txt";
    const std::string e = dir_->path() + "/err.txt";
    const int status = std::system(
        (testing::BinaryPath("friction") + " " + args + " >" + o + " 2>" + e)
            .c_str());
    *out = ReadText(o);
    *err = ReadText(e);
    return WEXITSTATUS(status);
  }
  static TempDir* dir_;
  static DaemonProcess* daemon_;
};
TempDir* ActuatorHttpTest::dir_ = nullptr;
DaemonProcess* ActuatorHttpTest::daemon_ = nullptr;

TEST_F(ActuatorHttpTest, UploadFetchSimulateExport) {
  auto c = daemon_->MakeClient();
  const std::string base = "/v1/materials/pendulum/";
  // Unknown first: 404 with the upload hint.
  auto res = c->Get((base + "actuator-model?joint=j1").c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404) << res->body;
  // A bad log among good ones: 400 naming the field, nothing stored.
  json bad = ShortLog("kp100_sin_sin", 300);
  bad["entries"][7].erase("goal_position");
  json body = {{"logs", {ShortLog("kp400_sin_sin", 300), bad}}};
  res = c->Post((base + "actuator-logs?joint=j1&law=coulomb_viscous").c_str(),
                body.dump(),
                "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400) << res->body;
  EXPECT_EQ(json::parse(res->body).value("field", ""),
            "logs[1].entries[7].goal_position")
      << res->body;
  // "trajectory" not a string: 400 naming it (it was a 500, the route
  // read it as a string; outside attack run).
  for (const json& t : {json(1), json(nullptr), json::array()}) {
    json log = ShortLog("kp400_sin_sin", 300);
    log["trajectory"] = t;
    res = c->Post((base + "actuator-logs?joint=j1").c_str(),
                  json{{"logs", {log}}}.dump(),
                  "application/json");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400) << res->body;
    EXPECT_EQ(json::parse(res->body).value("field", ""), "logs[0].trajectory")
        << res->body;
  }
  // 100,000 levels of nesting: one request used to crash the daemon (the
  // route serialised the parsed document recursively); now 400, daemon up.
  for (const char* route : {"actuator-logs?joint=j1"}) {
    res = c->Post((base + route).c_str(),
                  "{\"name\": " + std::string(100000, '[') +
                      std::string(100000, ']') + "}",
                  "application/json");
    ASSERT_TRUE(res) << route << ": " << httplib::to_string(res.error());
    EXPECT_EQ(res->status, 400) << res->body.substr(0, 300);
    EXPECT_EQ(json::parse(res->body).value("field", ""), "body");
  }
  res = c->Post((base + "actuator-logs?joint=j1").c_str(),
                "{\"mass\": 1",
                "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400) << res->body;
  res = c->Get((base + "actuator-model?joint=j1").c_str());
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 404) << "stored after a refusal: " << res->body;
  // Good logs: fitted and stored as version 1.
  body = {
      {"logs",
       {ShortLog("kp400_sin_sin", 300), ShortLog("kp100_lift_and_drop", 300)}}};
  res = c->Post((base + "actuator-logs?joint=j1&law=coulomb_viscous").c_str(),
                body.dump(),
                "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  json j = json::parse(res->body);
  EXPECT_EQ(j.value("version", 0), 1);
  EXPECT_EQ(j["actuator"]["model"].value("law", ""), "coulomb_viscous");
  res = c->Get((base + "actuator-model?joint=j1").c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  const json logs = json::parse(res->body)["actuator"]["logs"];
  ASSERT_EQ(logs.size(), 2u);
  EXPECT_EQ(logs[0].value("name", ""), "sin_sin_kp400");
  EXPECT_EQ(logs[1].value("name", ""), "lift_and_drop_kp100");
  // A gain beyond every integer type names the log in full (it was cast to
  // an integer: undefined behaviour).
  json huge = ShortLog("kp100_sin_sin", 300);
  huge["kp"] = 1e308;
  res = c->Post((base + "actuator-logs?joint=j2&law=coulomb_viscous").c_str(),
                huge.dump(),
                "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;
  EXPECT_EQ(json::parse(res->body)["actuator"]["logs"][0].value("name", ""),
            "sin_sin_kp1e+308")
      << res->body;
  res = c->Post(
      (base + "actuator-simulate?joint=j1").c_str(),
      "{\"name\": " + std::string(100000, '[') + std::string(100000, ']') + "}",
      "application/json");
  ASSERT_TRUE(res) << httplib::to_string(res.error());
  EXPECT_EQ(res->status, 400) << res->body.substr(0, 300);
  res = c->Post((base + "actuator-simulate?joint=j1").c_str(),
                ShortLog("kp200_sin_sin", 300).dump(),
                "application/json");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  j = json::parse(res->body);
  EXPECT_GT(j.value("mae_rad", -1.0), 0.0);
  EXPECT_LT(j.value("mae_rad", 1.0), 0.5);
  EXPECT_EQ(j.value("samples", 0), 300);
  res = c->Get((base + "actuator-mjcf?joint=j1").c_str());
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_NE(res->body.find("frictionloss=\""), std::string::npos) << res->body;
  EXPECT_NE(res->body.find("armature=\""), std::string::npos) << res->body;
}

TEST_F(ActuatorHttpTest, CliSimulatesBamParameters) {
  std::string out, err;
  const std::string params =
      testing::SourceDir() + "/data/bam_xl330/published_params/m1.json";
  ASSERT_EQ(Cli("actuator simulate " + LogPath("kp400_sin_sin") +
                    " --params-bam " + params + " --json",
                &out,
                &err),
            0)
      << err;
  const json j = json::parse(out);
  EXPECT_EQ(j.value("law", ""), "coulomb_viscous");
  EXPECT_EQ(j.value("samples", 0), 1200);
  EXPECT_NEAR(j.value("mae_rad", 0.0), 0.115, 0.01);
  // A bad log is refused naming the field, exit 2.
  const std::string bad = dir_->path() + "/bad.json";
  std::ofstream(bad) << R"({"mass": 0.49, "length": 0.1, "kp": 400, "vin": 7.4,
      "entries": [{"timestamp": 0, "position": 0, "goal_position": 0,
      "torque_enable": true}, {"timestamp": 0.005, "position": "x",
      "goal_position": 0, "torque_enable": true}]})";
  EXPECT_EQ(
      Cli("actuator simulate " + bad + " --params-bam " + params, &out, &err),
      2);
  EXPECT_NE(err.find("entries[1].position"), std::string::npos) << err;
}

// Input files are regular files of bounded size: /dev/zero was read until
// memory ran out (outside attack run), a sparse file beyond the limit was
// read whole before its size was checked.
TEST_F(ActuatorHttpTest, CliRefusesDevicesAndHugeFiles) {
  std::string out, err;
  for (const char* cmd : {"diagnose", "fit", "report", "joint-fit"}) {
    EXPECT_EQ(Cli(std::string(cmd) + " /dev/zero", &out, &err), 2) << cmd;
    EXPECT_NE(err.find("/dev/zero: not a regular file"), std::string::npos)
        << cmd << ": " << err;
  }
  const std::string sparse = dir_->path() + "/sparse.csv";
  {
    std::ofstream f(sparse);
    f << "t_s,fn_n,ft_n,v_mm_s\n";
  }
  ASSERT_EQ(::truncate(sparse.c_str(), 300ll << 20), 0);
  EXPECT_EQ(Cli("diagnose " + sparse, &out, &err), 2);
  EXPECT_NE(err.find("(limit 268435456)"), std::string::npos) << err;
}

}  // namespace
}  // namespace frictiond
