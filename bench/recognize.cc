// recognize: milliseconds to recognise one 640x480 JPEG photograph against a
// library of registered reference images (issues 6 and 22, goal <= 20 ms;
// since issue 22 each query is described five times (whole view and without
// each quadrant) and compared with nine scales of every reference), beside
// the floor of the same run: decoding the same JPEG with cv::imdecode, which
// every recogniser has to do first.
//
// Images are synthetic surface textures (filtered noise with a per-material
// grain size, orientation and tint), so the benchmark needs no data files;
// recognition accuracy on real textures is measured by
// recognition/test/recognition_accuracy_test.cc (docs/recognition.md).
#include <algorithm>
#include <chrono>
#include <iostream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "frictiond/recognition/material_recognizer.h"

#include "bench_json.h"

namespace {

constexpr int kMaterials = 30;
constexpr int kReferencesPerMaterial = 2;
constexpr int kQueries = 60;
constexpr int kRounds = 3;  // each query image is recognised kRounds times

/// A 640x480 texture of material `material`, photographed at `shot` (a new
/// noise realisation, so queries are not copies of the references).
std::string MakeJpeg(int material, int shot) {
  cv::RNG rng(static_cast<std::uint64_t>(1000 * material + shot + 1));
  cv::Mat noise(480, 640, CV_32FC1);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  const double grain = 0.8 + 0.25 * (material % 8);         // px
  const double stretch = 1.0 + 1.5 * ((material / 8) % 4);  // anisotropy
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), grain * stretch, grain);
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  cv::Mat grey;
  noise.convertTo(grey, CV_8UC1);
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  const cv::Scalar tint(0.6 + 0.4 * ((material * 7) % 5) / 4.0,
                        0.6 + 0.4 * ((material * 3) % 5) / 4.0,
                        0.6 + 0.4 * (material % 5) / 4.0);
  cv::multiply(bgr, tint, bgr);
  std::vector<unsigned char> buf;
  cv::imencode(".jpg", bgr, buf, {cv::IMWRITE_JPEG_QUALITY, 90});
  return std::string(buf.begin(), buf.end());
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main() {
  using Clock = std::chrono::steady_clock;
  frictiond::MaterialRecognizer recognizer;
  for (int m = 0; m < kMaterials; ++m) {
    for (int r = 0; r < kReferencesPerMaterial; ++r) {
      recognizer.AddReference("material-" + std::to_string(m), MakeJpeg(m, r));
    }
  }
  std::vector<std::string> queries;
  for (int q = 0; q < kQueries; ++q) {
    queries.push_back(MakeJpeg(q % kMaterials, 100 + q));
  }

  std::vector<double> recognise_ms, decode_ms;
  int correct = 0;
  for (int round = 0; round < kRounds; ++round) {
    for (int q = 0; q < kQueries; ++q) {
      const std::string& img = queries[static_cast<std::size_t>(q)];
      auto t0 = Clock::now();
      const frictiond::RecognitionResult res = recognizer.Recognize(img);
      auto t1 = Clock::now();
      const cv::Mat raw(1,
                        static_cast<int>(img.size()),
                        CV_8UC1,
                        const_cast<char*>(img.data()));
      const cv::Mat decoded = cv::imdecode(raw, cv::IMREAD_COLOR);
      auto t2 = Clock::now();
      if (decoded.empty()) {
        std::cerr << "recognize: imdecode failed\n";
        return 1;
      }
      recognise_ms.push_back(
          std::chrono::duration<double, std::milli>(t1 - t0).count());
      decode_ms.push_back(
          std::chrono::duration<double, std::milli>(t2 - t1).count());
      if (round == 0 && !res.candidates.empty() &&
          res.candidates.front().material ==
              "material-" + std::to_string(q % kMaterials)) {
        ++correct;
      }
    }
  }

  frictiond::bench::BenchResult r;
  r.bench = "recognize";
  r.value = Median(recognise_ms);
  r.unit = "ms";
  r.baseline = Median(decode_ms);
  r.baseline_name = "cv::imdecode of the same 640x480 JPEG (floor)";
  r.lower_is_better = true;
  r.goal = "<= 20 ms";
  r.note = "median of " + std::to_string(recognise_ms.size()) +
           " recognitions, " + std::to_string(kMaterials) + " materials x " +
           std::to_string(kReferencesPerMaterial) +
           " references; synthetic textures, top-1 " + std::to_string(correct) +
           "/" + std::to_string(kQueries);
  frictiond::bench::PrintBenchLine(r);
  return 0;
}
