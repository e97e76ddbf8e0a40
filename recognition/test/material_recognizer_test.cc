#include "frictiond/recognition/material_recognizer.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace frictiond {
namespace {

static_assert(std::is_nothrow_move_constructible_v<MaterialRecognizer>);
static_assert(std::is_nothrow_move_assignable_v<MaterialRecognizer>);
static_assert(!std::is_copy_constructible_v<MaterialRecognizer>);
static_assert(!std::is_copy_assignable_v<MaterialRecognizer>);

/// Expects `statement` to throw std::invalid_argument whose message starts
/// with `prefix` and contains `part`.
#define EXPECT_INVALID_ARGUMENT(statement, prefix, part)           \
  do {                                                             \
    try {                                                          \
      statement;                                                   \
      ADD_FAILURE() << "no exception from " #statement;            \
    } catch (const std::invalid_argument& e) {                     \
      const std::string message = e.what();                        \
      EXPECT_EQ(message.rfind(prefix, 0), 0u) << message;          \
      EXPECT_NE(message.find(part), std::string::npos) << message; \
    }                                                              \
  } while (false)

std::string Encode(const cv::Mat& image, const std::string& ext = ".png") {
  std::vector<unsigned char> buf;
  EXPECT_TRUE(cv::imencode(ext, image, buf));
  return std::string(buf.begin(), buf.end());
}

/// A textured colour image: smoothed noise of `seed` tinted by `colour`.
cv::Mat MakeTexture(int seed,
                    cv::Scalar colour,
                    int width = 200,
                    int height = 160) {
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  cv::Mat1f noise(height, width);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.0 + seed % 3);
  cv::normalize(noise, noise, 0.3, 1.0, cv::NORM_MINMAX);
  cv::Mat3f tinted;
  cv::merge(
      std::vector<cv::Mat>{
          noise * colour[0], noise * colour[1], noise * colour[2]},
      tinted);
  cv::Mat image;
  tinted.convertTo(image, CV_8UC3);
  return image;
}

TEST(RecognizerOptionsTest, DefaultsAreValid) {
  std::string why = "unchanged";
  EXPECT_TRUE(RecognizerOptions{}.IsValid(&why));
  EXPECT_EQ(why, "unchanged");
  EXPECT_TRUE(RecognizerOptions{}.IsValid(nullptr));
}

TEST(RecognizerOptionsTest, RejectsEachBadFieldWithItsName) {
  std::string why;
  RecognizerOptions o;
  o.unknown_threshold = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("unknown_threshold = nan (must be in [0, 1])"),
            std::string::npos)
      << why;
  o = {};
  o.unknown_threshold = 1.5;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("unknown_threshold = 1.5"), std::string::npos) << why;
  o = {};
  o.min_margin = -0.1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("min_margin = -0.1"), std::string::npos) << why;
  o = {};
  o.max_candidates = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_EQ(why, "max_candidates = 0 (must be >= 1)");
  EXPECT_INVALID_ARGUMENT(
      MaterialRecognizer{o}, "max_candidates = 0", "must be >= 1");
  o = RecognizerOptions{};
  o.calibration_slope = 0.0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("calibration_slope = 0"), std::string::npos) << why;
  o = RecognizerOptions{};
  o.calibration_midpoint = -0.1;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("calibration_midpoint = -0.1"), std::string::npos) << why;
}

class BadImageTest : public ::testing::Test {
 protected:
  /// Each bad input must throw "image: ..." naming `reason`, from every entry
  /// point, and register nothing.
  void ExpectRejected(const std::string& bytes, const std::string& reason) {
    SCOPED_TRACE(reason);
    EXPECT_INVALID_ARGUMENT(
        recognizer_.AddReference("steel", bytes), "image: ", reason);
    EXPECT_INVALID_ARGUMENT(recognizer_.Recognize(bytes), "image: ", reason);
    EXPECT_INVALID_ARGUMENT(
        recognizer_.ExtractFeatures(bytes), "image: ", reason);
    EXPECT_EQ(recognizer_.reference_count(), 0u);
  }
  MaterialRecognizer recognizer_;
  const cv::Mat good_ = MakeTexture(1, cv::Scalar(200, 120, 60));
};

