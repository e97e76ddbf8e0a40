#pragma once
/// @file
/// Alternative functional forms of mu = f(Fn) (paper 000, Table II and
/// section I), fitted to slipping samples and compared by held-out error:
///
///   linear       mu = a*Fn + b            (Table II; eq. 1 without v)
///   reciprocal   mu = 1/(a*Fn + b)        (Table II), least squares in mu
///   inverse_cube mu = a/Fn^3 + b          (Table II)
///   schallamach  mu = c*Fn^(-1/3)         (section I, [11]; one parameter,
///                                          stored as a = c, b = 0)
///   thirion      1/mu = a + b*Fn          (section I, [12]), least squares
///                                          in 1/mu
///   coulomb      mu = b                   (the constant baseline)
///
/// Thirion's law and the reciprocal form are the same family of curves
/// (1/(a*Fn + b) with the roles of a and b swapped); they differ in the
/// space the error is minimised in (1/mu vs mu), which matters when eps is
/// additive in mu as eq. (1) assumes.
///
/// Held-out error: strokes are dealt round-robin into K folds (K = min(
/// max_folds, strokes)); each form is fitted on K-1 folds and its mean
/// absolute error of mu measured on the held-out fold (leave-strokes-out),
/// so samples of one stroke never sit on both sides.
///
/// Usage:
/// @code
///   FormComparison c = CompareFrictionForms(fn_n, mu, stroke_id);
///   if (c.valid) { FrictionForm best = c.best; }
/// @endcode

#include <string>
#include <vector>

namespace frictiond {

/// A form of mu = f(Fn).
enum class FrictionForm {
  kLinear,
  kReciprocal,
  kInverseCube,
  kSchallamach,
  kThirion,
  kCoulomb,
};
/// Stable names: "linear", "reciprocal", "inverse_cube", "schallamach",
/// "thirion", "coulomb".
const char* ToString(FrictionForm form);
/// The formula as text, e.g. "mu = a*fn_n + b".
const char* FormulaOf(FrictionForm form);
/// All forms, in the order above.
const std::vector<FrictionForm>& AllFrictionForms();

/// One form fitted to data.
struct FormFit {
  FrictionForm form = FrictionForm::kLinear;
  bool valid = false;  ///< false: could not be fitted (why)
  std::string why;
  double a = 0.0;  ///< see the file comment per form
  double b = 0.0;
  int params = 0;       ///< free parameters (1 or 2)
  double r2 = 0.0;      ///< in-sample R^2 of mu (1 - SSE/SST)
  double mae = 0.0;     ///< in-sample mean |mu - f(Fn)|
  double cv_mae = 0.0;  ///< held-out mean |mu - f(Fn)| (CompareFrictionForms)
  int samples = 0;
};

/// mu of a fitted form at fn_n (> 0).
double EvalFrictionForm(FrictionForm form, double a, double b, double fn_n);

/// Fits one form to (fn_n, mu) pairs; samples with non-finite values or
/// fn_n <= 0 (and mu <= 0 for thirion) are skipped. Two-parameter forms are
/// not valid (why says so) when the 5-95 % range of Fn is below 2 % of its
/// median: constant-load data cannot tell the forms apart.
/// @throws std::invalid_argument when sizes differ.
FormFit FitFrictionForm(FrictionForm form,
                        const std::vector<double>& fn_n,
                        const std::vector<double>& mu);

/// All forms compared by leave-strokes-out error.
struct FormComparison {
  bool valid = false;  ///< false: fewer than 2 strokes or no form fitted
  std::string why;
  std::vector<FormFit> forms;  ///< in AllFrictionForms() order; a, b, r2,
                               ///< mae from all data, cv_mae held out
  FrictionForm best = FrictionForm::kLinear;  ///< lowest cv_mae
  int folds = 0;
  int strokes = 0;
};

/// Compares the forms on (fn_n, mu) samples grouped by `stroke` id.
/// @throws std::invalid_argument when sizes differ or max_folds < 2.
FormComparison CompareFrictionForms(const std::vector<double>& fn_n,
                                    const std::vector<double>& mu,
                                    const std::vector<int>& stroke,
                                    int max_folds = 5);

}  // namespace frictiond
