#include "frictiond/mujoco/pinch_grip.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

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

}  // namespace frictiond::mujoco
