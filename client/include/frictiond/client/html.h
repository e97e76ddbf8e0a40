#pragma once
/// @file
/// Text helpers for the HTML/SVG reports the client tools write.

#include <string>

namespace frictiond {

/// `s` with <, >, & and " replaced by their character references, safe in
/// HTML text and in double-quoted attribute values.
std::string EscapeHtml(const std::string& s);

}  // namespace frictiond
