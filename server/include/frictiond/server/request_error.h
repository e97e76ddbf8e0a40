#pragma once
/// @file
/// Errors a caller made, and the validators of ids and numeric parameters
/// shared by the HTTP and LCM front ends. Free of Eigen and the HTTP library.

#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace frictiond {

/// A request the caller got wrong. `status` is the HTTP status to answer
/// (400 bad input, 404 not found, 413 too large, 415 media type, 422 valid
/// but unusable); `field` names the offending input.
class RequestError : public std::invalid_argument {
 public:
  RequestError(int status,
               std::string field,
               const std::string& message,
               nlohmann::json extra = nullptr)
      : std::invalid_argument(message),
        status_(status),
        field_(std::move(field)),
        extra_(std::move(extra)) {}
  int status() const { return status_; }
  const std::string& field() const { return field_; }
  const nlohmann::json& extra() const { return extra_; }

 private:
  int status_;
  std::string field_;
  nlohmann::json extra_;
};

/// True when `id` matches [A-Za-z0-9._-]{1,64} and is not "." or "..".
bool IsValidId(const std::string& id);
/// @throws RequestError(400) naming `field` when the id is invalid.
void CheckId(const std::string& id, const std::string& field);

/// Parses a finite number from a query parameter.
/// @throws RequestError(400) naming the parameter.
double ParseNumberParam(const std::string& name, const std::string& value);

/// Parses the `version` query parameter: a model version, an integer in
/// [1, 1e9). @throws RequestError(400) naming "version".
int ParseVersionParam(const std::string& value);

}  // namespace frictiond
