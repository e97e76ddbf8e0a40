#pragma once
/// @file
/// Test helpers: a reader for GIMP pattern files (.pat) and synthetic views
/// (crop, rotation, scale, brightness) of a tiled texture.
///
/// GIMP pattern format (version 1), all integers 32-bit big-endian:
///   header_size, version (1), width, height, bytes_per_pixel (1-4),
///   magic "GPAT", UTF-8 name (NUL-terminated, up to header_size), then
///   width * height * bytes_per_pixel bytes of pixels, row-major, in
///   grey / grey+alpha / RGB / RGBA order.

#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace frictiond {
namespace testing_recognition {

/// Reads a .pat file into an 8-bit BGR image (alpha dropped, grey
/// replicated). Throws std::runtime_error on a malformed file.
inline cv::Mat ReadGimpPattern(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> data((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  auto be32 = [&](std::size_t at) {
    return (std::uint32_t{data[at]} << 24) |
           (std::uint32_t{data[at + 1]} << 16) |
           (std::uint32_t{data[at + 2]} << 8) | std::uint32_t{data[at + 3]};
  };
  if (data.size() < 24 ||
      std::string(data.begin() + 20, data.begin() + 24) != "GPAT") {
    throw std::runtime_error(path + ": not a GIMP pattern (no GPAT magic)");
  }
  const std::uint32_t header_size = be32(0);
  const int width = static_cast<int>(be32(8));
  const int height = static_cast<int>(be32(12));
  const int bytes = static_cast<int>(be32(16));
  if (bytes < 1 || bytes > 4 || width <= 0 || height <= 0 ||
      data.size() < header_size + std::size_t(width) * height * bytes) {
    throw std::runtime_error(path + ": truncated or unsupported pattern");
  }
  const cv::Mat raw(height,
                    width,
                    CV_8UC(bytes),
                    const_cast<unsigned char*>(data.data() + header_size));
  static const int kToBgr[] = {
      cv::COLOR_GRAY2BGR, -1, cv::COLOR_RGB2BGR, cv::COLOR_RGBA2BGR};
  cv::Mat bgr;
  if (bytes == 2) {
    cv::Mat grey;
    cv::extractChannel(raw, grey, 0);
    cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  } else {
    cv::cvtColor(raw, bgr, kToBgr[bytes - 1]);
  }
  return bgr;  // cvtColor copied the pixels out of `data`
}

/// Transformation of one synthetic view.
struct ViewParams {
  double angle_deg = 0.0;  ///< rotation, counter-clockwise
  double scale = 1.0;      ///< > 1 magnifies the texture
  double gain = 1.0;       ///< brightness multiplier (saturating)
  int out_side = 256;      ///< output is out_side x out_side
};

/// Tiles `pattern` to cover any view, then renders a view centred at a
/// random position: rotate by angle, magnify by scale, multiply by gain.
inline cv::Mat RenderView(const cv::Mat& pattern,
                          const ViewParams& p,
                          std::mt19937& rng) {
  // Source radius needed: the output half-diagonal divided by the scale.
  const double radius = p.out_side * std::sqrt(0.5) / p.scale + 4;
  const int need = static_cast<int>(2 * radius) + 2;
  const int reps_x = need / pattern.cols + 3;
  const int reps_y = need / pattern.rows + 3;
  cv::Mat tiled;
  cv::repeat(pattern, reps_y, reps_x, tiled);
  // Random centre such that the source disc stays inside the tiling.
  std::uniform_real_distribution<double> ux(radius + 1,
                                            tiled.cols - radius - 1);
  std::uniform_real_distribution<double> uy(radius + 1,
                                            tiled.rows - radius - 1);
  const cv::Point2f centre(static_cast<float>(ux(rng)),
                           static_cast<float>(uy(rng)));
  cv::Mat m = cv::getRotationMatrix2D(centre, p.angle_deg, p.scale);
  // Move the centre to the middle of the output.
  m.at<double>(0, 2) += p.out_side / 2.0 - centre.x;
  m.at<double>(1, 2) += p.out_side / 2.0 - centre.y;
  cv::Mat view;
  cv::warpAffine(tiled,
                 view,
                 m,
                 cv::Size(p.out_side, p.out_side),
                 cv::INTER_LINEAR,
                 cv::BORDER_REFLECT);
  if (p.gain != 1.0) view.convertTo(view, -1, p.gain, 0.0);
  return view;
}

/// PNG (or JPEG with quality) bytes of an image.
inline std::string Encode(const cv::Mat& image,
                          const std::string& ext = ".png",
                          int jpeg_quality = 90) {
  std::vector<unsigned char> buf;
  std::vector<int> params;
  if (ext == ".jpg") params = {cv::IMWRITE_JPEG_QUALITY, jpeg_quality};
  if (!cv::imencode(ext, image, buf, params)) {
    throw std::runtime_error("imencode failed");
  }
  return std::string(buf.begin(), buf.end());
}

}  // namespace testing_recognition
}  // namespace frictiond
