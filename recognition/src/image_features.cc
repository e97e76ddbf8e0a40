#include "image_features.h"

#include <algorithm>
#include <bitset>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "frictiond/recognition/material_recognizer.h"

namespace frictiond {
namespace internal {
namespace {

/// Shorter side of the working image [px]. Every image is resized to it, so
/// the same view photographed at another resolution gives the same features.
constexpr int kWorkingSide = 128;
/// The longer side is capped at this multiple of kWorkingSide.
constexpr int kMaxAspect = 2;

constexpr int kHueBins = 12;
constexpr int kSaturationBins = 3;
/// Pixels below this saturation (0-255) or value have no reliable hue; they
/// go to a single "grey" bin.
constexpr int kMinSaturation = 26;
constexpr int kMinValue = 20;

constexpr int kLbpSamples = 8;
constexpr int kLbpBins = kLbpSamples + 2;  // riu2: 0..P uniform, P+1 other
/// A neighbour counts as brighter when g_p >= g_c + kLbpTau, in units where
/// the image median is 128 (so the tolerance scales with brightness).
constexpr float kLbpTau = 1.0f;

/// Grey levels at or above this (0-255) are treated as clipped by the
/// sensor: their texture is lost, so they are left out of the LBP and
/// intensity histograms (a brighter exposure then changes the histograms
/// less).
constexpr float kClipGrey = 250.0f;

constexpr int kIntensityBins = 16;
/// Relative intensity g / median(g) is histogrammed over [0, kMaxRelative).
constexpr float kMaxRelative = 2.5f;

[[noreturn]] void ThrowImage(const std::string& what) {
  throw std::invalid_argument("image: " + what);
}

std::uint32_t ReadBigEndian32(std::string_view b, std::size_t at) {
  return (std::uint32_t{static_cast<unsigned char>(b[at])} << 24) |
         (std::uint32_t{static_cast<unsigned char>(b[at + 1])} << 16) |
         (std::uint32_t{static_cast<unsigned char>(b[at + 2])} << 8) |
         std::uint32_t{static_cast<unsigned char>(b[at + 3])};
}

int ReadBigEndian16(std::string_view b, std::size_t at) {
  return (static_cast<unsigned char>(b[at]) << 8) |
         static_cast<unsigned char>(b[at + 1]);
}

unsigned char Byte(std::string_view b, std::size_t at) {
  return static_cast<unsigned char>(b[at]);
}

ImageHeader ReadPngHeader(std::string_view b) {
  // Signature (8), IHDR length (4), "IHDR" (4), width (4), height (4).
  if (b.size() < 24) {
    ThrowImage("cannot decode: PNG truncated before its header (" +
               std::to_string(b.size()) + " bytes)");
  }
  if (b.substr(12, 4) != "IHDR") {
    ThrowImage("cannot decode: PNG without an IHDR header chunk");
  }
  const std::uint32_t width = ReadBigEndian32(b, 16);
  const std::uint32_t height = ReadBigEndian32(b, 20);
  if (width == 0 || height == 0 || width > (1u << 30) || height > (1u << 30)) {
    ThrowImage("cannot decode: PNG header gives an invalid size " +
               std::to_string(width) + "x" + std::to_string(height));
  }
  // A complete file ends with the IEND chunk; only padding may follow it.
  const std::string_view tail =
      b.substr(b.size() > 4096 ? b.size() - 4096 : 24);
  if (tail.find("IEND") == std::string_view::npos) {
    ThrowImage("cannot decode: PNG truncated (no IEND end chunk)");
  }
  return {ImageHeader::Format::kPng,
          static_cast<int>(width),
          static_cast<int>(height)};
}

bool IsStartOfFrame(unsigned char marker) {
  return marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 &&
         marker != 0xCC;
}

ImageHeader ReadJpegHeader(std::string_view b) {
  std::size_t at = 2;  // after SOI (FF D8)
  while (true) {
    // Markers are FF xx, possibly preceded by FF fill bytes.
    if (at >= b.size() || Byte(b, at) != 0xFF) {
      ThrowImage(
          "cannot decode: JPEG truncated or corrupt before its frame "
          "header");
    }
    while (at < b.size() && Byte(b, at) == 0xFF) ++at;
    if (at >= b.size()) {
      ThrowImage("cannot decode: JPEG truncated before its frame header");
    }
    const unsigned char marker = Byte(b, at);
    ++at;
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) continue;
    if (marker == 0xD9 || marker == 0xDA) {
      ThrowImage("cannot decode: JPEG without a frame header");
    }
    if (at + 2 > b.size()) {
      ThrowImage("cannot decode: JPEG truncated before its frame header");
    }
    const int length = ReadBigEndian16(b, at);
    if (length < 2) ThrowImage("cannot decode: JPEG segment length < 2");
    if (IsStartOfFrame(marker)) {
      // length (2), precision (1), height (2), width (2).
      if (at + 7 > b.size()) {
        ThrowImage("cannot decode: JPEG truncated in its frame header");
      }
      const int height = ReadBigEndian16(b, at + 3);
      const int width = ReadBigEndian16(b, at + 5);
      if (width == 0 || height == 0) {
        ThrowImage("cannot decode: JPEG frame header gives an invalid size " +
                   std::to_string(width) + "x" + std::to_string(height));
      }
      // A complete file ends with EOI (FF D9) after the frame; only padding
      // may follow it. Search the tail (after the frame header, so that an
      // EXIF thumbnail's EOI does not count).
      const std::size_t tail_start =
          std::max(at, b.size() > 4096 ? b.size() - 4096 : std::size_t{0});
      const std::string_view tail = b.substr(tail_start);
      if (tail.find("\xFF\xD9") == std::string_view::npos) {
        ThrowImage("cannot decode: JPEG truncated (no end-of-image marker)");
      }
      return {ImageHeader::Format::kJpeg, width, height};
    }
    at += static_cast<std::size_t>(length);
  }
}

bool IsEmpty(const std::vector<double>& hist) {
  return std::all_of(
      hist.begin(), hist.end(), [](double h) { return h == 0.0; });
}

/// Median of an 8-bit single-channel image.
double CalcMedian(const cv::Mat& grey8) {
  int counts[256] = {};
  for (int y = 0; y < grey8.rows; ++y) {
    const unsigned char* row = grey8.ptr<unsigned char>(y);
    for (int x = 0; x < grey8.cols; ++x) ++counts[row[x]];
  }
  const long long half = static_cast<long long>(grey8.total()) / 2;
  long long seen = 0;
  for (int v = 0; v < 256; ++v) {
    seen += counts[v];
    if (seen > half) return v;
  }
  return 255;
}

/// Normalises `hist` to sum 1 and stores the square roots at `out`.
void StoreSqrtHistogram(const std::vector<double>& hist, float* out) {
  double total = 0.0;
  for (double h : hist) total += h;
  CV_Assert(total > 0.0);
  for (std::size_t i = 0; i < hist.size(); ++i) {
    out[i] = static_cast<float>(std::sqrt(hist[i] / total));
  }
}

/// Hue-saturation histogram with linear interpolation between hue bins
/// (circular) and one extra bin for unsaturated or dark pixels.
std::vector<double> CalcHueSaturationHistogram(const cv::Mat& bgr) {
  cv::Mat hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);  // H in [0, 180)
  std::vector<double> hist(kHueBins * kSaturationBins + 1, 0.0);
  const double hue_scale = kHueBins / 180.0;
  const double sat_scale =
      kSaturationBins / static_cast<double>(256 - kMinSaturation);
  for (int y = 0; y < hsv.rows; ++y) {
    const cv::Vec3b* row = hsv.ptr<cv::Vec3b>(y);
    for (int x = 0; x < hsv.cols; ++x) {
      const int h = row[x][0];
      const int s = row[x][1];
      const int v = row[x][2];
      if (s < kMinSaturation || v < kMinValue) {
        hist.back() += 1.0;
        continue;
      }
      const int sat_bin =
          std::min(kSaturationBins - 1,
                   static_cast<int>((s - kMinSaturation) * sat_scale));
      const double position = h * hue_scale - 0.5;
      const double lower = std::floor(position);
      const double frac = position - lower;
      const int b0 = (static_cast<int>(lower) + kHueBins) % kHueBins;
      const int b1 = (b0 + 1) % kHueBins;
      hist[sat_bin * kHueBins + b0] += 1.0 - frac;
      hist[sat_bin * kHueBins + b1] += frac;
    }
  }
  return hist;
}

/// Histogram of g / median(g) (g is already normalised to median 128), linear
/// interpolation between bins.
std::vector<double> CalcRelativeIntensityHistogram(const cv::Mat1f& grey,
                                                   float clip_level) {
  std::vector<double> hist(kIntensityBins, 0.0);
  const float scale = kIntensityBins / (kMaxRelative * 128.0f);
  for (int y = 0; y < grey.rows; ++y) {
    const float* row = grey[y];
    for (int x = 0; x < grey.cols; ++x) {
      if (row[x] >= clip_level) continue;
      const float position =
          std::min(row[x] * scale - 0.5f, kIntensityBins - 1.0f);
      if (position <= 0.0f) {
        hist[0] += 1.0;
        continue;
      }
      const int b0 = static_cast<int>(position);
      const float frac = position - b0;
      hist[b0] += 1.0 - frac;
      if (b0 + 1 < kIntensityBins) hist[b0 + 1] += frac;
    }
  }
  if (IsEmpty(hist)) hist.back() = 1.0;  // all clipped: bright
  return hist;
}

/// Rotation-invariant uniform LBP (Ojala et al. 2002, LBP^riu2_{P,R}) with
/// bilinear interpolation of the circular samples: code = number of brighter
/// neighbours when the circular bit pattern has at most two 0/1 transitions,
/// P + 1 otherwise.
std::vector<double> CalcLbpHistogram(const cv::Mat1f& grey,
                                     double radius,
                                     float clip_level) {
  std::vector<double> hist(kLbpBins, 0.0);
  struct Sample {
    int dx0, dy0;
    float w00, w01, w10, w11;
  };
  Sample samples[kLbpSamples];
  for (int p = 0; p < kLbpSamples; ++p) {
    const double angle = 2.0 * CV_PI * p / kLbpSamples;
    const double sx = radius * std::cos(angle);
    const double sy = -radius * std::sin(angle);
    // Snap values within 1e-6 of an integer (avoids 0.9999 weights).
    const double fx = std::floor(sx + 1e-6);
    const double fy = std::floor(sy + 1e-6);
    const float tx = static_cast<float>(std::max(0.0, sx - fx));
    const float ty = static_cast<float>(std::max(0.0, sy - fy));
    samples[p] = {static_cast<int>(fx),
                  static_cast<int>(fy),
                  (1 - tx) * (1 - ty),
                  tx * (1 - ty),
                  (1 - tx) * ty,
                  tx * ty};
  }
  const int margin = static_cast<int>(std::ceil(radius)) + 1;
  for (int y = margin; y < grey.rows - margin; ++y) {
    for (int x = margin; x < grey.cols - margin; ++x) {
      if (grey(y, x) >= clip_level) continue;
      const float centre = grey(y, x) + kLbpTau;
      unsigned bits = 0;
      for (int p = 0; p < kLbpSamples; ++p) {
        const Sample& s = samples[p];
        const float* r0 = grey[y + s.dy0] + x + s.dx0;
        const float* r1 = grey[y + s.dy0 + 1] + x + s.dx0;
        const float value =
            s.w00 * r0[0] + s.w01 * r0[1] + s.w10 * r1[0] + s.w11 * r1[1];
        if (value >= centre) bits |= 1u << p;
      }
      const unsigned rotated =
          ((bits >> 1) | (bits << (kLbpSamples - 1))) & 0xFFu;
      const int transitions =
          static_cast<int>(std::bitset<kLbpSamples>(bits ^ rotated).count());
      const int code =
          transitions <= 2
              ? static_cast<int>(std::bitset<kLbpSamples>(bits).count())
              : kLbpSamples + 1;
      hist[code] += 1.0;
    }
  }
  if (IsEmpty(hist)) hist[0] = 1.0;  // all clipped: flat
  return hist;
}

struct LbpScale {
  int level;  ///< 0 = working image, 1 = half resolution
  double radius;
};
constexpr LbpScale kLbpScales[] = {
    {0, 1.0}, {0, 2.0}, {0, 3.0}, {1, 1.0}, {1, 2.0}};

}  // namespace

