#pragma once
/// @file
/// The one way outside JSON is parsed (HTTP bodies, LCM JSON texts, server
/// replies in the client, files given to the CLI, the daemon's config and
/// bundled data): nlohmann's parser is iterative, but copying, comparing or
/// serialising a document recurses once per nesting level, so a 100,000-deep
/// array parsed without a bound crashed the daemon's worker (an outside
/// attack run: one unauthenticated POST) and the CLI on such a reply. Every
/// document this project reads is at most a few levels deep.

#include <string_view>

#include <nlohmann/json.hpp>

#include "frictiond/estimators/field_error.h"

namespace frictiond {

/// Deepest nesting accepted from outside (objects and arrays).
inline constexpr int kMaxJsonDepth = 64;

/// Parses `text`, refusing nesting deeper than `max_depth`.
/// @throws FieldError "FIELD: invalid JSON: ..." or "FIELD:
/// nesting deeper than N" (FIELD = `field`).
nlohmann::json ParseJson(std::string_view text,
                         const char* field,
                         int max_depth = kMaxJsonDepth);

/// As ParseJson, but never throws: a discarded value (is_discarded()) for
/// invalid or too deeply nested text.
nlohmann::json ParseJsonOrDiscarded(std::string_view text,
                                    int max_depth = kMaxJsonDepth);

}  // namespace frictiond
