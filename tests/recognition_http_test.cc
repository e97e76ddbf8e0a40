// POST /v1/recognize over loopback HTTP (docs/recognition.md): the answer
// carries the calibrated scores, the operating point from the daemon's
// config file ("recognition_operating_point") and a reason when it rejects.
// Skipped when the daemon was built without OpenCV (501) or the images of
// Debian's gimp-data package are missing.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "frictiond/testing/daemon_process.h"

namespace frictiond {
namespace {

using nlohmann::json;
using testing::DaemonOptions;
using testing::DaemonProcess;
using testing::TempDir;

const char* const kImage = "/usr/share/gimp/2.0/scripts/images/texture.jpg";

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(RecognitionHttpTest, RejectionSaysWhyAtTheConfiguredOperatingPoint) {
  if (!std::filesystem::exists(kImage))
    GTEST_SKIP() << kImage << " missing: apt-get install gimp-data";
  TempDir dir("recognition_http_test");
  const std::string config = dir.path() + "/config.json";
  std::ofstream(config) << R"({"recognition_operating_point": 0.95})";
  DaemonOptions options;
  options.db = dir.path() + "/library.db";
  options.data = "none";
  options.extra_args = {"--config", config};
  DaemonProcess daemon(options);
  daemon.Start();
  auto client = daemon.MakeClient(20.0);
  const std::string image = ReadFile(kImage);

  auto res = client->Post("/v1/recognize", image, "image/jpeg");
  ASSERT_TRUE(res);
  if (res->status == 501) GTEST_SKIP() << "built without OpenCV";
  // Nothing registered: unknown, and the reason says so.
  ASSERT_EQ(res->status, 200) << res->body;
  json out = json::parse(res->body);
  EXPECT_TRUE(out["unknown"].get<bool>());
  EXPECT_EQ(out["reason"], "no reference image is registered");

  res = client->Put(
      "/v1/materials/oak", R"({"name": "oak"})", "application/json");
  ASSERT_TRUE(res);
  ASSERT_LT(res->status, 300) << res->body;
  res = client->Post("/v1/materials/oak/images", image, "image/jpeg");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 201) << res->body;

  // The same photo: similarity 1, but with one material the calibrated
  // score is about 0.9, below the configured 0.95.
  res = client->Post("/v1/recognize", image, "image/jpeg");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200) << res->body;
  out = json::parse(res->body);
  EXPECT_TRUE(out["unknown"].get<bool>()) << out.dump();
  EXPECT_DOUBLE_EQ(out["operating_point"].get<double>(), 0.95);
  ASSERT_EQ(out["candidates"].size(), 1u) << out.dump();
  EXPECT_EQ(out["candidates"][0]["material"], "oak");
  EXPECT_NEAR(out["candidates"][0]["similarity"].get<double>(), 1.0, 1e-6);
  const double score = out["candidates"][0]["score"].get<double>();
  EXPECT_GT(score, 0.5);
  EXPECT_LT(score, 0.95);
  const std::string reason = out["reason"].get<std::string>();
  EXPECT_EQ(reason.rfind("closest is oak at 0.", 0), 0u) << reason;
  EXPECT_NE(reason.find("below the 0.95 operating point"), std::string::npos)
      << reason;
  EXPECT_TRUE(out.contains("identification")) << out.dump();
}

}  // namespace
}  // namespace frictiond
