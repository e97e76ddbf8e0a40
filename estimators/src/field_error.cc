#include "frictiond/estimators/field_error.h"

#include <utility>

namespace frictiond {

FieldError::FieldError(std::string field, const std::string& message)
    : std::invalid_argument(message), field_(std::move(field)) {}

FieldError FieldError::Prefixed(const std::string& prefix) const {
  return FieldError(prefix + field_, prefix + what());
}

}  // namespace frictiond
