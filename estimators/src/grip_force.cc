#include "frictiond/estimators/grip_force.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frictiond/estimators/stats.h"

namespace frictiond {

bool GripForceOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& s) {
    if (why) *why = s;
    return false;
  };
  if (!(hold_s >= 0 && hold_s <= 3600))
    return fail("hold_s = " + std::to_string(hold_s) +
                " (must be in [0, 3600])");
  if (!(v_mm_s >= 0) || !std::isfinite(v_mm_s))
    return fail("v_mm_s = " + std::to_string(v_mm_s) +
                " (must be finite and >= 0)");
  return true;
}

namespace {

constexpr double kTailLevel = 0.02;  // the GPD's threshold level

// GPD excess below the 2 % quantile at probability p < 0.02.
double GpdExcess(double xi, double scale, double p) {
  const double r = p / kTailLevel;
  if (std::fabs(xi) < 1e-9) return -scale * std::log(r);
  return scale / xi * (std::pow(r, -xi) - 1);
}

// Inverse of GpdExcess.
double GpdLevel(double xi, double scale, double excess) {
  if (std::fabs(xi) < 1e-9) return kTailLevel * std::exp(-excess / scale);
  const double base = 1 + xi * excess / scale;
  if (!(base > 0)) return 0.0;  // beyond a light tail's end point
  return kTailLevel * std::pow(base, -1 / xi);
}

}  // namespace

double CalcStoredQuantileExtended(const std::vector<double>& q,
                                  double tail_xi,
                                  double tail_scale,
                                  double p) {
  const double p0 = EpsQuantileLevels().front();
  if (p >= p0) return InterpolateStoredQuantiles(q, p);
  const double q0 = q.front();
  if (tail_scale > 0)  // the GPD's shape, anchored at the 0.001 level
    return q0 - (GpdExcess(tail_xi, tail_scale, p) -
                 GpdExcess(tail_xi, tail_scale, p0));
  // Exponential lower tail through the 0.001 and 0.01 quantiles.
  const double q1 = InterpolateStoredQuantiles(q, 10 * p0);
  const double scale = std::max(0.0, q1 - q0) / std::log(10.0);
  return q0 + scale * std::log(p / p0);
}

double CalcStoredCdfExtended(const std::vector<double>& q,
                             double tail_xi,
                             double tail_scale,
                             double x) {
  const auto& levels = EpsQuantileLevels();
  const double p0 = levels.front(), q0 = q.front();
  if (x >= q.back()) return 1.0;
  if (x >= q0) {
    const auto it = std::upper_bound(q.begin(), q.end(), x);
    const std::size_t k = it - q.begin();
    const double dq = q[k] - q[k - 1];
    const double w = dq > 0 ? (x - q[k - 1]) / dq : 1.0;
    return std::max(p0, levels[k - 1] + w * (levels[k] - levels[k - 1]));
  }
  if (tail_scale > 0)
    return GpdLevel(
        tail_xi, tail_scale, GpdExcess(tail_xi, tail_scale, p0) + (q0 - x));
  const double q1 = InterpolateStoredQuantiles(q, 10 * p0);
  const double scale = std::max(1e-300, q1 - q0) / std::log(10.0);
  return p0 * std::exp((x - q0) / scale);
}

double CalcEpsQuantileExtended(const RegressionModel& model,
                               double p,
                               const EpsTimeModel& tail) {
  if (p >= EpsQuantileLevels().front() ||
      model.eps_quantiles.size() != EpsQuantileLevels().size())
    return CalcEpsQuantile(model, p);
  return CalcStoredQuantileExtended(
      model.eps_quantiles, tail.tail_xi, tail.tail_scale, p);
}

double CalcEpsQuantileExtended(const RegressionModel& model, double p) {
  return CalcEpsQuantileExtended(model, p, EpsTimeModel{});
}

// The CDF matching CalcEpsQuantileExtended.
double CalcEpsCdfExtended(const RegressionModel& model,
                          double e,
                          const EpsTimeModel& tail) {
  if (model.eps_quantiles.size() != EpsQuantileLevels().size())
    return CalcEpsCdf(model, e);
  return CalcStoredCdfExtended(
      model.eps_quantiles, tail.tail_xi, tail.tail_scale, e);
}

