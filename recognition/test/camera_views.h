#pragma once
/// @file
/// Test helpers for the camera-view validation (issue 22): the GIMP textures
/// split by material into a tuning set and a test set, views with random
/// combinations of what a robot's camera changes, and the evaluation of a
/// recogniser over such views (top-1, accepted-and-right, false accepts, per
/// change). Used by recognition_calibration_test.cc (tuning set only: fits
/// the score calibration and the operating point) and
/// recognition_camera_test.cc (test set only: checks the goals with the
/// constants compiled into the library).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "frictiond/recognition/material_recognizer.h"

#include "gimp_pattern.h"

namespace frictiond {
namespace testing_recognition {

inline const char* PatternDir() { return "/usr/share/gimp/2.0/patterns"; }

inline bool HavePatterns() {
  return std::filesystem::exists(std::string(PatternDir()) +
                                 "/Stone/brick.pat");
}

inline cv::Mat LoadPattern(const std::string& name) {
  return ReadGimpPattern(std::string(PatternDir()) + "/" + name + ".pat");
}

/// One side of the split: materials in the library and materials that are
/// not (open set). The two sides share no material.
struct MaterialSplit {
  std::vector<std::string> known;
  std::vector<std::string> unknown;
};

/// Tuning side: the calibration and every design choice were made on it.
inline MaterialSplit TuningSplit() {
  return {{"Animal/leather",
           "Fabric/burlap",
           "Food/java",
           "Paper/crinklepaper",
           "Stone/Craters",
           "Stone/amethyst",
           "Stone/brick",
           "Stone/granite1",
           "Stone/marble1",
           "Stone/rock",
           "Stone/terra",
           "Water/ice",
           "Wood/bark",
           "Wood/parque1",
           "Wood/wood1"},
          {"Animal/leopard",
           "Legacy/3dgreen",
           "Legacy/blue",
           "Legacy/bluegrid",
           "Legacy/fibers",
           "Legacy/qube1",
           "Legacy/sm_squares",
           "Plant/leaves",
           "Sky/lightning",
           "Stone/marble2",
           "Water/electric",
           "Wood/parque2",
           "Wood/wood2"}};
}

/// Test side: never seen by the tuning. Includes a near-duplicate of a
/// library material (wood4 beside wood3).
inline MaterialSplit TestSplit() {
  return {{"Legacy/nops",
           "Paper/paper",
           "Stone/Moonfoot",
           "Stone/cracked",
           "Stone/ground1",
           "Stone/pink_marble",
           "Stone/slate",
           "Stone/stone33",
           "Water/rain",
           "Wood/burlwood",
           "Wood/corkboard",
           "Wood/pine",
           "Wood/walnut",
           "Wood/wood3",
           "Wood/wood5"},
          {"Food/choc_swirl",
           "Legacy/bluesquares",
           "Legacy/blueweb",
           "Legacy/pastel",
           "Legacy/recessed",
           "Legacy/redcube",
           "Legacy/warning",
           "Sky/sky",
           "Sky/starfield",
           "Stone/marble3",
           "Water/pool",
           "Wood/parque3",
           "Wood/wood4"}};
}

/// What a camera changes between registration and query.
enum Change {
  kRotation = 0,  ///< in-plane rotation U(0, 360) deg
  kScale,         ///< magnification log-uniform in [1/1.6, 1.8]
  kTilt,          ///< perspective: one edge 15-35 % shorter than the other
  kLightColour,   ///< warm or cool lamp: R x (1 +- t), B x (1 -+ t), t U(.1,.3)
  kIntensity,     ///< light level x U(0.6, 1.4), saturating at 255
  kFalloff,       ///< light falling off linearly across the view to 45-75 %
  kBlur,          ///< Gaussian blur sigma U(0.8, 2.0) px
  kNoise,         ///< Gaussian noise sigma U(3, 8) grey levels per channel
  kJpeg,          ///< JPEG quality U(30, 80) (else PNG)
  kOcclusion,     ///< a dark-grey object covering 10-25 % of the view
  kChangeCount
};

inline const char* ChangeName(int c) {
  static const char* const kNames[] = {"rotation",
                                       "scale 1/1.6-1.8x",
                                       "perspective tilt",
                                       "warm/cool light",
                                       "light intensity",
                                       "light falloff",
                                       "blur",
                                       "noise",
                                       "JPEG",
                                       "partial occlusion"};
  return kNames[c];
}

constexpr int kViewWidth = 320;
constexpr int kViewHeight = 240;

/// A rendered view: encoded bytes and which changes it carries.
struct CameraView {
  std::string encoded;
  unsigned changes = 0;  ///< bit c set: Change c applied
  double magnification = 1.0;
};

/// Renders a kViewWidth x kViewHeight view of the tiled `pattern`, centred
/// at a random position, with each change applied with probability
/// `p_change` (all off for a reference).
inline CameraView RenderCameraView(const cv::Mat& pattern,
                                   std::mt19937& rng,
                                   double p_change) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  CameraView view;
  for (int c = 0; c < kChangeCount; ++c) {
    if (u(rng) < p_change) view.changes |= 1u << c;
  }
  auto on = [&](Change c) { return (view.changes >> c) & 1u; };
  const double angle = on(kRotation) ? 2 * CV_PI * u(rng) : 0.0;
  view.magnification =
      on(kScale) ? std::exp(std::log(1 / 1.6) +
                            u(rng) * (std::log(1.8) - std::log(1 / 1.6)))
                 : 1.0;
  const double tilt = on(kTilt) ? 0.15 + 0.2 * u(rng) : 0.0;
  const double tilt_axis = 2 * CV_PI * u(rng);

