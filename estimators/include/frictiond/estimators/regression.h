#pragma once
/// @file
/// Ordinary least squares over named model terms, the engine behind
/// mu = b0 + b1*v + b2*Fn + eps (paper 000, eq. 1) and its extensions
/// (extra covariates, non-linear forms) found by diagnosis.

#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Dense>

#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

/// How a term transforms its input column x.
enum class TermKind {
  kIntercept,  ///< 1                       name "intercept"
  kLinear,     ///< x                       name "x"
  kPower,      ///< x^a                     name "x^a"      (e.g. "fn_n^2",
               ///< "fn_n^-0.333333")
  kLog,        ///< ln(x)                   name "log(x)"
  kSin,  ///< sin(x)                  name "sin(x)"   (x in degrees when its
         ///< name ends in _deg)
  kCos,  ///< cos(x)                  name "cos(x)"   (likewise)
  kExpDecay,  ///< exp(-x/a)               name "exp(-x/a)"
  kWindow,    ///< 1 if a <= x < b else 0  name "in(x,a,b)"
  // Added for model diagnosis (names are stable, like the ones above):
  kHinge,   ///< max(x - a, 0)           name "hinge(x,a)"   (piecewise-linear
            ///< form)
  kSinDeg,  ///< sin(x degrees)          name "sind(x)"      (angle in degrees,
            ///< any column name)
  kCosDeg,  ///< cos(x degrees)          name "cosd(x)"
  kOnsetDecay,  ///< x^b exp(-s/a)           name "onset(x,a)" for b = 1,
                ///< "onset(x,a,b)" otherwise; s = time since the current slip
                ///< episode began [s] (see CalcTimeSinceSlipOnset), a = decay
                ///< time [s]. A slip-onset transient whose size scales with x^b
                ///< (e.g. "onset(dwell_s,0.15)"). Eval(x) gives its
                ///< steady-sliding value, 0.
};

/// One regressor of a linear model. Names are stable (they key the model's
/// coefficients in JSON), and Parse(Name()) gives the term back.
struct Term {
  TermKind kind = TermKind::kIntercept;
  std::string input;  ///< column the term reads ("" for the intercept); "x*y"
                      ///< names a product column the caller provides
  double a = 0.0;     ///< exponent, decay length or window start
  double b = 0.0;     ///< window end

  static Term Intercept() { return Term{}; }
  static Term Linear(std::string input) {
    return Term{TermKind::kLinear, std::move(input)};
  }
  /// Stable name, e.g. "v_mm_s", "fn_n^2", "cos(dir_deg)".
  std::string Name() const;
  /// Parses a name produced by Name().
  /// @throws std::invalid_argument naming the term and what is wrong.
  static Term Parse(std::string_view name);
  /// Value of the term for input value x. For kOnsetDecay this is the value
  /// in steady sliding (long after onset): 0; use the two-argument form.
  double Eval(double x) const;
  /// Value of the term for input value x at `since_onset_s` seconds after the
  /// current slip episode began (+inf outside slip). Only kOnsetDecay uses
  /// since_onset_s; the other kinds equal Eval(x).
  double Eval(double x, double since_onset_s) const;
  /// True for kinds whose value depends on the time since slip onset.
  bool NeedsSlipOnset() const { return kind == TermKind::kOnsetDecay; }
  bool operator==(const Term& o) const {
    return kind == o.kind && input == o.input && a == o.a && b == o.b;
  }
};

/// Status of a least-squares fit.
enum class FitStatus {
  kOk,       ///< fitted; every term identified
  kPartial,  ///< fitted, but some terms were not identified (coefficient fixed
             ///< at 0)
  kTooFewSamples,  ///< fewer samples than terms + 2
  kFailed,         ///< numerical failure (see why)
};
const char* ToString(FitStatus s);

/// A fitted linear model y = X beta + eps.
struct OlsResult {
  FitStatus status = FitStatus::kFailed;
  std::string why;               ///< reason when status != kOk
  Eigen::VectorXd beta;          ///< coefficients (0 for unidentified terms)
  Eigen::VectorXd std_err;       ///< standard errors (0 for unidentified terms)
  Eigen::MatrixXd P_beta;        ///< coefficient covariance sigma^2 (X'X)^-1
  std::vector<bool> identified;  ///< per term
  Eigen::VectorXd residuals;     ///< y - X beta
  double sigma_eps = 0.0;        ///< residual std, dof corrected
  double r2 = 0.0;               ///< coefficient of determination
  double f_stat = 0.0;           ///< overall F statistic (Table I of paper 000)
  double p_value = 1.0;          ///< P(F > f_stat) under H0: all slopes 0
  int samples = 0;
  int dof = 0;  ///< n - identified terms
  /// With status kFailed for values that cannot be summed (not finite, or
  /// so large that their squares overflow): the first such column of X
  /// (0..p-1), or p for y; -1 otherwise. Lets a caller name the input.
  int nonfinite_column = -1;
};

/// What FitOls computes besides the coefficients and their statistics.
struct OlsOptions {
  /// Fill OlsResult::residuals (one more pass over X, and n doubles). When
  /// false, the residual sum of squares comes from the moments of the one
  /// pass (relative error ~1e-12 of the total sum of squares) and
  /// `residuals` stays empty.
  bool residuals = true;
  /// Use the AVX2+FMA moment kernels when the CPU has them (else SSE2).
  /// False forces the baseline kernels (tests; results agree to rounding).
  bool allow_avx2 = true;
};

/// True when FitOls with `options` runs the AVX2+FMA kernels here.
bool OlsUsesAvx2(const OlsOptions& options);

/// Least squares of y on the columns of X. Column 0 may be an intercept (a
/// column of ones); columns that are (numerically) constant or collinear with
/// earlier ones are not identified: their coefficient is fixed at 0 and the
/// status is kPartial. Solved through the normal equations of centred and
/// scaled columns with a pivoted QR rank check, so 1e6 x 3 takes one pass
/// (two with residuals).
OlsResult FitOls(const Eigen::Ref<const Eigen::MatrixXd>& X,
                 const Eigen::Ref<const Eigen::VectorXd>& y,
                 const OlsOptions& options = {});

/// Time since the current slip episode began, per sample [s]: 0 at the first
/// slip sample of an episode (a run of slip == 1 within one stroke), growing
/// during the episode; +inf for samples that are not slipping or when
/// data.slip is empty.
std::vector<double> CalcTimeSinceSlipOnset(const StrokeData& data);

/// Design matrix: one row per index in `rows`, one column per term, reading
/// inputs from `data` (required columns or covariates). Terms that need the
/// time since slip onset (kOnsetDecay) get it from CalcTimeSinceSlipOnset.
/// @throws std::invalid_argument when a term's input is not a column of data.
Eigen::MatrixXd BuildDesign(const StrokeData& data,
                            const std::vector<Term>& terms,
                            const std::vector<std::size_t>& rows);

}  // namespace frictiond
