#include "frictiond/proto/json_parse.h"

#include <stdexcept>
#include <string>

#include "frictiond/estimators/field_error.h"

namespace frictiond {

namespace {

// Thrown by the depth callback; caught below.
struct TooDeep {};

nlohmann::json ParseWithDepth(std::string_view text, int max_depth) {
  const nlohmann::json::parser_callback_t limit =
      [max_depth](
          int depth, nlohmann::json::parse_event_t event, nlohmann::json&) {
        // The outermost object or array starts at depth 0.
        const bool opens =
            event == nlohmann::json::parse_event_t::object_start ||
            event == nlohmann::json::parse_event_t::array_start;
        if (opens && depth >= max_depth) throw TooDeep{};
        return true;
      };
  return nlohmann::json::parse(text.begin(), text.end(), limit);
}

}  // namespace

nlohmann::json ParseJson(std::string_view text,
                         const char* field,
                         int max_depth) {
  try {
    return ParseWithDepth(text, max_depth);
  } catch (const TooDeep&) {
    throw FieldError(field,
                     std::string(field) + ": nesting deeper than " +
                         std::to_string(max_depth));
  } catch (const nlohmann::json::exception& e) {
    throw FieldError(field, std::string(field) + ": invalid JSON: " + e.what());
  }
}

nlohmann::json ParseJsonOrDiscarded(std::string_view text, int max_depth) {
  try {
    return ParseWithDepth(text, max_depth);
  } catch (...) {
    return nlohmann::json(nlohmann::json::value_t::discarded);
  }
}

}  // namespace frictiond
