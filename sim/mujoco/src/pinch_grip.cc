#include "frictiond/mujoco/pinch_grip.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "frictiond/estimators/grip_force.h"

namespace frictiond::mujoco {
namespace {

double Coefficient(const RegressionModel& m, const char* term) {
  const int k = m.FindTerm(term);
  return k >= 0 && k < m.beta.size() ? m.beta(k) : 0.0;
}

// Mean mu at rest, eq. (1) with v = 0.
double MeanMuAtRest(const StochasticFrictionModel& s, double fn_n) {
  return Coefficient(s.mu, "intercept") + Coefficient(s.mu, "fn_n") * fn_n;
}

std::vector<double> MidpointQuantiles(const RegressionModel& m, int grid) {
  std::vector<double> q(grid);
  for (int i = 0; i < grid; ++i) q[i] = CalcEpsQuantile(m, (i + 0.5) / grid);
  std::sort(q.begin(), q.end());  // monotone already; guards rounding
  return q;
}

void CheckPositive(double x, const char* field) {
  if (!(x > 0) || !std::isfinite(x))
    throw std::invalid_argument(std::string(field) + " = " + std::to_string(x) +
                                " (must be finite and > 0)");
}

// One contact's eps over a hold (PinchHoldRisk): eps = F^-1(Phi(z)) on a
// z grid over [-8, 8] (as FrictionAdapter tabulates it), z = sqrt(f) A +
// sqrt(1 - f) w, w an AR(1) advanced every dt_s.
struct LatentEps {
  static constexpr double kZMax = 8.0;
  static constexpr int kPoints = 4097;

  explicit LatentEps(const StochasticFrictionModel& model, double hold_s) {
    const EpsTimeModel& et = model.eps_time;
    ar1 = et.valid && et.dt_s > 0 && et.offset_fraction < 1.0;
    if (ar1) {
      const double f = std::clamp(et.offset_fraction, 0.0, 1.0);
      sqrt_f = std::sqrt(f);
      sqrt_1mf = std::sqrt(1.0 - f);
      phi = std::clamp(et.phi, 0.0, 0.999);  // the adapter's clamp
      innovation = std::sqrt(1.0 - phi * phi);
      dt_s = et.dt_s;
      samples = 1 + static_cast<int>(std::lround(hold_s / dt_s));
    }
    table.resize(kPoints);
    for (int k = 0; k < kPoints; ++k) {
      const double z = -kZMax + 2.0 * kZMax * k / (kPoints - 1);
      const double p =
          std::clamp(0.5 * std::erfc(-z / std::sqrt(2.0)), 1e-15, 1.0 - 1e-15);
      // The adapter's draws: CalcEpsQuantileExtended on the AR(1) path,
      // CalcEpsQuantile of a uniform when eps is held per episode.
      table[k] = ar1 ? CalcEpsQuantileExtended(model.mu, p, et)
                     : CalcEpsQuantile(model.mu, p);
    }
  }

  double Eps(double offset_z, double ar_z) const {
    const double z = ar1 ? sqrt_f * offset_z + sqrt_1mf * ar_z : offset_z;
    const double x =
        (std::clamp(z, -kZMax, kZMax) + kZMax) / (2.0 * kZMax) * (kPoints - 1);
    const int k = std::min(static_cast<int>(x), kPoints - 2);
    const double w = x - k;
    return table[k] + w * (table[k + 1] - table[k]);
  }

