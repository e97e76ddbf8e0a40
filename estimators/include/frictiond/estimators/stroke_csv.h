#pragma once
/// @file
/// Parser for the contract's stroke CSV (CONTRACT.md, "Stroke data"). Parses
/// text that is already in memory: no file or network I/O happens here.

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

/// A rejected stroke CSV. what() reads like
/// "line 7: fn_n = -0.5 (must be > 0)"; line() is 1-based (0 when the error is
/// not tied to a line, e.g. an empty body) and field() names the column
/// ("body" or "header" for whole-input problems).
class StrokeCsvError : public FieldError {
 public:
  StrokeCsvError(std::size_t line,
                 std::string field,
                 const std::string& message,
                 bool too_large = false);
  std::size_t line() const { return line_; }
  /// True when the input broke a size limit (StrokeCsvOptions), not a rule.
  bool too_large() const { return too_large_; }

 private:
  std::size_t line_;
  bool too_large_ = false;
};

/// Limits applied while parsing.
struct StrokeCsvOptions {
  /// At most this many samples; more is rejected (protects the daemon).
  std::size_t max_samples = 5'000'000;
  /// At most this many columns.
  std::size_t max_columns = 64;
};

/// Parses a stroke CSV: one header row, one row per sample, comma separated,
/// lines starting with '#' (after optional spaces) and blank lines ignored,
/// CRLF accepted. Required columns: t_s, fn_n, ft_n, v_mm_s. Optional: slip
/// (0/1), stroke (integer). Every other column is a numeric covariate whose
/// name must match [A-Za-z_][A-Za-z0-9_]{0,63} and must not be reserved:
/// `intercept` (the model's constant term) and the derived feature names
/// (DerivedFeatureNames(): computed from the required columns).
///
/// Every cell must be a finite number. Rules checked per row: fn_n > 0,
/// ft_n >= 0, v_mm_s >= 0, t_s not decreasing, slip in {0,1}, stroke an
/// integer.
///
/// @throws StrokeCsvError naming the line, the column, the value and the rule.
StrokeData ParseStrokeCsv(std::string_view text,
                          const StrokeCsvOptions& options = {});

/// Writes samples back as a stroke CSV (header + rows), including slip,
/// stroke and covariates when present. Inverse of ParseStrokeCsv up to
/// number formatting (17 significant digits are kept, so values round-trip)
/// for data without derived features (AddDerivedFeatures), whose names
/// ParseStrokeCsv refuses.
std::string FormatStrokeCsv(const StrokeData& data);

}  // namespace frictiond