namespace {

int HoldSamples(const EpsTimeModel& t, double hold_s) {
  if (hold_s <= 0 || !t.valid) return 1;
  return 1 + static_cast<int>(std::lround(hold_s / t.dt_s));
}

// P(any slip during the hold) from the probability p of a slip at one
// instant: the first passage of the identified process over the hold's
// samples (one sample: p itself), the one rule of eps_time.h.
double HoldProbabilityFromInstant(double p,
                                  const EpsTimeModel& t,
                                  double hold_s) {
  return CalcHoldSlipFromInstant(p, HoldSamples(t, hold_s), t);
}

// Per-instant probability floor: from the time model, else the stored
// quantile levels (and 1 / samples).
double MinInstantRisk(const StochasticFrictionModel& model) {
  if (model.eps_time.valid) return model.eps_time.min_instant_risk;
  const double n = std::max(1, model.mu.samples);
  return std::max(EpsQuantileLevels().front(), 1.0 / n);
}

// x(Fn) of eq. (1) at v and the other inputs' fitted means; dx/dFn.
void Regressors(const StochasticFrictionModel& model,
                double fn_n,
                double v_mm_s,
                Eigen::VectorXd* x,
                Eigen::VectorXd* dx) {
  const RegressionModel& m = model.mu;
  const double h = 1e-6 * std::max(1.0, std::fabs(fn_n));
  x->resize(m.terms.size());
  dx->resize(m.terms.size());
  for (std::size_t k = 0; k < m.terms.size(); ++k) {
    const Term& t = m.terms[k];
    if (t.kind == TermKind::kIntercept) {
      (*x)(k) = 1.0;
      (*dx)(k) = 0.0;
      continue;
    }
    if (t.input == "fn_n") {
      (*x)(k) = t.Eval(fn_n);
      (*dx)(k) = (t.Eval(fn_n + h) - t.Eval(fn_n - h)) / (2 * h);
      continue;
    }
    double value = 0.0;
    std::string f1, f2;
    if (t.input == "v_mm_s") {
      value = v_mm_s;
    } else if (SplitProductName(t.input, &f1, &f2)) {
      // A product column "x*y" (an interaction, eps_scale.h) from its
      // factors at this Fn and v (others at their means).
      auto at = [&](double fn) {
        return t.Eval(ResolveInputValue(
            model, {{"fn_n", fn}, {"v_mm_s", v_mm_s}}, t.input));
      };
      (*x)(k) = at(fn_n);
      (*dx)(k) = f1 == "fn_n" || f2 == "fn_n"
                     ? (at(fn_n + h) - at(fn_n - h)) / (2 * h)
                     : 0.0;
      continue;
    } else {
      auto it = model.inputs.find(t.input);
      value = it != model.inputs.end() ? it->second.mean : 0.0;
    }
    (*x)(k) = t.Eval(value);
    (*dx)(k) = 0.0;
  }
}

// eps scale factor at (Fn, v) (exactly 1 without a scale model) and its
// derivative in Fn.
double ScaleAt(const StochasticFrictionModel& model,
               double fn_n,
               double v_mm_s,
               double* d_dfn = nullptr) {
  auto at = [&](double fn) {
    return CalcEpsScaleFactor(model, {{"fn_n", fn}, {"v_mm_s", v_mm_s}});
  };
  const double s = at(fn_n);
  if (d_dfn) {
    const double h = 1e-6 * std::max(1.0, std::fabs(fn_n));
    *d_dfn = model.eps_scale ? (at(fn_n + h) - at(fn_n - h)) / (2 * h) : 0.0;
  }
  return s;
}

// Coefficient covariance, rescaled to the stroke-clustered standard errors
// when they are stored (their correlations kept).
Eigen::MatrixXd CoefficientCovariance(const RegressionModel& m) {
  Eigen::MatrixXd P = m.P_beta;
  const Eigen::Index p = static_cast<Eigen::Index>(m.terms.size());
  if (P.rows() != p) return Eigen::MatrixXd::Zero(p, p);
  if (m.std_err_stroke.size() == p && m.std_err.size() == p) {
    Eigen::VectorXd s(p);
    for (Eigen::Index k = 0; k < p; ++k)
      s(k) = m.std_err(k) > 0
                 ? std::max(1.0, m.std_err_stroke(k) / m.std_err(k))
                 : 1.0;
    P = s.asDiagonal() * P * s.asDiagonal();
  }
  return P;
}

void CheckInputs(double load_n, double risk, const GripForceOptions& options) {
  if (!(load_n > 0) || !std::isfinite(load_n))
    throw std::invalid_argument("load_n = " + std::to_string(load_n) +
                                " (must be finite and > 0)");
  if (!(risk > 0 && risk < 1))
    throw std::invalid_argument("risk = " + std::to_string(risk) +
                                " (must be in (0, 1))");
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
}

}  // namespace

