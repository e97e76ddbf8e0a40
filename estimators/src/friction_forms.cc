#include "frictiond/estimators/friction_forms.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include <Eigen/Core>

#include "frictiond/estimators/least_squares.h"

namespace frictiond {

namespace {

constexpr double kMinRelativeSpan = 0.02;

// Simple linear regression y = s*x + c over pairs; false when x has no
// spread.
bool FitLine(const std::vector<double>& x,
             const std::vector<double>& y,
             double* s,
             double* c) {
  const double n = static_cast<double>(x.size());
  if (x.size() < 2) return false;
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= n;
  my /= n;
  double sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  if (!(sxx > 1e-300 * n)) return false;
  *s = sxy / sxx;
  *c = my - *s * mx;
  return true;
}

// Gauss-Newton with step halving (SolveLeastSquares) for
// mu = 1/(a Fn + b), from (a, b); unbounded, a trial with a*Fn + b <= 0 at
// a sample is rejected. False when the start is outside that domain.
bool FitReciprocalLs(const std::vector<double>& fn,
                     const std::vector<double>& mu,
                     double* a,
                     double* b) {
  const auto m = static_cast<Eigen::Index>(fn.size());
  auto residual = [&](const Eigen::Vector2d& x,
                      Eigen::VectorXd* r,
                      Eigen::Matrix<double, Eigen::Dynamic, 2>* J) {
    for (Eigen::Index i = 0; i < m; ++i) {
      const double d = x[0] * fn[i] + x[1];
      if (!(d > 0)) return false;
      const double p = 1.0 / d;
      (*r)[i] = mu[i] - p;
      (*J)(i, 0) = fn[i] * p * p;  // d r / d a
      (*J)(i, 1) = p * p;          // d r / d b
    }
    return std::isfinite(r->squaredNorm());
  };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  LeastSquaresOptions options;
  options.method = LeastSquaresMethod::kGaussNewton;
  options.max_iterations = 50;
  options.min_rcond = 0.0;
  LeastSquaresWorkspace<2> ws(m);
  Eigen::Vector2d x(*a, *b);
  const LeastSquaresSummary<2> s =
      SolveLeastSquares<2>(residual,
                           &x,
                           Eigen::Vector2d(-kInf, -kInf),
                           Eigen::Vector2d(kInf, kInf),
                           options,
                           &ws);
  if (s.status == LeastSquaresStatus::kFailed) return false;
  *a = x[0];
  *b = x[1];
  return true;
}

FormFit FitOn(FrictionForm form,
              const std::vector<double>& fn,
              const std::vector<double>& mu) {
  FormFit out;
  out.form = form;
  out.params =
      form == FrictionForm::kSchallamach || form == FrictionForm::kCoulomb ? 1
                                                                           : 2;
  std::vector<double> x, y;
  x.reserve(fn.size());
  y.reserve(fn.size());
  for (std::size_t i = 0; i < fn.size(); ++i) {
    if (!(fn[i] > 0) || !std::isfinite(fn[i]) || !std::isfinite(mu[i]))
      continue;
    if (form == FrictionForm::kThirion && !(mu[i] > 0)) continue;
    x.push_back(fn[i]);
    y.push_back(mu[i]);
  }
  out.samples = static_cast<int>(x.size());
  if (out.samples < out.params + 1) {
    out.why = std::to_string(out.samples) + " usable samples (need > " +
              std::to_string(out.params) + ")";
    return out;
  }
  if (out.params == 2) {
    // Like the stochastic fit's min_relative_span: a 5-95 % Fn range below
    // 2 % of the median cannot tell a slope from noise.
    std::vector<double> sorted = x;
    std::sort(sorted.begin(), sorted.end());
    const auto at = [&sorted](double p) {
      return sorted[static_cast<std::size_t>(p * (sorted.size() - 1))];
    };
    if (!(at(0.95) - at(0.05) >= kMinRelativeSpan * std::fabs(at(0.5)))) {
      out.why = "fn_n has no span (5-95 % range " +
                std::to_string(at(0.95) - at(0.05)) + " N < 2 % of median " +
                std::to_string(at(0.5)) +
                " N): the Fn dependence cannot be "
                "identified";
      return out;
    }
  }
  bool ok = true;
  switch (form) {
    case FrictionForm::kLinear:
      ok = FitLine(x, y, &out.a, &out.b);
      break;
    case FrictionForm::kInverseCube: {
      std::vector<double> z(x.size());
      for (std::size_t i = 0; i < x.size(); ++i)
        z[i] = 1.0 / (x[i] * x[i] * x[i]);
      ok = FitLine(z, y, &out.a, &out.b);
      break;
    }
    case FrictionForm::kThirion:
    case FrictionForm::kReciprocal: {
      // Thirion: OLS of 1/mu = a + b Fn. Reciprocal starts from it and
      // minimises the error in mu.
      std::vector<double> inv;
      std::vector<double> xp;
      for (std::size_t i = 0; i < x.size(); ++i) {
        if (y[i] > 0) {
          inv.push_back(1.0 / y[i]);
          xp.push_back(x[i]);
        }
      }
      double slope = 0, icpt = 0;
      ok = FitLine(xp, inv, &slope, &icpt);
      if (ok && form == FrictionForm::kThirion) {
        out.a = icpt;
        out.b = slope;
      } else if (ok) {
        out.a = slope;
        out.b = icpt;
        ok = FitReciprocalLs(x, y, &out.a, &out.b);
      }
      break;
    }
    case FrictionForm::kSchallamach: {
      double sxy = 0, sxx = 0;
      for (std::size_t i = 0; i < x.size(); ++i) {
        const double z = std::cbrt(1.0 / x[i]);
        sxy += z * y[i];
        sxx += z * z;
      }
      out.a = sxy / sxx;
      out.b = 0.0;
      break;
    }
    case FrictionForm::kCoulomb: {
      double s = 0;
      for (double v : y) s += v;
      out.a = 0.0;
      out.b = s / y.size();
      break;
    }
  }
  if (!ok) {
    out.why = "fn_n has no spread (or the fit left the domain Fn > 0)";
    return out;
  }
  double my = 0;
  for (double v : y) my += v;
  my /= y.size();
  double sse = 0, sst = 0, sae = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double e = y[i] - EvalFrictionForm(form, out.a, out.b, x[i]);
    sse += e * e;
    sae += std::fabs(e);
    sst += (y[i] - my) * (y[i] - my);
  }
  if (!std::isfinite(sse)) {
    out.why = "the fitted curve has a pole inside the data's Fn range";
    return out;
  }
  out.r2 = sst > 0 ? 1.0 - sse / sst : 0.0;
  out.mae = sae / x.size();
  out.valid = true;
  return out;
}

}  // namespace

