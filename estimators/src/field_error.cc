#include "frictiond/estimators/field_error.h"

#include <utility>

namespace frictiond {

FieldError::FieldError(std::string field, const std::string& message)
    : std::invalid_argument(message), field_(std::move(field)) {}

FieldError FieldError::Because(const std::string& field,
                               const std::string& why) {
  return FieldError(field, field + ": " + why);
}

FieldError FieldError::Prefixed(const std::string& prefix) const {
  return FieldError(prefix + field_, prefix + what());
}

}  // namespace frictiond
