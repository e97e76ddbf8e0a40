// Calibration of the recogniser's score and operating point on the TUNING
// side of the material split (camera_views.h): views with random
// combinations of camera changes, a library of the tuning materials, and the
// tuning materials outside the library as the open set. The fit (Platt
// scaling of the best similarity) and the operating point (the lowest score
// threshold accepting at most kTargetFalseAccept of the open-set views) are
// printed with the ROC, and must equal the constants compiled into
// RecognizerOptions (so the constants are reproducible from this test). The
// test side is never touched here (recognition_camera_test.cc).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/recognition/material_recognizer.h"

#include "camera_views.h"

namespace frictiond {
namespace {

using namespace testing_recognition;

/// Stated false-accept rate of the operating point on the tuning views (the
/// goal is <= 5 % on the test views; the margin absorbs the difference).
constexpr double kTargetFalseAccept = 0.03;

struct Platt {
  double slope = 0, midpoint = 0;
};

/// Logistic regression p = 1 / (1 + exp(-(a x + b))) by Newton's method
/// (maximum likelihood; Platt 1999 without the label smoothing).
Platt FitPlatt(const std::vector<double>& x, const std::vector<int>& y) {
  double a = 10, b = -8;
  for (int iter = 0; iter < 100; ++iter) {
    double g0 = 0, g1 = 0, h00 = 0, h01 = 0, h11 = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double p = 1 / (1 + std::exp(-(a * x[i] + b)));
      const double w = std::max(p * (1 - p), 1e-12);
      g0 += (p - y[i]) * x[i];
      g1 += p - y[i];
      h00 += w * x[i] * x[i];
      h01 += w * x[i];
      h11 += w;
    }
    const double det = h00 * h11 - h01 * h01;
    const double da = (h11 * g0 - h01 * g1) / det;
    const double db = (h00 * g1 - h01 * g0) / det;
    a -= da;
    b -= db;
    if (std::abs(da) < 1e-9 && std::abs(db) < 1e-9) break;
  }
  return {a, -b / a};
}

/// The evidence the recogniser calibrates (RecognitionCandidate::score).
double Evidence(const Outcome& o) {
  return 2 * o.top_similarity - o.second_similarity;
}

TEST(RecognitionCalibrationTest, ConstantsComeFromTheTuningViews) {
  if (!HavePatterns())
    GTEST_SKIP() << PatternDir() << " missing: apt-get install gimp-data";
  std::mt19937 rng(2026);
  // Raw similarities: the operating point 0 accepts everything.
  RecognizerOptions raw;
  raw.unknown_threshold = 0.0;
  raw.max_candidates = 100;
  MaterialRecognizer recognizer(raw);
  const MaterialSplit split = TuningSplit();
  RegisterLibrary(&recognizer, split.known, 2, &rng);
  const std::vector<Outcome> outcomes = Evaluate(
      recognizer, split, /*known_views=*/24, /*unknown_views=*/24, &rng);

  std::vector<double> x;
  std::vector<int> y;
  std::vector<double> open_set;
  for (const Outcome& o : outcomes) {
    x.push_back(Evidence(o));
    y.push_back(o.top1 ? 1 : 0);
    if (!o.known) open_set.push_back(Evidence(o));
  }
  const Platt fit = FitPlatt(x, y);
  PrintRates(outcomes);
  auto calibrate = [&](double s) {
    return 1 / (1 + std::exp(-fit.slope * (s - fit.midpoint)));
  };
  // Operating point: the smallest similarity threshold t (a similarity seen
  // on an open-set view, or just above it) with FAR(t) <= target.
  std::sort(open_set.begin(), open_set.end());
  const std::size_t allowed = static_cast<std::size_t>(
      std::floor(kTargetFalseAccept * open_set.size()));
  const double t_evidence =
      std::nextafter(open_set[open_set.size() - 1 - allowed], 2.0);
  const double operating_point = calibrate(t_evidence);
  std::printf(
      "tuning: %zu views; Platt slope %.2f midpoint %.4f; operating "
      "point %.3f (evidence %.4f) for false accepts <= %.2f\n",
      outcomes.size(),
      fit.slope,
      fit.midpoint,
      operating_point,
      t_evidence,
      kTargetFalseAccept);

  {
    // Open-set views accepted at the operating point, by material.
    std::map<std::string, int> accepted;
    for (const Outcome& o : outcomes) {
      if (!o.known && Evidence(o) >= t_evidence) {
        ++accepted[o.truth + " -> " + o.answer];
      }
    }
    for (const auto& [pair, n] : accepted) {
      std::printf("  open set accepted: %s x%d\n", pair.c_str(), n);
    }
    int known = 0, right = 0;
    for (const Outcome& o : outcomes) {
      if (!o.known) continue;
      ++known;
      right += o.top1 && Evidence(o) >= t_evidence;
    }
    std::printf("  accepted and right at the operating point: %.3f\n",
                double(right) / known);
    // Accepted and right per change at the operating point.
    for (int c = 0; c < kChangeCount; ++c) {
      int with = 0, with_right = 0, without = 0, without_right = 0;
      for (const Outcome& o : outcomes) {
        if (!o.known) continue;
        const bool ok = o.top1 && Evidence(o) >= t_evidence;
        if ((o.changes >> c) & 1u) {
          ++with;
          with_right += ok;
        } else {
          ++without;
          without_right += ok;
        }
      }
      std::printf("  accepted and right with %s: %.3f (without: %.3f)\n",
                  ChangeName(c),
                  double(with_right) / with,
                  double(without_right) / without);
    }
  }
  // ROC over the tuning views (score thresholds).
  std::printf(
      "| score threshold | accepted and right | false accepts |\n"
      "|---|---|---|\n");
  for (double p : {0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95}) {
    int known = 0, right = 0, unknown = 0, fa = 0;
    for (const Outcome& o : outcomes) {
      const bool accept = calibrate(Evidence(o)) >= p;
      if (o.known) {
        ++known;
        right += accept && o.top1;
      } else {
        ++unknown;
        fa += accept;
      }
    }
    std::printf("| %.2f | %.3f | %.3f |\n",
                p,
                double(right) / known,
                double(fa) / unknown);
  }
  // Reliability of the fitted score on the tuning views.
  std::printf(
      "| score bin | views | mean score | fraction right |\n"
      "|---|---|---|---|\n");
  for (int b = 0; b < 5; ++b) {
    int n = 0, right = 0;
    double sum = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double p = calibrate(x[i]);
      if (p >= b / 5.0 && (p < (b + 1) / 5.0 || b == 4)) {
        ++n;
        sum += p;
        right += y[i];
      }
    }
    std::printf("| %.1f-%.1f | %d | %.3f | %.3f |\n",
                b / 5.0,
                (b + 1) / 5.0,
                n,
                n ? sum / n : 0.0,
                n ? double(right) / n : 0.0);
  }

  EXPECT_NEAR(fit.slope, RecognizerOptions::kCalibrationSlope, 0.5);
  EXPECT_NEAR(fit.midpoint, RecognizerOptions::kCalibrationMidpoint, 0.002);
  EXPECT_NEAR(operating_point, RecognizerOptions::kDefaultOperatingPoint, 0.02);
}

}  // namespace
}  // namespace frictiond