TEST_F(BadImageTest, EmptyBody) { ExpectRejected("", "empty body"); }

TEST_F(BadImageTest, RandomBytes) {
  std::mt19937 rng(11);
  std::string bytes(4096, '\0');
  for (char& c : bytes) c = static_cast<char>(rng() & 0xFF);
  bytes[0] = 'R';  // make sure the signature is not PNG/JPEG by chance
  ExpectRejected(bytes, "not a PNG or JPEG");
}

TEST_F(BadImageTest, OtherFormatIsRejected) {
  ExpectRejected(Encode(good_, ".bmp"), "not a PNG or JPEG");
}

TEST_F(BadImageTest, TruncatedPng) {
  const std::string png = Encode(good_);
  ExpectRejected(png.substr(0, png.size() / 2),
                 "PNG truncated (no IEND end chunk)");
  // Complete framing around corrupt pixel data: libpng itself fails.
  std::string corrupt = png;
  for (std::size_t i = 60; i < corrupt.size() - 20; ++i)
    corrupt[i] = static_cast<char>(i);
  ExpectRejected(corrupt, "corrupt or truncated PNG data");
  ExpectRejected(png.substr(0, 20), "PNG truncated before its header");
}

TEST_F(BadImageTest, TruncatedJpeg) {
  const std::string jpeg = Encode(good_, ".jpg");
  ExpectRejected(jpeg.substr(0, jpeg.size() / 2), "JPEG truncated");
  ExpectRejected(jpeg.substr(0, 6), "JPEG truncated");
}

TEST_F(BadImageTest, EveryStrictPrefixIsRejected) {
  for (const std::string ext : {".png", ".jpg"}) {
    const std::string bytes = Encode(good_, ext);
    for (std::size_t n = 0; n + 2 < bytes.size(); n += 7) {
      EXPECT_INVALID_ARGUMENT(
          recognizer_.ExtractFeatures(bytes.substr(0, n)), "image: ", "");
    }
    EXPECT_EQ(recognizer_.ExtractFeatures(bytes).size(),
              MaterialRecognizer::feature_size());
  }
}

TEST_F(BadImageTest, TooSmall) {
  ExpectRejected(Encode(cv::Mat(1, 1, CV_8UC3, cv::Scalar(1, 2, 3))),
                 "1x1 pixels is too small (each side must be >= 32)");
  ExpectRejected(Encode(good_(cv::Rect(0, 0, 100, 31))),
                 "100x31 pixels is too small");
}

TEST_F(BadImageTest, TooLargeIsRejectedFromTheHeader) {
  // A valid small PNG whose IHDR claims 10000x5000: rejected before any
  // pixel is decoded (the CRC is not even checked).
  std::string png = Encode(good_);
  const auto put32 = [&](std::size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
      png[at + i] = static_cast<char>((v >> (24 - 8 * i)) & 0xFF);
  };
  put32(16, 10000);
  put32(20, 5000);
  ExpectRejected(
      png,
      "10000x5000 pixels = 50.0 megapixels is too large (must be <= 40.0)");
}

TEST(MaterialRecognizerTest, EmptyMaterialIdIsRejected) {
  MaterialRecognizer recognizer;
  const std::string png = Encode(MakeTexture(1, cv::Scalar(200, 120, 60)));
  EXPECT_INVALID_ARGUMENT(
      recognizer.AddReference("", png), "material_id: ", "non-empty");
  EXPECT_INVALID_ARGUMENT(
      recognizer.AddReferenceFeatures("", recognizer.ExtractFeatures(png)),
      "material_id: ",
      "non-empty");
  EXPECT_EQ(recognizer.reference_count(), 0u);
}

TEST(MaterialRecognizerTest, EmptyRegistryAnswersUnknown) {
  const MaterialRecognizer recognizer;
  const RecognitionResult r =
      recognizer.Recognize(Encode(MakeTexture(2, cv::Scalar(90, 200, 90))));
  EXPECT_TRUE(r.unknown);
  EXPECT_TRUE(r.candidates.empty());
  EXPECT_EQ(r.reason, "no reference image is registered");
}

