#pragma once
/// @file
/// The one error type for an input value that breaks a rule, carrying the
/// name of the field it came from. Validators in estimators/ and proto/
/// throw it, so a transport reports the field without reading the message
/// (request_error.h maps it to a canonical code). It is a
/// std::invalid_argument: code that catches that keeps working.
///
/// Field names are the input's own, outermost first, dotted and indexed the
/// way a client would write the path: "surface.alt_um", "entries[3].position",
/// "joints[1].friction.load_n". A parser that reads a nested value prefixes
/// the field (Prefixed), so the name a client sees is the full path.
///
/// @code
///   try {
///     ValidateSurface(surface);
///   } catch (const FieldError& e) {
///     // e.field() == "alt_um", e.what() == "alt_um = nan (must be finite)"
///   }
/// @endcode

#include <stdexcept>
#include <string>

namespace frictiond {

class FieldError : public std::invalid_argument {
 public:
  /// `message` is the whole text a user reads (it usually begins with the
  /// field); `field` may be empty when no single field is at fault.
  FieldError(std::string field, const std::string& message);

  /// The error "`field`: `why`", e.g. Because("entries", "must be an array")
  /// reads "entries: must be an array". For rules that state a value use
  /// the constructor: "kt = -1 (must be > 0)".
  static FieldError Because(const std::string& field, const std::string& why);
  const std::string& field() const noexcept { return field_; }

  /// The same error one level further out: `prefix` ("surface.",
  /// "logs[1].") is put before both the field and the message.
  FieldError Prefixed(const std::string& prefix) const;

 private:
  std::string field_;
};

}  // namespace frictiond