  bool ar1 = false;
  double sqrt_f = 1.0, sqrt_1mf = 0.0, phi = 0.0, innovation = 1.0;
  double dt_s = 1.0;
  int samples = 1;
  std::vector<double> table;
};

}  // namespace

double CalcPinchSlipProbability(const StochasticFrictionModel& a,
                                const StochasticFrictionModel& b,
                                double fn_n,
                                double load_n,
                                int grid) {
  CheckPositive(fn_n, "fn_n");
  CheckPositive(load_n, "load_n");
  grid = std::max(grid, 16);
  // Slip when eps_a + eps_b < c.
  const double c =
      load_n / fn_n - MeanMuAtRest(a, fn_n) - MeanMuAtRest(b, fn_n);
  const std::vector<double> qa = MidpointQuantiles(a.mu, grid);
  const std::vector<double> qb = MidpointQuantiles(b.mu, grid);
  // Count pairs (i, j) with qa[i] + qb[j] < c: two pointers, qa rising,
  // qb's bound falling.
  long long count = 0;
  int j = grid;  // qb[0..j) < c - qa[i]
  for (int i = 0; i < grid; ++i) {
    while (j > 0 && qa[i] + qb[j - 1] >= c) --j;
    count += j;
  }
  return static_cast<double>(count) / (static_cast<double>(grid) * grid);
}

PinchGripForce CalcPinchGripForce(const StochasticFrictionModel& a,
                                  const StochasticFrictionModel& b,
                                  double load_n,
                                  double risk,
                                  double fn_max_n) {
  CheckPositive(load_n, "load_n");
  CheckPositive(fn_max_n, "fn_max_n");
  if (!(risk > 0 && risk < 1))
    throw std::invalid_argument("risk = " + std::to_string(risk) +
                                " (must be in (0, 1))");
  // Search below the force of largest mean friction Fn (b0 + b2 Fn), where
  // the capacity rises with Fn.
  const double b2 = Coefficient(a.mu, "fn_n") + Coefficient(b.mu, "fn_n");
  const double b0 =
      Coefficient(a.mu, "intercept") + Coefficient(b.mu, "intercept");
  double hi = fn_max_n;
  if (b2 < 0 && b0 > 0) hi = std::min(hi, b0 / (-2.0 * b2));
  PinchGripForce out;
  if (CalcPinchSlipProbability(a, b, hi, load_n) > risk) return out;
  double lo = 0.0;
  while (hi - lo > 1e-6) {
    const double mid = 0.5 * (lo + hi);
    if (CalcPinchSlipProbability(a, b, mid, load_n) > risk)
      lo = mid;
    else
      hi = mid;
  }
  out.attainable = true;
  out.fn_n = hi;
  out.slip_probability = CalcPinchSlipProbability(a, b, hi, load_n);
  return out;
}

PinchHoldRisk::PinchHoldRisk(const StochasticFrictionModel& a,
                             const StochasticFrictionModel& b,
                             double load_n,
                             const PinchHoldOptions& options) {
  CheckPositive(load_n, "load_n");
  if (!(options.hold_s >= 0 && options.hold_s <= 3600))
    throw std::invalid_argument("hold_s = " + std::to_string(options.hold_s) +
                                " (must be in [0, 3600] s)");
  if (options.paths < 100)
    throw std::invalid_argument("paths = " + std::to_string(options.paths) +
                                " (must be >= 100)");
  load_n_ = load_n;
  b0_ = Coefficient(a.mu, "intercept") + Coefficient(b.mu, "intercept");
  b2_ = Coefficient(a.mu, "fn_n") + Coefficient(b.mu, "fn_n");
  const LatentEps ea(a, options.hold_s), eb(b, options.hold_s);
  samples_a_ = ea.samples;
  samples_b_ = eb.samples;
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  minima_.resize(options.paths);
  constexpr double kNever = std::numeric_limits<double>::infinity();
  for (double& m : minima_) {
    const double offset_a = normal(rng), offset_b = normal(rng);
    double wa = normal(rng), wb = normal(rng);  // stationary w_0
    double eps_a = ea.Eps(offset_a, wa), eps_b = eb.Eps(offset_b, wb);
    m = eps_a + eps_b;
    // Walk the union of both contacts' sample times.
    int ia = 0, ib = 0;
    while (ia + 1 < ea.samples || ib + 1 < eb.samples) {
      const double ta = ia + 1 < ea.samples ? (ia + 1) * ea.dt_s : kNever;
      const double tb = ib + 1 < eb.samples ? (ib + 1) * eb.dt_s : kNever;
      const double t = std::min(ta, tb);
      if (ta <= t + 1e-12) {
        ++ia;
        wa = ea.phi * wa + ea.innovation * normal(rng);
        eps_a = ea.Eps(offset_a, wa);
      }
      if (tb <= t + 1e-12) {
        ++ib;
        wb = eb.phi * wb + eb.innovation * normal(rng);
        eps_b = eb.Eps(offset_b, wb);
      }
      m = std::min(m, eps_a + eps_b);
    }
  }
  std::sort(minima_.begin(), minima_.end());
}

double PinchHoldRisk::SlipProbability(double fn_n) const {
  CheckPositive(fn_n, "fn_n");
  // Slip when min_t (eps_a + eps_b) < c.
  const double c = load_n_ / fn_n - b0_ - b2_ * fn_n;
  const auto below = std::lower_bound(minima_.begin(), minima_.end(), c);
  return static_cast<double>(below - minima_.begin()) /
         static_cast<double>(minima_.size());
}

PinchGripForce PinchHoldRisk::GripForce(double risk, double fn_max_n) const {
  CheckPositive(fn_max_n, "fn_max_n");
  if (!(risk > 0 && risk < 1))
    throw std::invalid_argument("risk = " + std::to_string(risk) +
                                " (must be in (0, 1))");
  double hi = fn_max_n;
  if (b2_ < 0 && b0_ > 0) hi = std::min(hi, b0_ / (-2.0 * b2_));
  PinchGripForce out;
  if (SlipProbability(hi) > risk) return out;
  double lo = 0.0;
  while (hi - lo > 1e-6) {
    const double mid = 0.5 * (lo + hi);
    if (SlipProbability(mid) > risk)
      lo = mid;
    else
      hi = mid;
  }
  out.attainable = true;
  out.fn_n = hi;
  out.slip_probability = SlipProbability(hi);
  return out;
}

}  // namespace frictiond::mujoco
