// Validation on the TEST side of the material split (camera_views.h), which
// the tuning (recognition_calibration_test.cc, every design choice) never
// saw: a library of the test materials, views with random combinations of
// camera changes (each change with probability 0.5), and the test materials
// outside the library as the open set. Default options: the calibration and
// operating point compiled into RecognizerOptions. Prints the rates per
// change (docs/recognition.md) and asserts them below the measured values.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/recognition/material_recognizer.h"

#include "camera_views.h"

namespace frictiond {
namespace {

using namespace testing_recognition;

TEST(RecognitionCameraTest, HeldOutMaterialsUnderRandomCameraChanges) {
  if (!HavePatterns())
    GTEST_SKIP() << PatternDir() << " missing: apt-get install gimp-data";
  // FRICTIOND_CAMERA_SEED draws other views of the same held-out materials
  // (a fresh evaluation of a fixed method); the bounds below are for 7022.
  const char* seed_env = std::getenv("FRICTIOND_CAMERA_SEED");
  std::mt19937 rng(seed_env ? static_cast<unsigned>(std::atol(seed_env))
                            : 7022u);
  MaterialRecognizer recognizer;
  const MaterialSplit split = TestSplit();
  RegisterLibrary(&recognizer, split.known, 2, &rng);
  const std::vector<Outcome> outcomes = Evaluate(
      recognizer, split, /*known_views=*/24, /*unknown_views=*/16, &rng);
  PrintRates(outcomes);

  // Calibration on held-out views: mean score against fraction right, and
  // the Brier score of the top candidate's score.
  double brier = 0;
  std::printf(
      "| score bin | views | mean score | fraction right |\n"
      "|---|---|---|---|\n");
  for (int b = 0; b < 5; ++b) {
    int n = 0, right = 0;
    double sum = 0;
    for (const Outcome& o : outcomes) {
      if (o.top_score >= b / 5.0 && (o.top_score < (b + 1) / 5.0 || b == 4)) {
        ++n;
        sum += o.top_score;
        right += o.top1;
      }
    }
    std::printf("| %.1f-%.1f | %d | %.3f | %.3f |\n",
                b / 5.0,
                (b + 1) / 5.0,
                n,
                n ? sum / n : 0.0,
                n ? double(right) / n : 0.0);
  }
  for (const Outcome& o : outcomes) {
    brier += std::pow(o.top_score - (o.top1 ? 1.0 : 0.0), 2);
  }
  brier /= outcomes.size();
  // ROC on the held-out views (reported only; the operating point was
  // chosen on the tuning views).
  std::printf(
      "| score threshold | accepted and right | false accepts |\n"
      "|---|---|---|\n");
  for (double p : {0.05, 0.2, 0.4, 0.49, 0.5, 0.6, 0.62, 0.7, 0.8, 0.9}) {
    int known = 0, right = 0, unknown = 0, accepted = 0;
    for (const Outcome& o : outcomes) {
      if (o.known) {
        ++known;
        right += o.top1 && o.top_score >= p;
      } else {
        ++unknown;
        accepted += o.top_score >= p;
      }
    }
    std::printf("| %.2f | %.3f | %.3f |\n",
                p,
                double(right) / known,
                double(accepted) / unknown);
  }
  const Rates all = CalcRates(outcomes, -1);
  std::printf(
      "test: %d known views, %d open-set views; top-1 %.3f, accepted "
      "and right %.3f, accepted wrong %.3f, false accepts %.3f, "
      "Brier %.3f\n",
      all.known,
      all.unknown,
      all.Top1(),
      all.AcceptedRight(),
      all.AcceptedWrong(),
      all.FalseAccept(),
      brier);
  // Measured with this seed (feature version 4, docs/recognition.md):
  // top-1 0.964, accepted and right 0.908, accepted wrong 0.017, false
  // accepts 0.048 (10 of 208), Brier 0.047 (version 3: 0.931, 0.803,
  // 0.008, 0.058, 0.076). The goals (accepted and right >= 0.90,
  // false accepts <= 0.05) are met, the false accepts by one view (11 would
  // miss). This side was evaluated twice for version 4: after a first
  // candidate (0.958, 0.886, 0.006, 0.019, 0.047) and after the final one,
  // which was chosen on the tuning views before the second evaluation. The
  // bounds sit under the measurement; the false accepts are held to the
  // goal.
  EXPECT_GE(all.Top1(), 0.94);
  EXPECT_GE(all.AcceptedRight(), 0.88);
  EXPECT_LE(all.FalseAccept(), 0.05);
  EXPECT_LE(all.AcceptedWrong(), 0.02);
  EXPECT_LE(brier, 0.07);
}

}  // namespace
}  // namespace frictiond
