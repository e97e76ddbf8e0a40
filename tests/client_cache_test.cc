// Robots offline (docs/offline.md): the client's disk cache of fetched
// models against the real `frictiond` on loopback. Fetch, stop the daemon,
// fetch again -> the same model from the cache, marked stale; a new version
// made while the robot was away -> Resync (and the next fetch) bring it; a
// corrupted cache file is reported and not used; `friction model` warns on
// stderr when it serves a stale model.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <sys/wait.h>

#include "frictiond/client/client.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/model_json.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::TempDir;

std::string SimulatedCsv(std::uint64_t seed, double b0) {
  testing::SimulationSpec spec;
  spec.strokes = 6;
  spec.b0 = b0;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class ClientCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    options_.db = dir_.path() + "/lib.db";
    options_.data = "none";
    cache_dir_ = dir_.path() + "/cache";
  }

  // Starts a daemon (on the previous daemon's port after the first).
  void StartDaemon() {
    DaemonOptions o = options_;
    if (port_ > 0) o.port = port_;
    daemon_ = std::make_unique<DaemonProcess>(o);
    daemon_->Start();
    port_ = daemon_->port();
  }
  // The daemon goes away (SIGKILL: a crash or power loss; a graceful stop
  // would wait for the robot's idle keep-alive connection to time out).
  void StopDaemon() { daemon_->Kill(); }
  std::string BaseUrl() const {
    return "http://127.0.0.1:" + std::to_string(port_);
  }
  ClientOptions RobotOptions() const {
    ClientOptions o;
    o.base_url = BaseUrl();
    o.timeout_s = 2.0;
    o.cache_dir = cache_dir_;
    return o;
  }
  // Another robot (no cache) that uploads a new version.
  int Upload(const std::string& material, std::uint64_t seed, double b0) {
    ClientOptions o;
    o.base_url = BaseUrl();
    o.timeout_s = 60;
    o.token = options_.operator_token;  // writes need a token (docs/auth.md)
    return FrictionClient(o)
        .UploadStrokes(material, SimulatedCsv(seed, b0))
        .version;
  }

  TempDir dir_{"client_cache"};
  DaemonOptions options_;
  std::string cache_dir_;
  std::unique_ptr<DaemonProcess> daemon_;
  int port_ = 0;
};

TEST_F(ClientCacheTest, ServesStaleModelOfflineAndResyncsWhenBack) {
  StartDaemon();
  ASSERT_EQ(Upload("cc-felt", 3, 0.9), 1);
  FrictionClient robot(RobotOptions());
  const FetchResult online = robot.FetchModelWithInfo("cc-felt");
  EXPECT_EQ(online.info.source, "daemon");
  EXPECT_FALSE(online.info.stale);
  EXPECT_EQ(online.info.version, 1);
  EXPECT_EQ(online.info.server, BaseUrl());
  EXPECT_TRUE(online.info.cache_error.empty()) << online.info.cache_error;
  EXPECT_FALSE(online.info.fetched_at.empty());

  StopDaemon();
  // No daemon: the cached model, equal to the fetched one, marked stale.
  const FetchResult offline = robot.FetchModelWithInfo("cc-felt");
  EXPECT_EQ(offline.info.source, "cache");
  EXPECT_TRUE(offline.info.stale);
  EXPECT_EQ(offline.info.version, 1);
  EXPECT_EQ(offline.info.fetched_at, online.info.fetched_at);
  EXPECT_EQ(offline.info.server, BaseUrl());
  EXPECT_FALSE(offline.info.daemon_error.empty());
  EXPECT_EQ(ModelSetToJson(offline.model).dump(),
            ModelSetToJson(online.model).dump());
  ASSERT_TRUE(offline.model.stochastic);
  EXPECT_NEAR(offline.model.stochastic->mu.beta(0), 0.9, 0.05);
  // The old signature works and can report the same.
  FetchInfo info;
  const ModelSet m = robot.FetchModel("cc-felt", 0, "", &info);
  EXPECT_TRUE(info.stale);
  EXPECT_EQ(m.version, 1);
  // A pinned version that is cached is served; others are not.
  EXPECT_EQ(robot.FetchModel("cc-felt", 1).version, 1);
  try {
    robot.FetchModel("cc-felt", 2);
    FAIL() << "version 2 was never fetched";
  } catch (const ClientError& e) {
    EXPECT_EQ(e.status(), 0);
    EXPECT_NE(std::string(e.what()).find("no cached model of cc-felt"),
              std::string::npos)
        << e.what();
  }
  // Resync needs a daemon.
  EXPECT_THROW(robot.Resync(), ClientError);
  // A fresh client on the same cache (a robot restarted offline).
  FrictionClient rebooted(RobotOptions());
  EXPECT_EQ(rebooted.FetchModelWithInfo("cc-felt").info.version, 1);

  // The daemon is back, with a new version made by another robot.
  StartDaemon();
  ASSERT_EQ(Upload("cc-felt", 4, 0.6), 2);
  ASSERT_EQ(Upload("cc-cork", 5, 0.5), 1);  // never fetched: not cached
  const std::vector<ResyncEntry> rs = robot.Resync();
  ASSERT_EQ(rs.size(), 1u);
  EXPECT_EQ(rs[0].material, "cc-felt");
  EXPECT_EQ(rs[0].fingertip, "default");
  EXPECT_EQ(rs[0].cached_version, 1);
  EXPECT_EQ(rs[0].version, 2);
  EXPECT_TRUE(rs[0].error.empty()) << rs[0].error;
  const FetchResult back = robot.FetchModelWithInfo("cc-felt");
  EXPECT_EQ(back.info.source, "daemon");
  EXPECT_FALSE(back.info.stale);
  EXPECT_EQ(back.info.version, 2);
  StopDaemon();
  // Offline again: the resynchronised version.
  const FetchResult later = rebooted.FetchModelWithInfo("cc-felt");
  EXPECT_TRUE(later.info.stale);
  EXPECT_EQ(later.info.version, 2);
  EXPECT_EQ(ModelSetToJson(later.model).dump(),
            ModelSetToJson(back.model).dump());
  ASSERT_TRUE(later.model.stochastic);
  EXPECT_GT(std::abs(later.model.stochastic->mu.beta(0) -
                     online.model.stochastic->mu.beta(0)),
            0.05);  // the new data (b0 0.6 vs 0.9) moved the intercept
}