TEST(MaterialRecognizerTest, FeaturesRoundTripAndSelfMatch) {
  MaterialRecognizer recognizer;
  const std::string steel = Encode(MakeTexture(1, cv::Scalar(200, 200, 200)));
  const std::string rubber =
      Encode(MakeTexture(2, cv::Scalar(40, 40, 200)), ".jpg");
  const std::vector<float> f = recognizer.ExtractFeatures(steel);
  ASSERT_EQ(f.size(), MaterialRecognizer::feature_size());
  recognizer.AddReferenceFeatures("steel", f);
  recognizer.AddReference("rubber", rubber);
  EXPECT_EQ(recognizer.reference_count(), 2u);
  EXPECT_EQ(recognizer.material_count(), 2u);

  const RecognitionResult r = recognizer.Recognize(steel);
  ASSERT_EQ(r.candidates.size(), 2u);
  EXPECT_FALSE(r.unknown);
  EXPECT_EQ(r.candidates[0].material, "steel");
  EXPECT_NEAR(r.candidates[0].similarity, 1.0, 1e-5);
  EXPECT_EQ(r.candidates[1].material, "rubber");
  EXPECT_GE(r.candidates[1].similarity, 0.0);
  EXPECT_LT(r.candidates[1].similarity, r.candidates[0].similarity);
  // The score is the calibrated evidence: similarity plus the margin over
  // the other material (RecognitionCandidate::score).
  const RecognizerOptions& o = recognizer.options();
  const double evidence =
      2 * r.candidates[0].similarity - r.candidates[1].similarity;
  EXPECT_NEAR(r.candidates[0].score,
              1 / (1 + std::exp(-o.calibration_slope *
                                (evidence - o.calibration_midpoint))),
              1e-12);
  EXPECT_GT(r.candidates[0].score, r.candidates[1].score);
  EXPECT_EQ(r.reason.rfind("steel at ", 0), 0u) << r.reason;
  EXPECT_EQ(r.operating_point, o.unknown_threshold);

  const RecognitionResult from_features = recognizer.RecognizeFeatures(f);
  ASSERT_EQ(from_features.candidates.size(), 2u);
  EXPECT_EQ(from_features.candidates[1].score, r.candidates[1].score);
}

TEST(MaterialRecognizerTest, BadFeatureVectorsAreRejected) {
  MaterialRecognizer recognizer;
  const std::vector<float> good = recognizer.ExtractFeatures(
      Encode(MakeTexture(3, cv::Scalar(10, 90, 200))));
  std::vector<float> bad(good.begin(), good.end() - 1);
  EXPECT_INVALID_ARGUMENT(recognizer.AddReferenceFeatures("x", bad),
                          "features: size = " + std::to_string(good.size() - 1),
                          "must be " + std::to_string(good.size()));
  bad = good;
  bad[3] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_INVALID_ARGUMENT(recognizer.AddReferenceFeatures("x", bad),
                          "features: value [3] = nan",
                          "must be finite");
  bad = good;
  bad[0] = -bad[0] - 0.1f;
  EXPECT_INVALID_ARGUMENT(
      recognizer.RecognizeFeatures(bad), "features: value [0]", ">= 0");
  bad = good;
  for (float& v : bad) v *= 2.0f;
  EXPECT_INVALID_ARGUMENT(recognizer.AddReferenceFeatures("x", bad),
                          "features: block chromaticity has squared norm 4",
                          "must be 1");
  EXPECT_EQ(recognizer.reference_count(), 0u);
}