double CalcMinSupportedRisk(const StochasticFrictionModel& model,
                            double hold_s) {
  GripForceOptions o;
  o.hold_s = hold_s;
  std::string why;
  if (!o.IsValid(&why)) throw std::invalid_argument(why);
  return HoldProbabilityFromInstant(
      MinInstantRisk(model), model.eps_time, hold_s);
}

double CalcHoldSlipProbability(const StochasticFrictionModel& model,
                               double fn_n,
                               double load_n,
                               const GripForceOptions& options) {
  if (load_n == 0) {  // nothing to hold: checked as any other input
    std::string why;
    if (!options.IsValid(&why)) throw std::invalid_argument(why);
  } else {
    CheckInputs(load_n, 0.5, options);
  }
  if (!(fn_n > 0) || !std::isfinite(fn_n))
    throw std::invalid_argument("fn_n = " + std::to_string(fn_n) +
                                " (must be finite and > 0)");
  const EpsTimeModel& t = model.eps_time;
  if (options.hold_s > 0 && !t.valid)
    throw std::invalid_argument(
        "hold_s = " + std::to_string(options.hold_s) +
        ": the model has no identified eps time correlation (" + t.why + ")");
  if (load_n == 0) return 0.0;
  Eigen::VectorXd x, dx;
  Regressors(model, fn_n, options.v_mm_s, &x, &dx);
  const double mean =
      model.mu.beta.size() == x.size() ? model.mu.beta.dot(x) : 0.0;
  double u = load_n / fn_n - mean;  // slip when eps < u
  // Heteroscedastic eps: the stored distribution is of eps / s(Fn, v).
  if (model.eps_scale) u /= ScaleAt(model, fn_n, options.v_mm_s);
  double p = CalcEpsCdfExtended(model.mu, u, t);
  p = std::clamp(p, 1e-300, 1.0 - 1e-16);
  return HoldProbabilityFromInstant(p, t, options.hold_s);
}