  // Output pixel -> source: centre + R(angle) / m * Tilt(p - out_centre).
  const double half_w = kViewWidth / 2.0, half_h = kViewHeight / 2.0;
  cv::Mat perspective = cv::Mat::eye(3, 3, CV_64F);
  if (tilt > 0) {
    // The square around the output centre maps to a trapezoid whose edge
    // along tilt_axis is shorter by `tilt` (a plane seen at an angle).
    const double r = std::max(half_w, half_h);
    const double ca = std::cos(tilt_axis), sa = std::sin(tilt_axis);
    auto rot = [&](double x, double y) {
      return cv::Point2f(static_cast<float>(ca * x - sa * y),
                         static_cast<float>(sa * x + ca * y));
    };
    const cv::Point2f dst[4] = {rot(-r, -r), rot(r, -r), rot(r, r), rot(-r, r)};
    const double near = 1.0 + tilt / 2, far = 1.0 - tilt / 2;
    const cv::Point2f src[4] = {rot(-r * far, -r),
                                rot(r * far, -r),
                                rot(r * near, r),
                                rot(-r * near, r)};
    perspective = cv::getPerspectiveTransform(dst, src);
  }
  // Source extent: generous bound on where output pixels land.
  const double reach =
      std::hypot(half_w, half_h) * (1.0 + tilt) / view.magnification + 8;
  const int need = static_cast<int>(2 * reach) + 2;
  cv::Mat tiled;
  cv::repeat(pattern, need / pattern.rows + 3, need / pattern.cols + 3, tiled);
  const double cx = reach + 1 + u(rng) * (tiled.cols - 2 * reach - 2);
  const double cy = reach + 1 + u(rng) * (tiled.rows - 2 * reach - 2);
  const double c = std::cos(angle) / view.magnification;
  const double s = std::sin(angle) / view.magnification;
  const cv::Mat to_centre =
      (cv::Mat_<double>(3, 3) << 1, 0, -half_w, 0, 1, -half_h, 0, 0, 1);
  const cv::Mat rotate_scale =
      (cv::Mat_<double>(3, 3) << c, -s, cx, s, c, cy, 0, 0, 1);
  const cv::Mat out_to_src = rotate_scale * perspective * to_centre;
  cv::Mat image;
  cv::warpPerspective(tiled,
                      image,
                      out_to_src,
                      cv::Size(kViewWidth, kViewHeight),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                      cv::BORDER_REFLECT);