TEST(MaterialRecognizerTest, CandidatesAreDistinctSortedAndCapped) {
  RecognizerOptions options;
  options.max_candidates = 3;
  MaterialRecognizer recognizer(options);
  const std::vector<cv::Scalar> colours = {cv::Scalar(200, 60, 60),
                                           cv::Scalar(60, 200, 60),
                                           cv::Scalar(60, 60, 200),
                                           cv::Scalar(200, 200, 60),
                                           cv::Scalar(200, 200, 200)};
  for (int i = 0; i < 5; ++i) {
    // Two references per material.
    recognizer.AddReference("m" + std::to_string(i),
                            Encode(MakeTexture(i, colours[i])));
    recognizer.AddReference("m" + std::to_string(i),
                            Encode(MakeTexture(i + 10, colours[i])));
  }
  EXPECT_EQ(recognizer.reference_count(), 10u);
  EXPECT_EQ(recognizer.material_count(), 5u);
  const RecognitionResult r =
      recognizer.Recognize(Encode(MakeTexture(20, colours[2])));
  ASSERT_EQ(r.candidates.size(), 3u);
  EXPECT_EQ(r.candidates[0].material, "m2");
  for (std::size_t i = 0; i < r.candidates.size(); ++i) {
    EXPECT_GE(r.candidates[i].score, 0.0);
    EXPECT_LE(r.candidates[i].score, 1.0);
    if (i > 0) {
      EXPECT_GE(r.candidates[i - 1].score, r.candidates[i].score);
      EXPECT_NE(r.candidates[i - 1].material, r.candidates[i].material);
    }
  }
}

TEST(MaterialRecognizerTest, RemoveMaterialAndClear) {
  MaterialRecognizer recognizer;
  const std::string a = Encode(MakeTexture(1, cv::Scalar(200, 60, 60)));
  const std::string b = Encode(MakeTexture(2, cv::Scalar(60, 200, 60)));
  recognizer.AddReference("a", a);
  recognizer.AddReference("b", b);
  recognizer.AddReference("a", b);
  EXPECT_EQ(recognizer.RemoveMaterial("missing"), 0u);
  EXPECT_EQ(recognizer.RemoveMaterial("a"), 2u);
  EXPECT_EQ(recognizer.reference_count(), 1u);
  const RecognitionResult r = recognizer.Recognize(a);
  ASSERT_EQ(r.candidates.size(), 1u);
  EXPECT_EQ(r.candidates[0].material, "b");
  // The remaining reference kept its own features.
  EXPECT_NEAR(recognizer.Recognize(b).candidates[0].similarity, 1.0, 1e-5);
  recognizer.Clear();
  EXPECT_EQ(recognizer.reference_count(), 0u);
  EXPECT_TRUE(recognizer.Recognize(a).unknown);
}

TEST(MaterialRecognizerTest, ThresholdAndMarginDecideUnknown) {
  const std::string image = Encode(MakeTexture(4, cv::Scalar(120, 80, 200)));
  const std::string other = Encode(MakeTexture(5, cv::Scalar(20, 220, 20)));
  {
    RecognizerOptions options;
    options.unknown_threshold = 0.0;
    MaterialRecognizer recognizer(options);
    recognizer.AddReference("x", other);
    EXPECT_FALSE(recognizer.Recognize(image).unknown);
  }
  {
    RecognizerOptions options;
    options.unknown_threshold = 1.0;
    MaterialRecognizer recognizer(options);
    recognizer.AddReference("x", other);
    const RecognitionResult r = recognizer.Recognize(image);
    EXPECT_TRUE(r.unknown);
    // Says why: the closest material, its score and the operating point.
    EXPECT_EQ(r.reason.rfind("closest is x at 0.", 0), 0u) << r.reason;
    EXPECT_NE(r.reason.find(", below the 1.00 operating point"),
              std::string::npos)
        << r.reason;
  }
  {
    // Two ids with the same reference: a perfect but ambiguous match.
    RecognizerOptions options;
    options.min_margin = 0.01;
    MaterialRecognizer recognizer(options);
    recognizer.AddReference("x", image);
    recognizer.AddReference("y", image);
    const RecognitionResult r = recognizer.Recognize(image);
    EXPECT_TRUE(r.unknown);
    ASSERT_EQ(r.candidates.size(), 2u);
    EXPECT_EQ(r.candidates[0].material, "x");  // ties broken by id
    recognizer.RemoveMaterial("y");
    EXPECT_FALSE(recognizer.Recognize(image).unknown);
  }
}

