#pragma once
/// @file
/// A heteroscedastic eps: the scale of eq. (1)'s error depending on one
/// input (a `spread` finding of diagnosis, issue 18), and the one rule for
/// columns computed from others (product columns "x*y" of interactions).
///
/// Scale model (log-linear in the input, clamped to the fitted range):
///
///     sigma_eps(x) = exp(c0 + c1 * clamp(x, x_min, x_max))
///     eps = ScaleFactor(x) * e,   ScaleFactor(x) = sigma_eps(x) / sigma_ref
///
/// where e has the constant-scale distribution (its empirical quantiles
/// are stored in units of sigma_ref). Departure from paper 000: the paper
/// takes eps independent of the inputs (section III-C); its own Fig. 6
/// shows the spread growing with Fn, which this model represents.
///
/// Fit (FitEpsScaleModel): least squares of log|r| on the clamped input,
/// then the level calibrated so that mean(r^2 / sigma_eps(x)^2) = 1 (the
/// slope of log|r| estimates the slope of log sigma for any symmetric
/// scale family; the calibration fixes the level the log bias shifts).
///
/// Usage:
/// @code
///   EpsScaleModel s;
///   if (FitEpsScaleModel(residuals, fn_values, "fn_n", &s))
///     double sd_at_3n = s.Sigma(3.0);
/// @endcode

#include <string>
#include <string_view>
#include <vector>

#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

/// Scale model of eps (a `spread` finding): sigma_eps(x) =
/// exp(log_sigma_intercept + log_sigma_slope * clamp(x, x_min, x_max)).
struct EpsScaleModel {
  std::string input;  ///< column or model input the scale depends on
  double log_sigma_intercept = 0.0;
  double log_sigma_slope = 0.0;     ///< per unit of input
  double x_min = 0.0, x_max = 0.0;  ///< range seen in the fit (clamped)
  double sigma_ref = 0.0;  ///< the constant-scale sigma_eps it replaces
  /// sigma_eps at input value x (x outside the fitted range is clamped).
  double Sigma(double x) const;
  /// Sigma(x) / sigma_ref: multiply a constant-scale sigma_eps by this
  /// (e.g. the grip force's eps scale at the grasp's input value); 1 when
  /// sigma_ref is not positive.
  double ScaleFactor(double x) const;
  /// True when every number is finite, x_min <= x_max, sigma_ref > 0 and
  /// input is a column name; otherwise *why names the field and the rule.
  bool IsValid(std::string* why) const;
};

/// Fits the scale model of residuals r on input values z (same length):
/// the clamp range is z's 1 % to 99 % quantiles, sigma_ref the RMS of r.
/// Returns false (out untouched) with fewer than 10 pairs, r all zero, no
/// span in z or a non-finite fit.
bool FitEpsScaleModel(const std::vector<double>& r,
                      const std::vector<double>& z,
                      const std::string& input,
                      EpsScaleModel* out);

/// The rule for computed columns (one place, used by the diagnosis, the
/// fits, the daemon's refit and the evaluations): a name "x*y" is the
/// product of columns x and y (an interaction term's input). True when
/// `name` has that form (exactly one '*', both sides non-empty); then *x
/// and *y (optional) receive the factors.
bool SplitProductName(std::string_view name,
                      std::string* x = nullptr,
                      std::string* y = nullptr);

/// True when data has column `name` or can compute it by the rule above
/// from columns it has.
bool CanComputeColumn(const StrokeData& data, std::string_view name);

/// Adds column `name` as a covariate when data lacks it and can compute it
/// (product of two columns, elementwise). Returns true when the column is
/// present afterwards.
bool AddComputedColumn(StrokeData* data, const std::string& name);

}  // namespace frictiond
