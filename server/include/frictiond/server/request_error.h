#pragma once
/// @file
/// Errors a caller made, and the validators of ids and numeric parameters
/// shared by the HTTP and LCM front ends. Free of Eigen and the HTTP library.

#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace frictiond {

/// Canonical error codes of the service core (after absl::StatusCode). The
/// service library speaks only these; each transport maps them in one place:
/// HTTP in HttpStatusFor, LCM in the `error_v1` reason and
/// the audit entry (StatusCodeName).
enum class StatusCode {
  kInvalidArgument,     ///< the input is wrong (HTTP 400)
  kUnauthenticated,     ///< no or bad credentials (401)
  kPermissionDenied,    ///< the caller may not do this (403)
  kNotFound,            ///< no such material, model, version, ... (404)
  kAlreadyExists,       ///< conflicts with the current state (409)
  kResourceExhausted,   ///< too large: samples, bytes, caps (413)
  kFailedPrecondition,  ///< valid, but the data cannot serve it (422)
  kUnavailable,         ///< the store is unreachable; retry later (503)
  kUnimplemented,       ///< this build lacks the feature (501)
  kInternal,            ///< a bug (500)
};

/// "invalid_argument", "not_found", ... (stable, for logs and LCM).
const char* StatusCodeName(StatusCode code);

/// The HTTP status of a canonical code: kInvalidArgument 400,
/// kUnauthenticated 401, kPermissionDenied 403, kNotFound 404,
/// kAlreadyExists 409, kResourceExhausted 413, kFailedPrecondition 422,
/// kInternal 500, kUnimplemented 501, kUnavailable 503.
/// The audit log records this number for every transport.
int HttpStatusFor(StatusCode code);

/// A request the caller got wrong, or one the service cannot serve: a
/// canonical `code`, the offending input `field` and a message naming field,
/// value and rule. `extra` carries structured detail for the answer (e.g.
/// the identification request recorded with a 404).
class RequestError : public std::invalid_argument {
 public:
  RequestError(StatusCode code,
               std::string field,
               const std::string& message,
               nlohmann::json extra = nullptr)
      : std::invalid_argument(message),
        code_(code),
        field_(std::move(field)),
        extra_(std::move(extra)) {}
  StatusCode code() const { return code_; }
  const std::string& field() const { return field_; }
  const nlohmann::json& extra() const { return extra_; }

 private:
  StatusCode code_;
  std::string field_;
  nlohmann::json extra_;
};

/// True when `id` matches [A-Za-z0-9._-]{1,64} and is not "." or "..".
bool IsValidId(const std::string& id);
/// @throws RequestError(StatusCode::kInvalidArgument) naming `field` when the
/// id is invalid.
void CheckId(const std::string& id, const std::string& field);

/// Parses a finite number from a query parameter.
/// @throws RequestError(StatusCode::kInvalidArgument) naming the parameter.
double ParseNumberParam(const std::string& name, const std::string& value);

/// Parses the `version` query parameter: a model version, an integer in
/// [1, 1e9). @throws RequestError(StatusCode::kInvalidArgument) naming
/// "version".
int ParseVersionParam(const std::string& value);

/// A validator's rejection as a request error (kInvalidArgument): the one
/// place an error from estimators/ or proto/ crosses to a transport. The
/// field is the FieldError's (field_error.h), else `fallback_field` (a
/// plain std::invalid_argument names no field, and its message is never
/// parsed for one). `prefix` ("logs[1].") goes before field and message
/// when the validated value was nested in the request.
RequestError InvalidArgumentFrom(const std::invalid_argument& e,
                                 const std::string& fallback_field,
                                 const std::string& prefix = "");

/// Parses a request body as JSON (ParseJson: nesting bounded).
/// @throws RequestError(StatusCode::kInvalidArgument) naming "body", with
/// ParseJson's reason.
nlohmann::json ParseJsonBody(const std::string& body);

}  // namespace frictiond