TEST(MaterialRecognizerTest, InvariantToResolutionAndBrightness) {
  MaterialRecognizer recognizer;
  const cv::Mat texture = MakeTexture(6, cv::Scalar(60, 140, 220), 320, 240);
  recognizer.AddReference("wood", Encode(texture));
  cv::Mat bigger;
  cv::resize(texture, bigger, cv::Size(), 2.0, 2.0, cv::INTER_CUBIC);
  EXPECT_GT(
      recognizer.Recognize(Encode(bigger, ".jpg")).candidates[0].similarity,
      0.9);
  cv::Mat darker;
  texture.convertTo(darker, -1, 0.7);
  EXPECT_GT(recognizer.Recognize(Encode(darker)).candidates[0].similarity, 0.9);
}

TEST(MaterialRecognizerTest, OccluderAndLampColourCostLittle) {
  MaterialRecognizer recognizer;
  const cv::Mat texture = MakeTexture(6, cv::Scalar(60, 140, 220), 320, 240);
  recognizer.AddReference("wood", Encode(texture));
  recognizer.AddReference("other",
                          Encode(MakeTexture(7, cv::Scalar(60, 140, 220))));
  // A dark-grey occluder over 1/6 of the view, inside the top-left 4 of the
  // 16 cells: the partial match leaves those cells out.
  cv::Mat occluded = texture.clone();
  cv::rectangle(
      occluded, cv::Rect(0, 0, 140, 90), cv::Scalar(50, 50, 52), cv::FILLED);
  const RecognitionResult r = recognizer.Recognize(Encode(occluded));
  ASSERT_EQ(r.candidates.size(), 2u);
  EXPECT_EQ(r.candidates[0].material, "wood");
  std::printf("occluded: similarity %.4f (other material %.4f)\n",
              r.candidates[0].similarity,
              r.candidates[1].similarity);
  // Measured 0.984 (the other material 0.892). Without the partial match
  // the occluder's sixth of the mass would cost about 0.15.
  EXPECT_GT(r.candidates[0].similarity, 0.96);
  EXPECT_GT(r.candidates[0].similarity - r.candidates[1].similarity, 0.05);
  // A warmer lamp (a diagonal gain: R x 1.25, B x 0.75): the grey world and
  // the balanced grey cancel it.
  cv::Mat warm;
  cv::multiply(texture, cv::Scalar(0.75, 1.0, 1.25), warm);
  const RecognitionResult w = recognizer.Recognize(Encode(warm));
  ASSERT_EQ(w.candidates.size(), 2u);
  EXPECT_EQ(w.candidates[0].material, "wood");
  std::printf("warm lamp: similarity %.4f (other material %.4f)\n",
              w.candidates[0].similarity,
              w.candidates[1].similarity);
  // Measured 0.989 (the other material 0.903).
  EXPECT_GT(w.candidates[0].similarity, 0.97);
  EXPECT_GT(w.candidates[0].similarity - w.candidates[1].similarity, 0.05);
}

TEST(MaterialRecognizerTest, MovedRecognizerKeepsItsReferences) {
  MaterialRecognizer a;
  const std::string png = Encode(MakeTexture(7, cv::Scalar(10, 10, 250)));
  a.AddReference("m", png);
  MaterialRecognizer b(std::move(a));
  EXPECT_EQ(b.reference_count(), 1u);
  MaterialRecognizer c;
  c = std::move(b);
  EXPECT_EQ(c.Recognize(png).candidates.at(0).material, "m");
}

TEST(MaterialRecognizerTest, ConcurrentRecognizeAndAdd) {
  MaterialRecognizer recognizer;
  const std::string query = Encode(MakeTexture(8, cv::Scalar(90, 90, 200)));
  recognizer.AddReference("base", query);
  std::vector<std::thread> threads;
  for (int t = 0; t < 3; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 10; ++i) {
        const RecognitionResult r = recognizer.Recognize(query);
        EXPECT_FALSE(r.candidates.empty());
      }
    });
  }
  const std::vector<float> f = recognizer.ExtractFeatures(query);
  for (int i = 0; i < 20; ++i)
    recognizer.AddReferenceFeatures("m" + std::to_string(i), f);
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(recognizer.reference_count(), 21u);
}

}  // namespace
}  // namespace frictiond
