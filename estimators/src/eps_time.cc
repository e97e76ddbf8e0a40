#include "frictiond/estimators/eps_time.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "frictiond/estimators/stats.h"

namespace frictiond {

namespace {

constexpr double kMaxPhi = 0.995;

void CheckPhi(int n, double phi) {
  if (n < 1)
    throw std::invalid_argument("n = " + std::to_string(n) + " (must be >= 1)");
  if (!(phi >= 0 && phi <= kMaxPhi))
    throw std::invalid_argument("phi = " + std::to_string(phi) +
                                " (must be in [0, 0.995])");
}

}  // namespace

double CalcAr1Survival(double b, int n, double phi) {
  CheckPhi(n, phi);
  const double p_above = 1.0 - NormalCdf(b);
  if (n == 1 || p_above <= 0.0) return p_above;
  if (phi == 0.0) return std::pow(p_above, n);
  // Nystroem: the density f_t of w_t on {w_0..w_t >= b} on a grid over
  // [b, hi], Simpson weights; f_{t+1}(y) = Int_b^hi f_t(x) N(y; phi x,
  // 1 - phi^2) dx. The kernel is banded (8.5 standard deviations).
  const double s = std::sqrt(1.0 - phi * phi);
  const double hi = std::max(b, 0.0) + 8.5;
  double h = std::min(0.05, s / 4.0);
  int m = static_cast<int>(std::ceil((hi - b) / h));
  if (m % 2 == 1) ++m;  // Simpson needs an even number of intervals
  h = (hi - b) / m;
  const int points = m + 1;
  std::vector<double> x(points), w(points), f(points), g(points);
  for (int j = 0; j < points; ++j) {
    x[j] = b + j * h;
    w[j] = h / 3.0 * (j == 0 || j == m ? 1.0 : (j % 2 == 1 ? 4.0 : 2.0));
    f[j] = std::exp(-0.5 * x[j] * x[j]) / std::sqrt(2 * M_PI);
  }
  const double reach = 8.5 * s;
  std::vector<int> lo(points), len(points);
  std::vector<double> kernel;
  kernel.reserve(static_cast<std::size_t>(points) *
                 static_cast<std::size_t>(2 * reach / h + 3));
  std::vector<std::size_t> start(points);
  const double norm = 1.0 / (s * std::sqrt(2 * M_PI));
  for (int i = 0; i < points; ++i) {
    const double mean = phi * x[i];
    const int j0 =
        std::max(0, static_cast<int>(std::floor((mean - reach - b) / h)));
    const int j1 =
        std::min(m, static_cast<int>(std::ceil((mean + reach - b) / h)));
    lo[i] = j0;
    len[i] = std::max(0, j1 - j0 + 1);
    start[i] = kernel.size();
    for (int j = j0; j <= j1; ++j) {
      const double d = (x[j] - mean) / s;
      kernel.push_back(norm * std::exp(-0.5 * d * d));
    }
  }
  auto mass = [&](const std::vector<double>& v) {
    double sum = 0;
    for (int j = 0; j < points; ++j) sum += w[j] * v[j];
    return sum;
  };
  double surv = mass(f);
  double last_ratio = -1.0;
  int stable = 0;
  for (int t = 1; t < n; ++t) {
    std::fill(g.begin(), g.end(), 0.0);
    for (int i = 0; i < points; ++i) {
      const double a = f[i] * w[i];
      if (a == 0.0) continue;
      const double* k = kernel.data() + start[i];
      double* out = g.data() + lo[i];
      for (int j = 0; j < len[i]; ++j) out[j] += a * k[j];
    }
    const double next = mass(g);
    if (!(next > 1e-300)) return 0.0;
    const double ratio = next / surv;
    f.swap(g);
    surv = next;
    // Once the decay rate is the quasi-stationary one, S_n = S_t r^(n-1-t).
    // (A bounded number of steps in any case: past 20000 the rate has
    // converged to far below the quadrature error.)
    if (std::fabs(ratio - last_ratio) < 1e-12 * ratio || t >= 20000) {
      if (++stable >= 3 || t >= 20000) return surv * std::pow(ratio, n - 1 - t);
    } else {
      stable = 0;
    }
    last_ratio = ratio;
  }
  return surv;
}

namespace {

// P(any z_t < c) of one hold, with S_n tabulated once per (n, phi).
class HoldCrossing {
 public:
  HoldCrossing(int n, double phi, double f) : n_(n), phi_(phi), f_(f) {
    CheckPhi(n, phi);
    if (!(f >= 0 && f <= 1))
      throw std::invalid_argument("offset_fraction = " + std::to_string(f) +
                                  " (must be in [0, 1])");
    if (n == 1 || f >= 0.9999 || f <= 0.0) return;  // no table needed
    y_.resize(kNb);
    for (int k = 0; k < kNb; ++k) {
      const double sv = CalcAr1Survival(kBLo + k * kBStep, n, phi);
      const double l = sv > 1e-300 ? -std::log(sv) : 690.0;
      y_[k] = std::log(std::max(l, 1e-300));
    }
  }