ImageHeader ReadImageHeader(std::string_view bytes) {
  if (bytes.empty())
    ThrowImage("cannot decode: empty body (expected PNG or JPEG)");
  static constexpr std::string_view kPngSignature("\x89PNG\r\n\x1a\n", 8);
  if (bytes.size() >= 8 && bytes.substr(0, 8) == kPngSignature) {
    return ReadPngHeader(bytes);
  }
  if (bytes.size() >= 3 && Byte(bytes, 0) == 0xFF && Byte(bytes, 1) == 0xD8 &&
      Byte(bytes, 2) == 0xFF) {
    return ReadJpegHeader(bytes);
  }
  ThrowImage("cannot decode: not a PNG or JPEG (" +
             std::to_string(bytes.size()) +
             " bytes with an unknown signature)");
}

cv::Mat DecodeImage(std::string_view bytes,
                    int min_side,
                    long long max_pixels) {
  const ImageHeader header = ReadImageHeader(bytes);
  const std::string size =
      std::to_string(header.width) + "x" + std::to_string(header.height);
  if (header.width < min_side || header.height < min_side) {
    ThrowImage(size + " pixels is too small (each side must be >= " +
               std::to_string(min_side) + ")");
  }
  const long long pixels = static_cast<long long>(header.width) * header.height;
  if (pixels > max_pixels) {
    char text[160];
    std::snprintf(text,
                  sizeof(text),
                  " pixels = %.1f megapixels is too large (must be <= %.1f)",
                  pixels / 1e6,
                  max_pixels / 1e6);
    ThrowImage(size + text);
  }
  int flags = cv::IMREAD_COLOR;
  if (header.format == ImageHeader::Format::kJpeg) {
    // DCT scaling in libjpeg: decode directly at 1/2 or 1/4 size while the
    // shorter side stays >= 1.5 working sides.
    const int shorter = std::min(header.width, header.height);
    const int needed = kWorkingSide * 3 / 2;
    if (shorter / 4 >= needed) {
      flags = cv::IMREAD_REDUCED_COLOR_4;
    } else if (shorter / 2 >= needed) {
      flags = cv::IMREAD_REDUCED_COLOR_2;
    }
  }
  const cv::Mat buffer(1,
                       static_cast<int>(bytes.size()),
                       CV_8UC1,
                       const_cast<char*>(bytes.data()));
  cv::Mat image;
  try {
    image = cv::imdecode(buffer, flags);
  } catch (const cv::Exception& e) {
    ThrowImage(std::string("cannot decode: ") + e.what());
  }
  if (image.empty() || image.type() != CV_8UC3) {
    ThrowImage(std::string("cannot decode: corrupt or truncated ") +
               (header.format == ImageHeader::Format::kPng ? "PNG" : "JPEG") +
               " data");
  }
  return image;
}

