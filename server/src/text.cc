#include "frictiond/server/text.h"

#include "frictiond/server/request_error.h"

namespace frictiond {

namespace {

// Length of the well-formed UTF-8 sequence starting at text[i], or 0.
std::size_t Utf8SequenceLength(std::string_view text, std::size_t i) {
  const auto byte = [&](std::size_t k) {
    return static_cast<unsigned char>(text[k]);
  };
  const unsigned char c = byte(i);
  if (c < 0x80) return 1;
  std::size_t n;
  unsigned char lo = 0x80, hi = 0xBF;  // range of the second byte
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;  // overlong
    if (c == 0xED) hi = 0x9F;  // surrogates
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;  // overlong
    if (c == 0xF4) hi = 0x8F;  // above U+10FFFF
  } else {
    return 0;
  }
  if (i + n > text.size()) return 0;
  if (byte(i + 1) < lo || byte(i + 1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k)
    if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return 0;
  return n;
}

bool IsControl(unsigned char c) { return (c < 0x20 && c != '\t') || c == 0x7F; }

}  // namespace

bool IsValidUtf8(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t n = Utf8SequenceLength(text, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

namespace {

void CheckTextWith(std::string_view text,
                   const std::string& field,
                   std::size_t max_bytes,
                   bool line_breaks) {
  if (text.size() > max_bytes)
    throw RequestError(StatusCode::kInvalidArgument,
                       field,
                       field + ": " + std::to_string(text.size()) +
                           " bytes (must be at most " +
                           std::to_string(max_bytes) + ")");
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t n = Utf8SequenceLength(text, i);
    if (n == 0)
      throw RequestError(StatusCode::kInvalidArgument,
                         field,
                         field + ": invalid UTF-8 at byte " +
                             std::to_string(i) + " (must be valid UTF-8)");
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (n == 1 && IsControl(c) && !(line_breaks && (c == '\n' || c == '\r')))
      throw RequestError(StatusCode::kInvalidArgument,
                         field,
                         field + ": control character at byte " +
                             std::to_string(i) + " (must be printable text)");
    i += n;
  }
}

}  // namespace

void CheckText(std::string_view text,
               const std::string& field,
               std::size_t max_bytes) {
  CheckTextWith(text, field, max_bytes, /*line_breaks=*/false);
}

void CheckFreeText(std::string_view text,
                   const std::string& field,
                   std::size_t max_bytes) {
  CheckTextWith(text, field, max_bytes, /*line_breaks=*/true);
}

std::string ShownText(std::string_view text, std::size_t max_chars) {
  std::string out;
  std::size_t chars = 0;
  std::size_t i = 0;
  for (; i < text.size() && chars < max_chars; ++chars) {
    const std::size_t n = Utf8SequenceLength(text, i);
    if (n == 0 || (n == 1 && IsControl(static_cast<unsigned char>(text[i])))) {
      out += '?';
      i += 1;
    } else {
      out.append(text.substr(i, n));
      i += n;
    }
  }
  if (i < text.size()) out += "...";
  return out;
}

}  // namespace frictiond
