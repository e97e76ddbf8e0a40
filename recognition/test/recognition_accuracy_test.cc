// Accuracy of the recogniser on real textures: the GIMP pattern set
// (Debian package gimp-data, /usr/share/gimp/2.0/patterns). Reference and
// query images are different crops of the tiled patterns; queries are
// rotated (90 deg, 30 deg, random), magnified 0.7-1.4x and brightened
// 0.7-1.3x (saturating), and a quarter of them are JPEG. All seeds fixed.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/recognition/material_recognizer.h"

#include "gimp_pattern.h"

namespace frictiond {
namespace {

using testing_recognition::Encode;
using testing_recognition::ReadGimpPattern;
using testing_recognition::RenderView;
using testing_recognition::ViewParams;

const char* const kPatternDir = "/usr/share/gimp/2.0/patterns";

/// Registered materials: the natural surface textures of the set.
const std::vector<std::string> kKnown = {
    "Animal/leather", "Fabric/burlap",      "Food/java",
    "Legacy/nops",    "Paper/crinklepaper", "Paper/paper",
    "Stone/Craters",  "Stone/Moonfoot",     "Stone/amethyst",
    "Stone/brick",    "Stone/cracked",      "Stone/granite1",
    "Stone/ground1",  "Stone/marble1",      "Stone/pink_marble",
    "Stone/rock",     "Stone/slate",        "Stone/stone33",
    "Stone/terra",    "Water/ice",          "Water/rain",
    "Wood/bark",      "Wood/burlwood",      "Wood/corkboard",
    "Wood/parque1",   "Wood/pine",          "Wood/walnut",
    "Wood/wood1",     "Wood/wood3",         "Wood/wood5"};
/// Never registered. Includes near-duplicates of registered ones
/// (marble2/3 ~ marble1, parque2/3 ~ parque1, wood4 ~ wood3, wood2 ~ pine).
/// Legacy/Stripes1px and Stripes2px are left out: their texture is only in
/// the alpha channel, which the recogniser ignores (both decode to black).
const std::vector<std::string> kUnknown = {
    "Animal/leopard",    "Food/choc_swirl", "Legacy/3dgreen",
    "Legacy/blue",       "Legacy/bluegrid", "Legacy/bluesquares",
    "Legacy/blueweb",    "Legacy/fibers",   "Legacy/pastel",
    "Legacy/qube1",      "Legacy/recessed", "Legacy/redcube",
    "Legacy/sm_squares", "Legacy/warning",  "Plant/leaves",
    "Sky/lightning",     "Sky/sky",         "Sky/starfield",
    "Stone/marble2",     "Stone/marble3",   "Water/electric",
    "Water/pool",        "Wood/parque2",    "Wood/parque3",
    "Wood/wood2",        "Wood/wood4"};

constexpr int kViewsPerPattern = 8;

bool HavePatterns() {
  return std::filesystem::exists(std::string(kPatternDir) + "/Stone/brick.pat");
}

cv::Mat LoadPattern(const std::string& name) {
  return ReadGimpPattern(std::string(kPatternDir) + "/" + name + ".pat");
}

/// Fraction of pixels at or above 250 grey: such views have lost their
/// texture to saturation.
double ClippedFraction(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  return cv::countNonZero(grey >= 250) / static_cast<double>(grey.total());
}

/// Registers three 256x256 PNG crops per known pattern, at other positions
/// than the queries: (0 deg, 1x), (45 deg, 0.8x), (20 deg, 1.25x).
void RegisterKnown(MaterialRecognizer* recognizer, std::mt19937* rng) {
  for (const std::string& name : kKnown) {
    const cv::Mat pattern = LoadPattern(name);
    const ViewParams references[] = {
        {0.0, 1.0, 1.0, 256}, {45.0, 0.8, 1.0, 256}, {20.0, 1.25, 1.0, 256}};
    for (const ViewParams& p : references) {
      recognizer->AddReference(name, Encode(RenderView(pattern, p, *rng)));
    }
  }
}

struct Query {
  std::string truth;
  ViewParams params;
  double clipped = 0.0;
  RecognitionResult result;
};

/// kViewsPerPattern queries of `name`: rotation 90 deg, 30 deg, then
/// uniform; scale U(0.7, 1.4); gain U(0.7, 1.3); every 4th one JPEG (q 90).
std::vector<Query> RunQueries(const MaterialRecognizer& recognizer,
                              const std::string& name,
                              std::mt19937* rng) {
  const cv::Mat pattern = LoadPattern(name);
  std::uniform_real_distribution<double> angle(0.0, 360.0);
  std::uniform_real_distribution<double> scale(0.7, 1.4);
  std::uniform_real_distribution<double> gain(0.7, 1.3);
  std::vector<Query> queries;
  for (int k = 0; k < kViewsPerPattern; ++k) {
    Query q;
    q.truth = name;
    q.params.angle_deg = k == 0 ? 90.0 : k == 1 ? 30.0 : angle(*rng);
    q.params.scale = scale(*rng);
    q.params.gain = gain(*rng);
    const cv::Mat view = RenderView(pattern, q.params, *rng);
    q.clipped = ClippedFraction(view);
    q.result = recognizer.Recognize(Encode(view, k % 4 == 3 ? ".jpg" : ".png"));
    queries.push_back(std::move(q));
  }
  return queries;
}

TEST(RecognitionAccuracyTest, GimpTexturesUnderRotationScaleAndBrightness) {
  if (!HavePatterns())
    GTEST_SKIP() << kPatternDir << " missing: apt-get install gimp-data";
  std::mt19937 rng(20240607);
  MaterialRecognizer recognizer;  // default options: threshold 0.90
  RegisterKnown(&recognizer, &rng);
  ASSERT_EQ(recognizer.material_count(), kKnown.size());

  // Known materials.
  int total = 0, correct = 0, accepted_correct = 0;
  int textured = 0, textured_correct = 0;
  for (const std::string& name : kKnown) {
    for (const Query& q : RunQueries(recognizer, name, &rng)) {
      ASSERT_FALSE(q.result.candidates.empty());
      const RecognitionCandidate& best = q.result.candidates.front();
      const bool ok = best.material == q.truth;
      ++total;
      correct += ok;
      accepted_correct += ok && !q.result.unknown;
      // Views with most pixels saturated carry no texture.
      if (q.clipped < 0.5) {
        ++textured;
        textured_correct += ok;
      }
      if (!ok || q.result.unknown) {
        std::printf(
            "  %-18s angle %5.1f scale %.2f gain %.2f clipped %.2f -> %s "
            "%.3f%s\n",
            name.c_str(),
            q.params.angle_deg,
            q.params.scale,
            q.params.gain,
            q.clipped,
            best.material.c_str(),
            best.score,
            q.result.unknown ? " (unknown)" : "");
      }
    }
  }
  // Unregistered patterns.
  int unknown_total = 0, rejected = 0;
  for (const std::string& name : kUnknown) {
    for (const Query& q : RunQueries(recognizer, name, &rng)) {
      ++unknown_total;
      rejected += q.result.unknown;
      if (!q.result.unknown) {
        std::printf("  unregistered %-18s accepted as %s %.3f\n",
                    name.c_str(),
                    q.result.candidates.front().material.c_str(),
                    q.result.candidates.front().score);
      }
    }
  }
  const double top1 = double(correct) / total;
  const double top1_textured = double(textured_correct) / textured;
  const double recall = double(accepted_correct) / total;
  const double rejection = double(rejected) / unknown_total;
  std::printf(
      "top-1 accuracy: %d/%d = %.3f (views with < 50%% clipped pixels: %d/%d = "
      "%.3f)\n",
      correct,
      total,
      top1,
      textured_correct,
      textured,
      top1_textured);
  std::printf("known views accepted and correct: %.3f\n", recall);
  std::printf(
      "unknown rejection: %d/%d = %.3f\n", rejected, unknown_total, rejection);

  // Measured with this seed: 0.971 / 0.987 / 0.925 / 0.971; over seeds 1-5
  // the ranges were 0.967-0.983 / 0.991-0.996 / 0.917-0.950 / 0.942-0.962
  // (docs/recognition.md). The bounds sit below the worst seed; chance top-1
  // is 1/30.
  EXPECT_GE(top1, 0.95);
  EXPECT_GE(top1_textured, 0.97);
  EXPECT_GE(recall, 0.90);
  EXPECT_GE(rejection, 0.85);
}

TEST(RecognitionAccuracyTest, PrintsTimePer640x480Image) {
  if (!HavePatterns())
    GTEST_SKIP() << kPatternDir << " missing: apt-get install gimp-data";
  std::mt19937 rng(5);
  MaterialRecognizer recognizer;
  RegisterKnown(&recognizer, &rng);
  cv::Mat tiled;
  cv::repeat(LoadPattern("Stone/stone33"), 4, 5, tiled);
  const cv::Mat image = tiled(cv::Rect(0, 0, 640, 480)).clone();
  const std::string png = Encode(image, ".png");
  const std::string jpeg = Encode(image, ".jpg");
  const std::vector<float> features = recognizer.ExtractFeatures(png);
  constexpr int kRepeats = 30;
  auto time_ms = [&](auto&& call) {
    call();  // warm-up
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < kRepeats; ++i) call();
    const std::chrono::duration<double, std::milli> elapsed =
        std::chrono::steady_clock::now() - start;
    return elapsed.count() / kRepeats;
  };
  const double png_ms = time_ms([&] { recognizer.Recognize(png); });
  const double jpeg_ms = time_ms([&] { recognizer.Recognize(jpeg); });
  const double match_ms =
      time_ms([&] { recognizer.RecognizeFeatures(features); });
  cv::Mat decoded;
  const double decode_png_ms = time_ms([&] {
    decoded = cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()),
                           cv::IMREAD_COLOR);
  });
  std::printf(
      "640x480, %zu references: Recognize(PNG %zu kB) %.2f ms (of which "
      "imdecode %.2f ms), "
      "Recognize(JPEG %zu kB) %.2f ms, RecognizeFeatures %.3f ms\n",
      recognizer.reference_count(),
      png.size() / 1024,
      png_ms,
      decode_png_ms,
      jpeg.size() / 1024,
      jpeg_ms,
      match_ms);
}

}  // namespace
}  // namespace frictiond