const std::vector<FeatureBlock>& FeatureLayout() {
  static const std::vector<FeatureBlock> layout = {
      {"hue_saturation", kHueBins * kSaturationBins + 1, 0.30},
      {"lbp_l0_r1", kLbpBins, 0.11},
      {"lbp_l0_r2", kLbpBins, 0.11},
      {"lbp_l0_r3", kLbpBins, 0.11},
      {"lbp_l1_r1", kLbpBins, 0.11},
      {"lbp_l1_r2", kLbpBins, 0.11},
      {"relative_intensity", kIntensityBins, 0.15},
  };
  return layout;
}

std::size_t FeatureSize() {
  std::size_t n = 0;
  for (const FeatureBlock& b : FeatureLayout()) n += b.size;
  return n;
}

std::vector<float> ComputeFeatures(const cv::Mat& bgr) {
  CV_Assert(bgr.type() == CV_8UC3 && !bgr.empty());
  // 1. Working size: shorter side kWorkingSide, longer side capped.
  const double scale =
      std::min(kWorkingSide / static_cast<double>(std::min(bgr.cols, bgr.rows)),
               kMaxAspect * kWorkingSide /
                   static_cast<double>(std::max(bgr.cols, bgr.rows)));
  const cv::Size size(
      std::max(1, static_cast<int>(std::lround(bgr.cols * scale))),
      std::max(1, static_cast<int>(std::lround(bgr.rows * scale))));
  cv::Mat work;
  cv::resize(
      bgr, work, size, 0, 0, scale < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);

  std::vector<float> features(FeatureSize());
  float* out = features.data();
  const std::vector<FeatureBlock>& layout = FeatureLayout();
  std::size_t block = 0;
  auto store = [&](const std::vector<double>& hist) {
    CV_Assert(static_cast<int>(hist.size()) == layout[block].size);
    StoreSqrtHistogram(hist, out);
    out += layout[block].size;
    ++block;
  };

  // 2. Colour.
  store(CalcHueSaturationHistogram(work));

  // 3. Grey, normalised to median 128 (multiplicative brightness removed).
  cv::Mat grey8;
  cv::cvtColor(work, grey8, cv::COLOR_BGR2GRAY);
  cv::Mat1f grey;
  grey8.convertTo(grey, CV_32F);
  const double median = std::max(1.0, CalcMedian(grey8));
  const float gain = static_cast<float>(128.0 / median);
  grey *= gain;
  const float clip_level = kClipGrey * gain;
  cv::Mat1f half;
  cv::resize(grey, half, cv::Size(), 0.5, 0.5, cv::INTER_AREA);

  // 4. Texture.
  for (const LbpScale& s : kLbpScales) {
    store(CalcLbpHistogram(s.level == 0 ? grey : half, s.radius, clip_level));
  }

  // 5. Contrast shape.
  store(CalcRelativeIntensityHistogram(grey, clip_level));
  CV_Assert(block == layout.size());
  return features;
}