  double Probability(double c) const {
    if (n_ == 1 || f_ >= 0.9999) return NormalCdf(c);
    if (f_ <= 0.0) return 1.0 - CalcAr1Survival(c, n_, phi_);
    // P = 1 - Int phi_N(a) S_n((c - sqrt(f) a) / sqrt(1 - f)) da, Simpson
    // over a.
    const double sf = std::sqrt(f_), sr = std::sqrt(1.0 - f_);
    double step = std::min(0.05, 0.25 * sr / sf);
    int m = static_cast<int>(std::ceil(17.0 / step));
    if (m % 2 == 1) ++m;
    step = 17.0 / m;
    double integral = 0;
    for (int j = 0; j <= m; ++j) {
      const double a = -8.5 + j * step;
      const double wj =
          step / 3.0 * (j == 0 || j == m ? 1.0 : (j % 2 == 1 ? 4.0 : 2.0));
      integral += wj * std::exp(-0.5 * a * a) / std::sqrt(2 * M_PI) *
                  Survival((c - sf * a) / sr);
    }
    return std::clamp(1.0 - integral, NormalCdf(c), 1.0);
  }

 private:
  static constexpr double kBLo = -6.0, kBHi = 4.5, kBStep = 0.25;
  static constexpr int kNb = 43;  // (kBHi - kBLo) / kBStep + 1

  // S_n(b): Catmull-Rom in log(-log S) on the table.
  double Survival(double b) const {
    if (b < kBLo) return std::exp(-n_ * NormalCdf(b));
    if (b >= kBHi) return 0.0;
    const double u = (b - kBLo) / kBStep;
    const int k = std::min(kNb - 2, static_cast<int>(u));
    const double t = u - k;
    const double y0 = k > 0 ? y_[k - 1] : 2 * y_[k] - y_[k + 1];
    const double y3 = k + 2 < kNb ? y_[k + 2] : 2 * y_[k + 1] - y_[k];
    const double y1 = y_[k], y2 = y_[k + 1];
    const double v = y1 + 0.5 * t *
                              (y2 - y0 +
                               t * (2 * y0 - 5 * y1 + 4 * y2 - y3 +
                                    t * (3 * (y1 - y2) + y3 - y0)));
    return std::exp(-std::exp(v));
  }

