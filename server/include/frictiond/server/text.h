#pragma once
/// @file
/// The one rule for text that arrives from outside and is stored or echoed
/// (ids, names, requesters, tags, column names, query and header values,
/// values quoted in error messages): valid UTF-8 of bounded length, without
/// control characters. Every route and the HTTP server itself use these
/// helpers (docs/security.md "Text").

#include <cstddef>
#include <string>
#include <string_view>

namespace frictiond {

/// Bounds on outside text [bytes].
inline constexpr std::size_t kMaxQueryValueBytes = 1024;
inline constexpr std::size_t kMaxHeaderValueBytes = 4096;
inline constexpr std::size_t kMaxPathSegmentBytes = 256;
/// Names, tags, requesters, column names stored in the library.
inline constexpr std::size_t kMaxNameBytes = 256;

/// True when `text` is well-formed UTF-8 (RFC 3629: no overlong forms, no
/// surrogates, nothing above U+10FFFF).
bool IsValidUtf8(std::string_view text);

/// Checks stored or echoed text: valid UTF-8, at most `max_bytes` bytes,
/// no control characters (below U+0020 except tab, and U+007F).
/// @throws RequestError(StatusCode::kInvalidArgument) naming `field`, the byte
/// offset and the rule; the message never quotes the offending bytes.
void CheckText(std::string_view text,
               const std::string& field,
               std::size_t max_bytes = kMaxNameBytes);

/// Checks stored free text (descriptions): as CheckText, but line breaks
/// (\n, \r) are allowed as well as tab.
/// @throws RequestError(StatusCode::kInvalidArgument) naming `field`.
void CheckFreeText(std::string_view text,
                   const std::string& field,
                   std::size_t max_bytes);

/// A printable excerpt of outside text for messages and logs: at most
/// `max_chars` characters, invalid bytes and control characters shown as
/// '?', "..." appended when cut. Always valid UTF-8.
std::string ShownText(std::string_view text, std::size_t max_chars = 40);

}  // namespace frictiond