  // Light, in float: per-channel gain (colour), intensity, falloff.
  cv::Mat3f light;
  image.convertTo(light, CV_32FC3);
  cv::Vec3f gain(1, 1, 1);
  if (on(kLightColour)) {
    const double t = (0.1 + 0.2 * u(rng)) * (u(rng) < 0.5 ? 1 : -1);
    gain =
        cv::Vec3f(static_cast<float>(1 - t), 1.0f, static_cast<float>(1 + t));
  }
  if (on(kIntensity)) gain *= static_cast<float>(0.6 + 0.8 * u(rng));
  const double fall_to = on(kFalloff) ? 0.45 + 0.3 * u(rng) : 1.0;
  const double fall_axis = 2 * CV_PI * u(rng);
  const double fx = std::cos(fall_axis), fy = std::sin(fall_axis);
  const double span = std::abs(fx) * kViewWidth + std::abs(fy) * kViewHeight;
  for (int y = 0; y < light.rows; ++y) {
    cv::Vec3f* row = light[y];
    for (int x = 0; x < light.cols; ++x) {
      const double along =
          ((x - half_w) * fx + (y - half_h) * fy) / span + 0.5;  // 0..1
      const float level = static_cast<float>(1.0 - (1.0 - fall_to) * along);
      for (int k = 0; k < 3; ++k) row[x][k] *= gain[k] * level;
    }
  }
  if (on(kBlur)) {
    const double sigma = 0.8 + 1.2 * u(rng);
    cv::GaussianBlur(light, light, cv::Size(0, 0), sigma);
  }
  if (on(kOcclusion)) {
    // A rotated rectangle (a gripper finger, a cable) of a dark grey with
    // slight shading, covering 10-25 % of the view.
    const double area = (0.10 + 0.15 * u(rng)) * kViewWidth * kViewHeight;
    const double aspect = 1.0 + 2.0 * u(rng);
    const float w = static_cast<float>(std::sqrt(area * aspect));
    const float h = static_cast<float>(std::sqrt(area / aspect));
    const cv::RotatedRect box(
        cv::Point2f(static_cast<float>(u(rng) * kViewWidth),
                    static_cast<float>(u(rng) * kViewHeight)),
        cv::Size2f(w, h),
        static_cast<float>(360 * u(rng)));
    cv::Point2f corners[4];
    box.points(corners);
    std::vector<cv::Point> poly(corners, corners + 4);
    const float grey = static_cast<float>(30 + 60 * u(rng));
    cv::fillConvexPoly(light, poly, cv::Scalar(grey, grey, grey * 1.05));
  }
  if (on(kNoise)) {
    cv::Mat3f noise(light.size());
    const double sigma = 3.0 + 5.0 * u(rng);
    cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(sigma));
    light += noise;
  }
  light.convertTo(image, CV_8UC3);  // saturating
  if (on(kJpeg)) {
    view.encoded = Encode(image, ".jpg", 30 + static_cast<int>(50 * u(rng)));
  } else {
    view.encoded = Encode(image, ".png");
  }
  return view;
}

/// Registers `references` views per known material (no changes: the
/// operator's camera, distance and lamp), the first at 0 deg.
inline void RegisterLibrary(MaterialRecognizer* recognizer,
                            const std::vector<std::string>& known,
                            int references,
                            std::mt19937* rng) {
  for (const std::string& name : known) {
    const cv::Mat pattern = LoadPattern(name);
    for (int r = 0; r < references; ++r) {
      recognizer->AddReference(name,
                               RenderCameraView(pattern, *rng, 0.0).encoded);
    }
  }
}