const char* ToString(FrictionForm form) {
  switch (form) {
    case FrictionForm::kLinear:
      return "linear";
    case FrictionForm::kReciprocal:
      return "reciprocal";
    case FrictionForm::kInverseCube:
      return "inverse_cube";
    case FrictionForm::kSchallamach:
      return "schallamach";
    case FrictionForm::kThirion:
      return "thirion";
    case FrictionForm::kCoulomb:
      return "coulomb";
  }
  return "unknown";
}

const char* FormulaOf(FrictionForm form) {
  switch (form) {
    case FrictionForm::kLinear:
      return "mu = a*fn_n + b";
    case FrictionForm::kReciprocal:
      return "mu = 1/(a*fn_n + b)";
    case FrictionForm::kInverseCube:
      return "mu = a/fn_n^3 + b";
    case FrictionForm::kSchallamach:
      return "mu = a*fn_n^(-1/3)";
    case FrictionForm::kThirion:
      return "1/mu = a + b*fn_n";
    case FrictionForm::kCoulomb:
      return "mu = b";
  }
  return "";
}

const std::vector<FrictionForm>& AllFrictionForms() {
  static const std::vector<FrictionForm> all = {FrictionForm::kLinear,
                                                FrictionForm::kReciprocal,
                                                FrictionForm::kInverseCube,
                                                FrictionForm::kSchallamach,
                                                FrictionForm::kThirion,
                                                FrictionForm::kCoulomb};
  return all;
}

