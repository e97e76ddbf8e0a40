// `frictiond --config FILE.json` (DaemonConfig::LoadFile, server/src/
// daemon.cc): a valid file configures the daemon (settings no flag gives
// are taken from it; flags override it), and a bad file (unknown key, wrong
// type, broken JSON) stops the daemon at start-up with exit status 2 and a
// message naming the field, before anything is created.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/wait.h>

#include "frictiond/testing/daemon_process.h"

namespace frictiond {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::BinaryPath;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::ExitStatus;
using testing::TempDir;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string WriteFile(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

TEST(DaemonConfigTest, ValidConfigIsUsedAndFlagsOverrideIt) {
  TempDir dir("daemon_config_test");
  // data "none" (the default would load the bundled dataset), a 1 MiB body
  // limit (default 16) and a stroke plan (default Fn 0.5..4.5 N) come only
  // from the file; db is in the file too but --db overrides it.
  const std::string config = WriteFile(dir.path() + "/frictiond.json", R"({
    "db": ")" + dir.path() + R"(/from_config.db",
    "bind": "127.0.0.1",
    "data": "none",
    "lcm": "none",
    "max_body_mb": 1,
    "threads": 2,
    "plan": {"fn_min_n": 1.5, "fn_max_n": 7.5, "v_max_mm_s": 60,
             "lugre_fn_n": 3, "lugre_fast_strokes": 2}
  })");
  DaemonOptions options;
  options.db = dir.path() + "/from_flag.db";
  options.data = "";  // not passed: the file decides
  options.lcm = "";
  options.extra_args = {"--config", config};
  DaemonProcess daemon(options);
  daemon.Start();
  auto client = daemon.MakeClient();

  auto res = client->Get("/v1/materials");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  EXPECT_TRUE(json::parse(res->body)["materials"].empty())
      << "data \"none\" from the config file was not applied: " << res->body;

  res = client->Get("/v1/materials/cfg-unknown/model");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 404) << res->body;
  const json stroke = json::parse(res->body)["identification"]["stroke"];
  EXPECT_EQ(stroke["fn_n"], json({1.5, 7.5})) << stroke;
  EXPECT_EQ(stroke["v_mm_s"][1], 60) << stroke;
  EXPECT_EQ(stroke["lugre"]["fn_n"], 3) << stroke;
  EXPECT_EQ(stroke["lugre"]["fast"]["strokes"], 2) << stroke;
  EXPECT_EQ(stroke["lugre"]["slow"]["accel_mm_s2"], 2) << stroke;

  // A 2 MiB body is over the configured 1 MiB limit.
  res = client->Post(
      "/v1/materials/cfg-big/strokes", std::string(2 << 20, '1'), "text/csv");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 413) << res->body.substr(0, 200);

  const ExitStatus s = daemon.Stop(SIGTERM);
  EXPECT_TRUE(s.exited && s.code == 0) << s.ToString() << daemon.ReadLog();
  EXPECT_TRUE(fs::exists(dir.path() + "/from_flag.db"));
  EXPECT_FALSE(fs::exists(dir.path() + "/from_config.db"))
      << "--db should override the file's db";
}

struct Rejection {
  const char* name;
  const char* text;      // the config file
  const char* expected;  // in the daemon's message
};