/// One evaluated query.
struct Outcome {
  bool known = false;  ///< the material is in the library
  unsigned changes = 0;
  bool top1 = false;      ///< best candidate is the true material
  bool accepted = false;  ///< not unknown
  double top_similarity = 0.0;
  double second_similarity = 0.0;    ///< of the second material
  std::vector<double> similarities;  ///< of every candidate, best first
  double top_score = 0.0;
  std::string truth, answer;
};

/// `views` random views (p_change 0.5) of each known and unknown material.
inline std::vector<Outcome> Evaluate(const MaterialRecognizer& recognizer,
                                     const MaterialSplit& split,
                                     int known_views,
                                     int unknown_views,
                                     std::mt19937* rng) {
  std::vector<Outcome> outcomes;
  for (int side = 0; side < 2; ++side) {
    const std::vector<std::string>& names =
        side == 0 ? split.known : split.unknown;
    for (const std::string& name : names) {
      const cv::Mat pattern = LoadPattern(name);
      for (int v = 0; v < (side == 0 ? known_views : unknown_views); ++v) {
        const CameraView view = RenderCameraView(pattern, *rng, 0.5);
        const RecognitionResult r = recognizer.Recognize(view.encoded);
        Outcome o;
        o.known = side == 0;
        o.changes = view.changes;
        o.truth = name;
        if (!r.candidates.empty()) {
          o.answer = r.candidates.front().material;
          o.top_similarity = r.candidates.front().similarity;
          o.top_score = r.candidates.front().score;
          if (r.candidates.size() > 1)
            o.second_similarity = r.candidates[1].similarity;
          for (const RecognitionCandidate& c : r.candidates)
            o.similarities.push_back(c.similarity);
        }
        o.top1 = o.known && o.answer == name;
        o.accepted = !r.unknown;
        outcomes.push_back(o);
      }
    }
  }
  return outcomes;
}

/// Rates over a subset of outcomes.
struct Rates {
  int known = 0, unknown = 0;
  int top1 = 0, accepted_right = 0, accepted_wrong = 0, false_accepts = 0;
  double Top1() const { return known ? double(top1) / known : 0; }
  double AcceptedRight() const {
    return known ? double(accepted_right) / known : 0;
  }
  /// Known views accepted as another material.
  double AcceptedWrong() const {
    return known ? double(accepted_wrong) / known : 0;
  }
  /// Views of materials not in the library that were accepted.
  double FalseAccept() const {
    return unknown ? double(false_accepts) / unknown : 0;
  }
};

/// Rates over the outcomes with change `change` (-1: all outcomes).
inline Rates CalcRates(const std::vector<Outcome>& outcomes, int change) {
  Rates r;
  for (const Outcome& o : outcomes) {
    if (change >= 0 && !((o.changes >> change) & 1u)) continue;
    if (o.known) {
      ++r.known;
      r.top1 += o.top1;
      r.accepted_right += o.top1 && o.accepted;
      r.accepted_wrong += !o.top1 && o.accepted;
    } else {
      ++r.unknown;
      r.false_accepts += o.accepted;
    }
  }
  return r;
}

inline void PrintRates(const std::vector<Outcome>& outcomes) {
  std::printf(
      "| change | known views | top-1 | accepted and right | "
      "accepted wrong | unknown views | false accepts |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (int c = -1; c < kChangeCount; ++c) {
    const Rates r = CalcRates(outcomes, c);
    std::printf("| %s | %d | %.3f | %.3f | %.3f | %d | %.3f |\n",
                c < 0 ? "all views" : ChangeName(c),
                r.known,
                r.Top1(),
                r.AcceptedRight(),
                r.AcceptedWrong(),
                r.unknown,
                r.FalseAccept());
  }
}

}  // namespace testing_recognition
}  // namespace frictiond