void CheckFeatures(const std::vector<float>& features) {
  if (features.size() != FeatureSize()) {
    throw std::invalid_argument(
        "features: size = " + std::to_string(features.size()) + " (must be " +
        std::to_string(FeatureSize()) + ", feature version " +
        std::to_string(MaterialRecognizer::kFeatureVersion) + ")");
  }
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (!(features[i] >= 0.0f) || !std::isfinite(features[i])) {
      throw std::invalid_argument("features: value [" + std::to_string(i) +
                                  "] = " + std::to_string(features[i]) +
                                  " (must be finite and >= 0)");
    }
  }
  std::size_t at = 0;
  for (const FeatureBlock& b : FeatureLayout()) {
    double norm2 = 0.0;
    for (int i = 0; i < b.size; ++i)
      norm2 += double{features[at + i]} * features[at + i];
    if (!(std::abs(norm2 - 1.0) <= 1e-3)) {
      throw std::invalid_argument(
          std::string("features: block ") + b.name + " has squared norm " +
          std::to_string(norm2) +
          " (must be 1; use vectors returned by ExtractFeatures)");
    }
    at += b.size;
  }
}

double CalcSimilarity(const float* a, const float* b) {
  double score = 1.0;
  for (const FeatureBlock& block : FeatureLayout()) {
    // H^2 = 1 - BC = sum (a_i - b_i)^2 / 2 for unit-norm sqrt histograms;
    // the difference form is exact (0) for identical vectors.
    double sum2 = 0.0;
    for (int i = 0; i < block.size; ++i) {
      const double d = double{a[i]} - double{b[i]};
      sum2 += d * d;
    }
    const double hellinger = std::sqrt(std::min(1.0, 0.5 * sum2));
    score -= block.weight * hellinger;
    a += block.size;
    b += block.size;
  }
  return std::clamp(score, 0.0, 1.0);
}

}  // namespace internal
}  // namespace frictiond