double EvalFrictionForm(FrictionForm form, double a, double b, double fn_n) {
  switch (form) {
    case FrictionForm::kLinear:
      return a * fn_n + b;
    case FrictionForm::kReciprocal: {
      const double d = a * fn_n + b;
      return d > 0 ? 1.0 / d : std::numeric_limits<double>::infinity();
    }
    case FrictionForm::kInverseCube:
      return a / (fn_n * fn_n * fn_n) + b;
    case FrictionForm::kSchallamach:
      return a / std::cbrt(fn_n);
    case FrictionForm::kThirion: {
      const double d = a + b * fn_n;
      return d > 0 ? 1.0 / d : std::numeric_limits<double>::infinity();
    }
    case FrictionForm::kCoulomb:
      return b;
  }
  return 0.0;
}

FormFit FitFrictionForm(FrictionForm form,
                        const std::vector<double>& fn_n,
                        const std::vector<double>& mu) {
  if (fn_n.size() != mu.size()) {
    throw std::invalid_argument("fn_n has " + std::to_string(fn_n.size()) +
                                " entries, mu " + std::to_string(mu.size()) +
                                " (must be equal)");
  }
  return FitOn(form, fn_n, mu);
}

FormComparison CompareFrictionForms(const std::vector<double>& fn_n,
                                    const std::vector<double>& mu,
                                    const std::vector<int>& stroke,
                                    int max_folds) {
  if (fn_n.size() != mu.size() || stroke.size() != mu.size()) {
    throw std::invalid_argument(
        "fn_n, mu and stroke have " + std::to_string(fn_n.size()) + ", " +
        std::to_string(mu.size()) + " and " + std::to_string(stroke.size()) +
        " entries (must be equal)");
  }
  if (max_folds < 2) {
    throw std::invalid_argument("max_folds = " + std::to_string(max_folds) +
                                " (must be >= 2)");
  }
  FormComparison out;
  std::map<int, int> fold_of;  // stroke id -> fold
  for (int s : stroke) fold_of.emplace(s, 0);
  out.strokes = static_cast<int>(fold_of.size());
  for (FrictionForm f : AllFrictionForms())
    out.forms.push_back(FitOn(f, fn_n, mu));
  if (out.strokes < 2) {
    out.why = std::to_string(out.strokes) +
              " stroke(s): held-out comparison needs >= 2 strokes";
    return out;
  }
  out.folds = std::min(max_folds, out.strokes);
  int k = 0;
  for (auto& [id, fold] : fold_of) fold = k++ % out.folds;
  std::vector<double> sum_abs(out.forms.size(), 0.0);
  std::vector<int> count(out.forms.size(), 0);
  std::vector<double> fn_train, mu_train;
  for (int fold = 0; fold < out.folds; ++fold) {
    fn_train.clear();
    mu_train.clear();
    for (std::size_t i = 0; i < mu.size(); ++i) {
      if (fold_of[stroke[i]] != fold) {
        fn_train.push_back(fn_n[i]);
        mu_train.push_back(mu[i]);
      }
    }
    for (std::size_t f = 0; f < out.forms.size(); ++f) {
      const FormFit fit = FitOn(out.forms[f].form, fn_train, mu_train);
      if (!fit.valid) {
        count[f] = -1;  // this form failed on a fold: no held-out error
        continue;
      }
      if (count[f] < 0) continue;
      for (std::size_t i = 0; i < mu.size(); ++i) {
        if (fold_of[stroke[i]] != fold || !(fn_n[i] > 0) ||
            !std::isfinite(fn_n[i]) || !std::isfinite(mu[i]))
          continue;
        sum_abs[f] += std::fabs(
            mu[i] - EvalFrictionForm(fit.form, fit.a, fit.b, fn_n[i]));
        ++count[f];
      }
    }
  }
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t f = 0; f < out.forms.size(); ++f) {
    FormFit& fit = out.forms[f];
    if (!fit.valid) continue;
    if (count[f] <= 0) {
      fit.valid = false;
      fit.why = "could not be fitted on every training fold";
      continue;
    }
    fit.cv_mae = sum_abs[f] / count[f];
    if (fit.cv_mae < best) {
      best = fit.cv_mae;
      out.best = fit.form;
    }
  }
  out.valid = std::isfinite(best);
  if (!out.valid) out.why = "no form could be fitted";
  return out;
}

}  // namespace frictiond