TEST_F(ClientCacheTest, CorruptedCacheFileIsReportedNotTrusted) {
  StartDaemon();
  ASSERT_EQ(Upload("cc-rubber", 6, 0.8), 1);
  FrictionClient robot(RobotOptions());
  ASSERT_EQ(robot.FetchModel("cc-rubber").version, 1);
  StopDaemon();
  const std::string file = cache_dir_ + "/cc-rubber@default.latest.json";
  const std::string good = ReadAll(file);
  ASSERT_FALSE(good.empty()) << file;
  auto expect_corrupted = [&](const std::string& content,
                              const std::string& why) {
    std::ofstream(file, std::ios::binary | std::ios::trunc) << content;
    try {
      robot.FetchModel("cc-rubber");
      ADD_FAILURE() << "a corrupted cache file (" << why << ") was used";
    } catch (const ClientError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(e.status(), 0);
      EXPECT_NE(msg.find(file + " is corrupted"), std::string::npos) << msg;
      EXPECT_NE(msg.find(why), std::string::npos) << msg;
      EXPECT_NE(msg.find("not used"), std::string::npos) << msg;
    }
  };
  expect_corrupted(good.substr(0, good.size() / 2), "not valid JSON");
  // Valid JSON, one coefficient digit changed: the checksum catches it.
  std::string flipped = good;
  const std::size_t pos = flipped.find("\"coefficients\"");
  ASSERT_NE(pos, std::string::npos);
  const std::size_t digit = flipped.find_first_of("123456789", pos);
  flipped[digit] = flipped[digit] == '9' ? '8' : '9';
  expect_corrupted(flipped, "checksum");
  // Back online: fetched and the file replaced; offline works again.
  StartDaemon();
  const FetchResult r = robot.FetchModelWithInfo("cc-rubber");
  EXPECT_EQ(r.info.source, "daemon");
  StopDaemon();
  EXPECT_TRUE(robot.FetchModelWithInfo("cc-rubber").info.stale);
}

TEST_F(ClientCacheTest, CliWarnsWhenServingAStaleModel) {
  StartDaemon();
  ASSERT_EQ(Upload("cc-wood", 8, 0.7), 1);
  auto friction =
      [&](const std::string& args, std::string* out, std::string* err) {
        const std::string o = dir_.path() + "/cli.out",
                          e = dir_.path() + "/cli.err";
        const std::string cmd = testing::BinaryPath("friction") + " --server " +
                                BaseUrl() + " --cache-dir " + cache_dir_ + " " +
                                args + " >" + o + " 2>" + e;
        const int status = std::system(cmd.c_str());
        *out = ReadAll(o);
        *err = ReadAll(e);
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      };
  std::string out, err;
  ASSERT_EQ(friction("model cc-wood", &out, &err), 0) << err;
  EXPECT_EQ(err.find("STALE"), std::string::npos) << err;
  const std::string online_out = out;
  EXPECT_NE(online_out.find("version 1"), std::string::npos) << online_out;
  ASSERT_EQ(friction("resync", &out, &err), 0) << err;
  EXPECT_NE(out.find("cc-wood"), std::string::npos) << out;
  StopDaemon();
  ASSERT_EQ(friction("model cc-wood", &out, &err), 0) << err;
  EXPECT_EQ(out, online_out);
  EXPECT_NE(err.find("STALE"), std::string::npos) << err;
  EXPECT_NE(err.find("version 1"), std::string::npos) << err;
  // Unknown to the cache, no daemon: exit 1 with the reason.
  EXPECT_EQ(friction("model cc-none", &out, &err), 1);
  EXPECT_NE(err.find("no cached model of cc-none"), std::string::npos) << err;
  EXPECT_EQ(friction("resync", &out, &err), 1);
}

}  // namespace
}  // namespace frictiond