GripForce CalcGripForce(const StochasticFrictionModel& model,
                        double load_n,
                        double risk,
                        const GripForceOptions& options) {
  CheckInputs(load_n, risk, options);
  GripForce g;
  const EpsTimeModel& t = model.eps_time;
  if (options.hold_s > 0 && !t.valid) {
    g.status = GripForceStatus::kNoTimeModel;
    g.why = "hold_s = " + std::to_string(options.hold_s) +
            " needs the eps time correlation, which this model lacks (" +
            (t.why.empty() ? std::string("identified before it was stored")
                           : t.why) +
            "); re-identify the material";
    return g;
  }
  g.hold_samples = HoldSamples(t, options.hold_s);
  // One rule, tabulated once, for the smallest supported risk (as
  // CalcMinSupportedRisk) and the answer.
  const HoldSlipRule rule(t, g.hold_samples);
  g.min_supported_risk = rule.SlipFromInstant(MinInstantRisk(model));
  if (risk < g.min_supported_risk) {
    g.status = GripForceStatus::kUnsupportedRisk;
    g.why = "risk = " + std::to_string(risk) +
            " is below the smallest risk the data support for hold_s = " +
            std::to_string(options.hold_s) + ": " +
            std::to_string(g.min_supported_risk);
    return g;
  }
  g.instant_risk = rule.InstantRiskFor(risk);
  // u: the eps quantile at the instant risk. With an eps scale model the
  // stored quantile is of eps / s(Fn, v), so (*) reads
  //   Fn * (x(Fn)' beta + s(Fn, v) u) = load_n
  // (the scale at the answer's own Fn: eps_scale.h).
  const double u = CalcEpsQuantileExtended(model.mu, g.instant_risk, t);
  const bool scaled = model.eps_scale.has_value();
  // Solve (*) Fn (x(Fn)' beta + u) = load by Newton from the linear answer
  // (exact for eq. (1)'s linear fn_n term; general for other Fn terms).
  const RegressionModel& m = model.mu;
  Eigen::VectorXd x, dx;
  auto residual = [&](double fn, double* slope) {
    Regressors(model, fn, options.v_mm_s, &x, &dx);
    if (!scaled) {
      const double mu = m.beta.dot(x) + u;
      *slope = mu + fn * m.beta.dot(dx);
      return fn * mu - load_n;
    }
    double ds = 0.0;
    const double sc = ScaleAt(model, fn, options.v_mm_s, &ds);
    const double mu = m.beta.dot(x) + sc * u;
    *slope = mu + fn * (m.beta.dot(dx) + ds * u);
    return fn * mu - load_n;
  };
  // Quadratic start (linear in Fn) for an eps quantile uq held fixed.
  const int k2 = m.FindTerm("fn_n");
  const double b2 = k2 >= 0 ? m.beta(k2) : 0.0;
  auto quadratic_start = [&](double uq, double* fn_out) {
    Regressors(model, 0.0, options.v_mm_s, &x, &dx);
    const double a0 = m.beta.dot(x) + uq;  // mu at Fn = 0
    if (std::fabs(b2) < 1e-12) {
      if (!(a0 > 0)) {
        g.status = GripForceStatus::kUnattainable;
        g.why = "the " + std::to_string(g.instant_risk) +
                " quantile of mu is " + std::to_string(a0) +
                " (<= 0): no grip holds";
        return false;
      }
      *fn_out = load_n / a0;
      return true;
    }
    const double disc = a0 * a0 + 4 * b2 * load_n;
    if (disc < 0) {
      g.status = GripForceStatus::kUnattainable;
      g.why = "mu falls with Fn too fast: Fn*mu(Fn) peaks at " +
              std::to_string(-a0 * a0 / (4 * b2)) + " N, below the load";
      return false;
    }
    const double sq = std::sqrt(disc);
    double best = std::numeric_limits<double>::infinity();
    for (double r : {(-a0 + sq) / (2 * b2), (-a0 - sq) / (2 * b2)})
      if (r > 0 && r < best) best = r;
    if (!std::isfinite(best)) {
      g.status = GripForceStatus::kUnattainable;
      g.why = "no positive normal force holds the load at this risk";
      return false;
    }
    *fn_out = best;
    return true;
  };
  double fn = 0.0;
  if (!scaled) {
    if (!quadratic_start(u, &fn)) return g;
  } else {
    // Fixed point in the scale: the quadratic answer with the scale at the
    // previous answer (from the fitted mean Fn), then Newton below.
    auto it = model.inputs.find("fn_n");
    fn = it != model.inputs.end() ? it->second.mean : 1.0;
    for (int it_s = 0; it_s < 50; ++it_s) {
      double next = 0.0;
      if (!quadratic_start(ScaleAt(model, fn, options.v_mm_s) * u, &next))
        return g;
      const bool done = std::fabs(next - fn) < 1e-12 * next;
      fn = next;
      if (done) break;
    }
  }
  for (int it = 0; it < 20; ++it) {  // polish (no-op for linear terms)
    double slope;
    const double r = residual(fn, &slope);
    if (!(std::fabs(slope) > 0)) break;
    const double step = r / slope;
    fn -= step;
    if (std::fabs(step) < 1e-12 * fn) break;
  }
  if (scaled) {
    double slope;
    const double r = residual(fn, &slope);
    if (!(fn > 0) || !std::isfinite(fn) || !(std::fabs(r) <= 1e-9 * load_n)) {
      g.status = GripForceStatus::kUnattainable;
      g.why =
          "no normal force holds the load at this risk with the eps scale "
          "in " +
          model.eps_scale->input +
          " (Fn*mu(Fn) at the risk's quantile "
          "does not reach the load)";
      return g;
    }
  }
  double slope;
  residual(fn, &slope);
  // Delta method: d fn / d beta = -fn x / slope.
  const Eigen::MatrixXd P = CoefficientCovariance(m);
  if (std::fabs(slope) > 0 && P.rows() == x.size()) {
    const Eigen::VectorXd grad = (-fn / slope) * x;
    g.fn_n_sd = std::sqrt(std::max(0.0, grad.dot(P * grad)));
  }
  g.status = GripForceStatus::kOk;
  g.attainable = true;
  g.fn_n = fn;
  g.mu_used = load_n / fn;
  auto it = model.inputs.find("fn_n");
  if (it != model.inputs.end())
    g.extrapolated = fn < it->second.min || fn > it->second.max;
  auto iv = model.inputs.find("v_mm_s");
  if (iv != model.inputs.end() &&
      (options.v_mm_s < iv->second.min || options.v_mm_s > iv->second.max))
    g.extrapolated = true;
  return g;
}

}  // namespace frictiond