  int n_;
  double phi_, f_;
  std::vector<double> y_;
};

}  // namespace

double CalcHoldCrossingProbability(double c,
                                   int n,
                                   double phi,
                                   double offset_fraction) {
  return HoldCrossing(n, phi, offset_fraction).Probability(c);
}

double CalcHoldCrossingLevel(double risk,
                             int n,
                             double phi,
                             double offset_fraction) {
  if (!(risk > 0 && risk < 1))
    throw std::invalid_argument("risk = " + std::to_string(risk) +
                                " (must be in (0, 1))");
  const HoldCrossing crossing(n, phi, offset_fraction);
  if (n == 1) return NormalQuantile(risk);
  // The probability increases with c and is >= Phi(c): bisection below
  // Phi^-1(risk).
  double lo = -12.0, hi = NormalQuantile(risk);
  for (int it = 0; it < 60 && hi - lo > 1e-7; ++it) {
    const double mid = 0.5 * (lo + hi);
    (crossing.Probability(mid) < risk ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace frictiond

namespace frictiond {

EpsTimeModel FitEpsTimeModel(const std::vector<double>& residuals,
                             const std::vector<int>& episode,
                             double dt_s) {
  EpsTimeModel out;
  const std::size_t n = std::min(residuals.size(), episode.size());
  out.samples = static_cast<int>(n);
  out.dt_s = dt_s;
  if (!(dt_s > 0) || !std::isfinite(dt_s)) {
    out.why = "sampling interval dt_s = " + std::to_string(dt_s) +
              " (must be finite and > 0)";
    return out;
  }
  if (n < 3) {
    out.why = std::to_string(n) + " residuals (need more)";
    return out;
  }
  // Standardised residuals z = (r - mean) / sd: their autocorrelations
  // stand in for the copula's latent ones (equal for Gaussian eps; O(n),
  // no sort, so identification stays cheap).
  double mean = 0;
  for (std::size_t i = 0; i < n; ++i) mean += residuals[i];
  mean /= n;
  double var = 0;
  for (std::size_t i = 0; i < n; ++i)
    var += (residuals[i] - mean) * (residuals[i] - mean);
  var /= n;
  if (!(var > 0)) {
    out.why = "residuals have no spread";
    return out;
  }
  const double inv_sd = 1.0 / std::sqrt(var);
  std::vector<double> z(n);
  for (std::size_t i = 0; i < n; ++i) z[i] = (residuals[i] - mean) * inv_sd;
  double g0 = 0, g1 = 0, g2 = 0;
  std::size_t n1 = 0, n2 = 0;
  std::vector<int> lengths;
  int run = 1;
  for (std::size_t i = 0; i < n; ++i) {
    g0 += z[i] * z[i];
    if (i + 1 < n && episode[i + 1] == episode[i]) {
      g1 += z[i] * z[i + 1];
      ++n1;
      ++run;
    } else {
      lengths.push_back(run);
      run = 1;
    }
    if (i + 2 < n && episode[i + 2] == episode[i] &&
        episode[i + 1] == episode[i]) {
      g2 += z[i] * z[i + 2];
      ++n2;
    }
  }
  out.episodes = static_cast<int>(lengths.size());
  if (out.episodes < 2 || n2 < 50) {
    out.why = std::to_string(out.episodes) + " episodes and " +
              std::to_string(n2) +
              " lag-2 pairs (need >= 2 episodes and >= 50 pairs)";
    return out;
  }
  g0 /= n;
  g1 /= n1;
  g2 /= n2;
  // Method of moments (eps_time.h): phi from the decay between lags.
  double phi = g0 - g1 > 1e-9 ? (g1 - g2) / (g0 - g1) : 0.0;
  phi = std::clamp(phi, 0.0, 0.98);
  double within = (g0 - g1) / (1.0 - phi);  // (1 - f) g0
  within = std::clamp(within, 0.0, g0);
  const double f = g0 > 0 ? 1.0 - within / g0 : 0.0;
  out.phi = phi;
  out.corr_time_s = phi > 0 ? -dt_s / std::log(phi) : 0.0;
  out.offset_fraction = std::clamp(f, 0.0, 1.0);
  double n_eff = 0;
  for (int len : lengths) {
    const double var_mean = out.offset_fraction + (1.0 - out.offset_fraction) *
                                                      (1 + phi) /
                                                      ((1 - phi) * len);
    n_eff += std::min(static_cast<double>(len), 1.0 / var_mean);
  }
  out.effective_samples = n_eff;
  // Generalised Pareto lower tail by probability-weighted moments on the
  // excesses below the 2 % quantile (the lowest 2 %: a partial selection,
  // then a sort of that 2 % only).
  const std::size_t m_tail = static_cast<std::size_t>(0.02 * n);
  if (m_tail >= 20) {
    std::vector<double> low(residuals.begin(), residuals.begin() + n);
    std::nth_element(low.begin(), low.begin() + m_tail, low.end());
    const double u0 = low[m_tail];
    low.resize(m_tail);
    std::vector<double> y(m_tail);
    for (std::size_t i = 0; i < m_tail; ++i) y[i] = u0 - low[i];
    std::sort(y.begin(), y.end());  // ascending excesses
    double a0 = 0, a1 = 0;
    for (std::size_t i = 0; i < m_tail; ++i) {
      const double p = (i + 1 - 0.35) / m_tail;
      a0 += y[i];
      a1 += (1 - p) * y[i];
    }
    a0 /= m_tail;
    a1 /= m_tail;
    if (a0 > 0 && a0 - 2 * a1 > 0) {
      const double k = a0 / (a0 - 2 * a1) - 2;  // Hosking's k = -xi
      out.tail_xi = std::clamp(-k, -0.5, 1.0);
      out.tail_scale = 2 * a0 * a1 / (a0 - 2 * a1);
    }
  }
  out.min_instant_risk = std::max(1e-6, 1.0 / n_eff);
  out.valid = true;
  return out;
}

}  // namespace frictiond