TEST(DaemonConfigTest, BadConfigIsRejectedNamingTheField) {
  TempDir dir("daemon_config_bad");
  const Rejection cases[] = {
      {"unknown_key",
       R"({"data": "none", "prot": 8080})",
       "unknown key 'prot'"},
      {"port_type",
       R"({"data": "none", "port": "8080"})",
       "port: expected an integer"},
      {"port_fraction",
       R"({"data": "none", "port": 80.5})",
       "port: expected an integer"},
      {"db_type", R"({"db": 7})", "db: expected a string"},
      {"plan_type", R"({"plan": [1, 2]})", "plan: expected an object"},
      {"plan_field_type",
       R"({"plan": {"fn_max_n": "high"}})",
       "plan.fn_max_n: expected a number"},
      {"plan_lugre_slow_accel",
       R"({"plan": {"lugre_slow_accel_mm_s2": 4}})",
       "plan.lugre_slow_accel_mm_s2 = 4 (must be in (0, 3]"},
      {"plan_lugre_pair_type",
       R"({"plan": {"lugre_pair": 1}})",
       "plan.lugre_pair: expected true or false"},
      {"open_reads_type",
       R"({"open_reads": "yes"})",
       "open_reads: expected true or false"},
      {"broken_json", R"({"port": 8080,)", "invalid JSON"},
      {"lcm_key_short",
       R"({"lcm_keys": {"arm-1": "00ff"}})",
       "lcm_keys: arm-1: key of 2 bytes"},
      {"lcm_key_not_hex",
       R"({"lcm_keys": {"arm-2": "zz"}})",
       "lcm_keys: arm-2: not a hex string"},
      {"lcm_keys_type", R"({"lcm_keys": ["k"]})", "lcm_keys: expected"},
      {"lcm_allow_unsigned_type",
       R"({"lcm_allow_unsigned": "yes"})",
       "lcm_allow_unsigned: expected true or false"},
      {"not_object", R"([1, 2, 3])", "expected a JSON object"},
  };
  for (const Rejection& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string config =
        WriteFile(dir.path() + "/" + c.name + ".json", c.text);
    const std::string db = dir.path() + "/" + c.name + ".db";
    const std::string err = dir.path() + "/" + c.name + ".err";
    // The port is free and the db new: only the config can make it fail.
    // `timeout` ends a daemon that wrongly starts serving.
    const std::string cmd = "timeout -s KILL 20 " + BinaryPath("frictiond") +
                            " --config " + config + " --db " + db + " --port " +
                            std::to_string(testing::FindFreePort()) +
                            " >/dev/null 2>" + err;
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << "status " << status;
    EXPECT_EQ(WEXITSTATUS(status), 2) << ReadAll(err);
    const std::string message = ReadAll(err);
    EXPECT_NE(message.find(c.expected), std::string::npos)
        << "expected \"" << c.expected << "\" in: " << message;
    EXPECT_NE(message.find(config), std::string::npos) << message;
    EXPECT_FALSE(fs::exists(db)) << "a rejected config created the database";
  }
  // A missing file is rejected the same way.
  const std::string cmd = "timeout -s KILL 20 " + BinaryPath("frictiond") +
                          " --config " + dir.path() + "/missing.json --db " +
                          dir.path() + "/missing.db >/dev/null 2>" +
                          dir.path() + "/missing.err";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  EXPECT_NE(ReadAll(dir.path() + "/missing.err").find("cannot read"),
            std::string::npos);
}

// A flag given with an out-of-range value is refused naming the flag (exit
// 2), never silently replaced by its default: `--port -1` served on 8080
// and `--db ''` used ./frictiond.db (outside attack run).
TEST(DaemonConfigTest, NegativeAndEmptyFlagsAreRefused) {
  TempDir dir("daemon_config_flags");
  const std::pair<const char*, const char*> cases[] = {
      {"--port -1", "--port -1: must be in 0..65535"},
      {"--threads -5", "--threads -5: must be in 1..256"},
      {"--max-body-mb -1", "--max-body-mb -1: must be in 1..1024"},
      {"--header-timeout-ms -1", "--header-timeout-ms -1: must be in"},
      {"--lcm-max-skew-s -1", "--lcm-max-skew-s"},
      {"--lcm-max-skew-s nan", "--lcm-max-skew-s nan"},
      {"--bind ''", "--bind: empty"},
      {"--data ''", "--data: empty"},
      {"--lcm-keys ''", "--lcm-keys: empty"},
  };
  int i = 0;
  for (const auto& [flags, expected] : cases) {
    SCOPED_TRACE(flags);
    const std::string db = dir.path() + "/" + std::to_string(i) + ".db";
    const std::string err = dir.path() + "/" + std::to_string(i++) + ".err";
    const int status = std::system(
        ("timeout -s KILL 20 " + BinaryPath("frictiond") +
         (std::string(flags).rfind("--data", 0) == 0 ? "" : " --data none") +
         " --db " + db + " " + flags + " >/dev/null 2>" + err)
            .c_str());
    ASSERT_TRUE(WIFEXITED(status)) << "status " << status;
    EXPECT_EQ(WEXITSTATUS(status), 2) << ReadAll(err);
    EXPECT_NE(ReadAll(err).find(expected), std::string::npos) << ReadAll(err);
    EXPECT_FALSE(fs::exists(db));
  }
  const std::string err = dir.path() + "/db.err";
  const int status =
      std::system(("timeout -s KILL 20 " + BinaryPath("frictiond") +
                   " --data none --db '' >/dev/null 2>" + err)
                      .c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 2);
  EXPECT_NE(ReadAll(err).find("--db: empty"), std::string::npos)
      << ReadAll(err);
}

}  // namespace
}  // namespace frictiond
