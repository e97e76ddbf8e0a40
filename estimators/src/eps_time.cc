#include "frictiond/estimators/eps_time.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <vector>

#include "frictiond/estimators/grip_force.h"
#include "frictiond/estimators/stats.h"
#include "frictiond/estimators/stochastic_model.h"

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

// S_n(b) of the unit AR(1), tabulated once per (n, phi) on b in
// [-6, 4.5] and interpolated (Catmull-Rom in log(-log S)).
class SurvivalTable {
 public:
  SurvivalTable() = default;
  SurvivalTable(int n, double phi) : n_(n) {
    y_.resize(kNb);
    for (int k = 0; k < kNb; ++k) {
      const double sv = CalcAr1Survival(kBLo + k * kBStep, n, phi);
      const double l = sv > 1e-300 ? -std::log(sv) : 690.0;
      y_[k] = std::log(std::max(l, 1e-300));
    }
  }

  // S_n(b).
  double operator()(double b) const {
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

 private:
  static constexpr double kBLo = -6.0, kBHi = 4.5, kBStep = 0.25;
  static constexpr int kNb = 43;  // (kBHi - kBLo) / kBStep + 1
  int n_ = 1;
  std::vector<double> y_;
};

// P(any z_t < c) of one hold, with S_n tabulated once per (n, phi).
class HoldCrossing {
 public:
  HoldCrossing(int n, double phi, double f) : n_(n), phi_(phi), f_(f) {
    CheckPhi(n, phi);
    if (!(f >= 0 && f <= 1))
      throw std::invalid_argument("offset_fraction = " + std::to_string(f) +
                                  " (must be in [0, 1])");
    if (n == 1 || f >= 0.9999 || f <= 0.0) return;  // no table needed
    survival_ = SurvivalTable(n, phi);
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
                  survival_((c - sf * a) / sr);
    }
    return std::clamp(1.0 - integral, NormalCdf(c), 1.0);
  }

 private:
  int n_;
  double phi_, f_;
  SurvivalTable survival_;
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

namespace {

// The offset decomposition's stored distributions are read with the rule
// of CalcEpsQuantileExtended (grip_force.h: CalcStoredQuantileExtended,
// CalcStoredCdfExtended).

void CheckOffsetModel(const EpsTimeModel& t) {
  const std::size_t levels = EpsQuantileLevels().size();
  if (!t.offset.valid || t.offset.offset_quantiles.size() != levels ||
      t.offset.within_quantiles.size() != levels ||
      (!t.offset.innovation_quantiles.empty() &&
       t.offset.innovation_quantiles.size() != levels))
    throw std::invalid_argument(
        "eps_time.offset_decomposition: not identified (no valid offset and "
        "within-episode quantiles)");
}

// S_n(b) = P(u_0..u_{n-1} >= b) of the linear AR(1) u_t = phi u_{t-1} +
// e_t, e_t ~ E i.i.d. (the stored innovation quantiles), u_0 ~ H: a Markov
// chain on cells of width h over [lo, hi] (cell-averaged transition
// probabilities from E's CDF, mass below b absorbed), iterated until the
// quasi-stationary decay rate has converged, then geometric (as
// CalcAr1Survival). Tabulated at cell boundaries b_k, interpolated in
// log(-log S).
class LinearSurvivalTable {
 public:
  LinearSurvivalTable() = default;
  LinearSurvivalTable(const EpsOffsetModel& m, double phi, int n) : n_(n) {
    const auto& levels = EpsQuantileLevels();
    auto level_index = [&](double p) {
      return static_cast<std::size_t>(
          std::lower_bound(levels.begin(), levels.end(), p - 1e-12) -
          levels.begin());
    };
    const std::vector<double>& qh = m.within_quantiles;
    const double sd_u =
        std::max(1e-300, 0.5 * (qh[level_index(0.84)] - qh[level_index(0.16)]));
    auto h_cdf = [&](double x) {
      return CalcStoredCdfExtended(
          qh, m.within_tail_xi, m.within_tail_scale, x);
    };
    auto e_cdf = [&](double x) {
      return CalcStoredCdfExtended(m.innovation_quantiles,
                                   m.innovation_tail_xi,
                                   m.innovation_tail_scale,
                                   x);
    };
    // Grid: from H's 1e-7 quantile (floored at -12 sd) to 8 sd above its
    // top quantile; at most kCells cells, at most a fifth of e's sd wide.
    lo_ = std::max(CalcStoredQuantileExtended(
                       qh, m.within_tail_xi, m.within_tail_scale, 1e-7),
                   qh[level_index(0.5)] - 12 * sd_u);
    const double hi = qh.back() + 8 * sd_u;
    const double sd_e = sd_u * std::sqrt(std::max(1e-6, 1 - phi * phi));
    h_ = std::max(sd_e / 5, (hi - lo_) / kCells);
    const int cells = static_cast<int>(std::ceil((hi - lo_) / h_));
    // P[i][j]: from the centre of cell i into cell j.
    std::vector<double> kernel(static_cast<std::size_t>(cells) * cells);
    std::vector<double> edge(cells + 1);
    for (int i = 0; i < cells; ++i) {
      const double x = lo_ + (i + 0.5) * h_;
      for (int j = 0; j <= cells; ++j) edge[j] = e_cdf(lo_ + j * h_ - phi * x);
      for (int j = 0; j < cells; ++j)
        kernel[static_cast<std::size_t>(i) * cells + j] = edge[j + 1] - edge[j];
    }
    std::vector<double> start(cells), mass(cells), next(cells);
    for (int j = 0; j < cells; ++j)
      start[j] = h_cdf(lo_ + (j + 1) * h_) - h_cdf(lo_ + j * h_);
    // Table at every kStride-th boundary (b_k = lo_ + k h).
    stride_ = std::max(1, cells / kPoints);
    for (int k0 = 0; k0 < cells; k0 += stride_) {
      double surv = 0;
      for (int j = k0; j < cells; ++j) surv += start[j];
      std::copy(start.begin(), start.end(), mass.begin());
      double last_ratio = -1;
      int stable = 0;
      for (int t = 1; t < n && surv > 1e-300; ++t) {
        std::fill(next.begin() + k0, next.end(), 0.0);
        for (int i = k0; i < cells; ++i) {
          const double a = mass[i];
          if (a == 0.0) continue;
          const double* row =
              kernel.data() + static_cast<std::size_t>(i) * cells;
          for (int j = k0; j < cells; ++j) next[j] += a * row[j];
        }
        double total = 0;
        for (int j = k0; j < cells; ++j) total += next[j];
        const double ratio = surv > 0 ? total / surv : 0.0;
        mass.swap(next);
        surv = total;
        if (std::fabs(ratio - last_ratio) < 1e-10 * ratio) {
          if (++stable >= 3) {
            surv *= std::pow(ratio, n - 1 - t);
            break;
          }
        } else {
          stable = 0;
        }
        last_ratio = ratio;
      }
      const double l = surv > 1e-300 ? -std::log(surv) : 690.0;
      y_.push_back(std::log(std::max(l, 1e-300)));
    }
    // Below the grid: at most n independent looks.
    h_lo_ = h_cdf(lo_);
  }

  double operator()(double b) const {
    if (!(b >= lo_)) return std::max(0.0, 1.0 - n_ * h_lo_);
    const double u = (b - lo_) / (h_ * stride_);
    const int nb = static_cast<int>(y_.size());
    if (u >= nb - 1) return std::exp(-std::exp(y_.back()));
    const int k = static_cast<int>(u);
    const double t = u - k;
    return std::exp(-std::exp(y_[k] + t * (y_[k + 1] - y_[k])));
  }

 private:
  static constexpr int kCells = 320, kPoints = 64;
  int n_ = 1, stride_ = 1;
  double lo_ = 0, h_ = 1, h_lo_ = 0;
  std::vector<double> y_;
};

}  // namespace

namespace internal {

// The hold of n >= 2 samples under the offset decomposition:
//   Y_t = a + u_t,  a ~ G once per episode,  u_t = H^-1(Phi(w_t)),
//   eps_t = F^-1(K(Y_t)),  K the CDF of Y_t,
// so a slip at eps level e is Y_t < y = K^-1(F(e)) and
//   P(any Y_t < y) = 1 - E_a[ S_n(Phi^-1(H(y - a))) ].
// E_a is Simpson in the normal score s of a = G^-1(Phi(s)) on [-8.5, 8.5].
class OffsetHold {
 public:
  OffsetHold(const EpsTimeModel& t, int n) : m_(t.offset) {
    CheckPhi(n, t.phi);
    CheckOffsetModel(t);
    const EpsOffsetModel& m = m_;
    linear_ = !m.innovation_quantiles.empty();
    if (n >= 2 && linear_) linear_survival_ = LinearSurvivalTable(m, t.phi, n);
    if (n >= 2 && !linear_) survival_ = SurvivalTable(n, t.phi);
    constexpr int kIntervals = 850;  // step 0.02 in the normal score
    const double step = 17.0 / kIntervals;
    a_.resize(kIntervals + 1);
    w_.resize(kIntervals + 1);
    double sum = 0;
    for (int j = 0; j <= kIntervals; ++j) {
      const double s = -8.5 + j * step;
      a_[j] = CalcStoredQuantileExtended(m.offset_quantiles,
                                         m.offset_tail_xi,
                                         m.offset_tail_scale,
                                         NormalCdf(s));
      w_[j] = step / 3.0 *
              (j == 0 || j == kIntervals ? 1.0 : (j % 2 == 1 ? 4.0 : 2.0)) *
              std::exp(-0.5 * s * s) / std::sqrt(2 * M_PI);
      sum += w_[j];
    }
    for (double& w : w_) w /= sum;
    // Bracket of y: below it K and the crossing are < ~1e-12 (n <= 360,001
    // samples), above it both are 1.
    y_lo_ =
        CalcStoredQuantileExtended(
            m.offset_quantiles, m.offset_tail_xi, m.offset_tail_scale, 1e-18) +
        CalcStoredQuantileExtended(
            m.within_quantiles, m.within_tail_xi, m.within_tail_scale, 1e-18);
    y_hi_ = m.offset_quantiles.back() + m.within_quantiles.back();
  }

  // K(y) = P(a + u < y).
  double Cdf(double y) const {
    double sum = 0;
    for (std::size_t j = 0; j < a_.size(); ++j)
      sum += w_[j] * Within(y - a_[j]);
    return std::clamp(sum, 0.0, 1.0);
  }

  // P(any Y_t < y) over the hold.
  double Crossing(double y) const {
    double sum = 0;
    for (std::size_t j = 0; j < a_.size(); ++j) {
      if (linear_) {
        sum += w_[j] * linear_survival_(y - a_[j]);
        continue;
      }
      const double h = Within(y - a_[j]);
      if (h <= 1e-300) {  // S_n = exp(-n h) to far below rounding
        sum += w_[j];
      } else if (h < 1.0) {
        sum += w_[j] * survival_(NormalQuantile(h));
      }
    }
    return std::clamp(1.0 - sum, 0.0, 1.0);
  }

  // P(slip during the hold) from the per-instant probability p.
  double FromInstant(double p) const {
    const double y = Solve([&](double v) { return Cdf(v); }, p);
    return std::clamp(Crossing(y), p, 1.0);
  }

  // The per-instant probability p with FromInstant(p) = risk.
  double InstantFor(double risk) const {
    const double y = Solve([&](double v) { return Crossing(v); }, risk);
    return std::min(risk, Cdf(y));
  }

 private:
  double Within(double x) const {
    const EpsOffsetModel& m = m_;
    return CalcStoredCdfExtended(
        m.within_quantiles, m.within_tail_xi, m.within_tail_scale, x);
  }

  // y with g(y) = target for g increasing: bisection on [y_lo_, y_hi_].
  template <class G>
  double Solve(const G& g, double target) const {
    double lo = y_lo_, hi = y_hi_;
    const double tol = 1e-12 * std::max(1.0, std::fabs(hi - lo));
    for (int it = 0; it < 200 && hi - lo > tol; ++it) {
      const double mid = 0.5 * (lo + hi);
      (g(mid) < target ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
  }

  EpsOffsetModel m_;     // a copy: the rule may outlive the model
  bool linear_ = false;  // u_t a linear AR(1) (innovation quantiles)
  SurvivalTable survival_;
  LinearSurvivalTable linear_survival_;
  std::vector<double> a_, w_;  // nodes and weights of G
  double y_lo_ = 0, y_hi_ = 0;
};

}  // namespace internal

HoldSlipRule::HoldSlipRule(const EpsTimeModel& t, int n)
    : n_(n), phi_(t.phi), offset_fraction_(t.offset_fraction) {
  if (n < 1)
    throw std::invalid_argument("n = " + std::to_string(n) + " (must be >= 1)");
  if (n >= 2 && t.offset.valid)
    impl_ = std::make_unique<const internal::OffsetHold>(t, n);
}

HoldSlipRule::~HoldSlipRule() = default;
HoldSlipRule::HoldSlipRule(HoldSlipRule&&) noexcept = default;
HoldSlipRule& HoldSlipRule::operator=(HoldSlipRule&&) noexcept = default;

double HoldSlipRule::SlipFromInstant(double p) const {
  if (!(p >= 0 && p <= 1))
    throw std::invalid_argument("instant risk = " + std::to_string(p) +
                                " (must be in [0, 1])");
  if (n_ == 1) return p;
  if (!impl_)
    return CalcHoldCrossingProbability(
        NormalQuantile(p), n_, phi_, offset_fraction_);
  if (p <= 0.0 || p >= 1.0) return p;
  return impl_->FromInstant(p);
}

double HoldSlipRule::InstantRiskFor(double risk) const {
  if (!(risk > 0 && risk < 1))
    throw std::invalid_argument("risk = " + std::to_string(risk) +
                                " (must be in (0, 1))");
  if (n_ == 1) return risk;
  if (!impl_)
    return NormalCdf(CalcHoldCrossingLevel(risk, n_, phi_, offset_fraction_));
  return impl_->InstantFor(risk);
}

double CalcHoldSlipFromInstant(double p, int n, const EpsTimeModel& t) {
  return HoldSlipRule(t, n).SlipFromInstant(p);
}

double CalcInstantRiskForHold(double risk, int n, const EpsTimeModel& t) {
  return HoldSlipRule(t, n).InstantRiskFor(risk);
}

double CalcOffsetQuantile(const EpsTimeModel& t, double p) {
  CheckOffsetModel(t);
  const EpsOffsetModel& m = t.offset;
  return CalcStoredQuantileExtended(
      m.offset_quantiles, m.offset_tail_xi, m.offset_tail_scale, p);
}

double CalcWithinQuantile(const EpsTimeModel& t, double p) {
  CheckOffsetModel(t);
  const EpsOffsetModel& m = t.offset;
  return CalcStoredQuantileExtended(
      m.within_quantiles, m.within_tail_xi, m.within_tail_scale, p);
}

double CalcInnovationQuantile(const EpsTimeModel& t, double p) {
  CheckOffsetModel(t);
  const EpsOffsetModel& m = t.offset;
  if (m.innovation_quantiles.empty())
    throw std::invalid_argument(
        "eps_time.offset_decomposition: no innovation quantiles (u_t is the "
        "Gaussian copula AR(1))");
  return CalcStoredQuantileExtended(
      m.innovation_quantiles, m.innovation_tail_xi, m.innovation_tail_scale, p);
}

double CalcOffsetSumCdf(const EpsTimeModel& t, double y) {
  return internal::OffsetHold(t, 1).Cdf(y);
}

}  // namespace frictiond

namespace frictiond {

namespace {

// Generalised Pareto lower tail by probability-weighted moments on the
// excesses below the 2 % quantile of x (the lowest 2 %: a partial
// selection, then a sort of that 2 % only). Leaves *xi, *scale unchanged
// when there are fewer than 20 excesses or the moments are degenerate.
void FitLowerTail(std::vector<double> low, double* xi, double* scale) {
  const std::size_t m_tail = static_cast<std::size_t>(0.02 * low.size());
  if (m_tail < 20) return;
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
    *xi = std::clamp(-k, -0.5, 1.0);
    *scale = 2 * a0 * a1 / (a0 - 2 * a1);
  }
}

// Var(mean of n consecutive samples) / Var(one sample) for a stationary
// AR(1) with coefficient phi < 1:
//   (1/n) [1 + 2 sum_{j=1}^{n-1} (1 - j/n) phi^j].
double MeanVarianceFactor(int n, double phi) {
  if (n <= 1) return 1.0;
  const double tail = phi / (1 - phi) - phi * (1 - std::pow(phi, n)) /
                                            (n * (1 - phi) * (1 - phi));
  return std::clamp((1 + 2 * tail) / n, 0.0, 1.0);
}

// Quantiles at EpsQuantileLevels() of the stationary law of the linear
// AR(1) u_t = phi u_{t-1} + e_t, e_t ~ E (quantiles eq with their lower
// tail): the chain on 560 cells over +-14 sd_u iterated from N(0, sd_u^2)
// until phi^t < 1e-3 (the start's share of u_t is then negligible).
std::vector<double> StationaryQuantiles(const std::vector<double>& eq,
                                        double xi,
                                        double scale,
                                        double phi,
                                        double sd_u) {
  constexpr int kCells = 560;
  const double lo = -14 * sd_u, h = 28 * sd_u / kCells;
  std::vector<double> kernel(static_cast<std::size_t>(kCells) * kCells);
  std::vector<double> edge(kCells + 1);
  for (int i = 0; i < kCells; ++i) {
    const double x = lo + (i + 0.5) * h;
    for (int j = 0; j <= kCells; ++j)
      edge[j] =
          j == 0 ? 0.0
          : j == kCells
              ? 1.0  // the grid's ends keep the mass beyond them
              : CalcStoredCdfExtended(eq, xi, scale, lo + j * h - phi * x);
    for (int j = 0; j < kCells; ++j)
      kernel[static_cast<std::size_t>(i) * kCells + j] = edge[j + 1] - edge[j];
  }
  std::vector<double> mass(kCells), next(kCells);
  for (int j = 0; j < kCells; ++j)
    mass[j] =
        NormalCdf((lo + (j + 1) * h) / sd_u) - NormalCdf((lo + j * h) / sd_u);
  const int steps =
      phi > 0 ? static_cast<int>(std::ceil(std::log(1e-3) / std::log(phi))) : 1;
  for (int t = 0; t < steps; ++t) {
    std::fill(next.begin(), next.end(), 0.0);
    for (int i = 0; i < kCells; ++i) {
      const double a = mass[i];
      if (a < 1e-300) continue;
      const double* row = kernel.data() + static_cast<std::size_t>(i) * kCells;
      for (int j = 0; j < kCells; ++j) next[j] += a * row[j];
    }
    mass.swap(next);
  }
  // Quantiles: the CDF is linear within a cell.
  std::vector<double> q;
  double cdf = 0;
  int j = 0;
  for (double p : EpsQuantileLevels()) {
    while (j < kCells - 1 && cdf + mass[j] < p) cdf += mass[j++];
    const double w =
        mass[j] > 0 ? std::clamp((p - cdf) / mass[j], 0.0, 1.0) : 0.5;
    q.push_back(lo + (j + w) * h);
  }
  return q;
}

// The offset decomposition eps = a + u_t (eps_time.h) from the residuals
// r (in time order, runs of `lengths`), their mean and the identified phi
// and f. Leaves *out not valid when f is 0 or 1, the offset variance is not
// positive, or fewer than 100 episodes have a reliable mean or fewer than
// 1000 samples a usable deviation.
void FitOffsetModel(const std::vector<double>& r,
                    const std::vector<int>& lengths,
                    double mean,
                    double phi,
                    double f,
                    EpsOffsetModel* out) {
  *out = EpsOffsetModel{};
  if (!(f > 0.0 && f < 1.0)) return;
  std::vector<double> offsets, within, innovations, power, means, factors;
  means.reserve(lengths.size());
  factors.reserve(lengths.size());
  within.reserve(r.size());
  // Pass 1: episode means m_k, their variance factors c_k, deviations,
  // innovations and the moments of both.
  double sum_d2 = 0, sum_weight = 0, sum_m2 = 0, sum_c = 0;
  std::size_t i0 = 0;
  for (int len : lengths) {
    double sum = 0;
    for (int i = 0; i < len; ++i) sum += r[i0 + i];
    const double m = sum / len;
    const double c = MeanVarianceFactor(len, phi);
    means.push_back(m);
    factors.push_back(c);
    sum_m2 += (m - mean) * (m - mean);
    sum_c += c;
    // A deviation u_t - mean(u) has variance v_t var_u with
    //   v_t = 1 - 2 k_t + c,  k_t = (1/n) sum_s phi^|t - s|
    // (larger at the episode's ends; their mean over t is 1 - c): scaled
    // back by 1 / sqrt(v_t), so that Gaussian u gives Gaussian deviations
    // (a common scale would mix variances: heavier tails than u's).
    // Samples with v_t < 0.25 skipped.
    if (len >= 2) {
      power.resize(len + 1);  // phi^j, j = 0..len (no underflow trouble)
      power[0] = 1.0;
      for (int j = 1; j <= len; ++j) power[j] = power[j - 1] * phi;
      // Innovations of the linear AR(1) from the deviations (the episode
      // mean leaves only (1 - phi) mean(u), small against e_t).
      for (int i = 1; i < len; ++i)
        innovations.push_back((r[i0 + i] - m) - phi * (r[i0 + i - 1] - m));
      for (int i = 0; i < len; ++i) {
        const double d = r[i0 + i] - m;
        sum_d2 += d * d;
        // sum_{s <= t} phi^(t-s) + sum_{s >= t} phi^(s-t) - 1
        const double k =
            ((1 - power[i + 1]) + (1 - power[len - i])) / (1 - phi) - 1;
        const double v = 1 - 2 * k / len + c;
        if (v >= 0.25) within.push_back(d / std::sqrt(v));
      }
      sum_weight += len * (1 - c);
    }
    i0 += len;
  }
  if (!(sum_weight > 0) || lengths.empty()) return;
  // Method of moments on the variances: E sum_t d^2 = n (1 - c) var_u and
  // E (m - mean)^2 = var_a + c var_u (no use of f: its estimate carries
  // phi's small-sample bias).
  const double var_u = sum_d2 / sum_weight;
  const double episodes = static_cast<double>(lengths.size());
  const double var_a = sum_m2 / episodes - sum_c / episodes * var_u;
  if (!(var_a > 0)) return;
  // Pass 2: an episode mean m = a + mean(u) has variance var_a + c var_u.
  // Scaling its deviation by sqrt(rho), rho = var_a / (var_a + c var_u),
  // gives a's variance (exact for Gaussian a and u; for a heavy-tailed a
  // the far tail comes out short by up to 1 - sqrt(rho)). Only episodes
  // whose mean is mostly offset (rho >= 0.5) are used.
  offsets.reserve(lengths.size());
  std::vector<double> raw;
  double noise = 0;  // mean c_k var_u over the episodes used
  for (std::size_t k = 0; k < means.size(); ++k) {
    const double rho = var_a / (var_a + factors[k] * var_u);
    if (rho >= 0.5) {
      offsets.push_back(mean + (means[k] - mean) * std::sqrt(rho));
      raw.push_back(means[k]);
      noise += factors[k] * var_u;
    }
  }
  if (raw.empty()) return;
  noise /= raw.size();
  if (offsets.size() < 100 || within.size() < 1000) return;
  out->episodes_used = static_cast<int>(offsets.size());
  FitLowerTail(offsets, &out->offset_tail_xi, &out->offset_tail_scale);
  FitLowerTail(within, &out->within_tail_xi, &out->within_tail_scale);
  // G's quantiles: those of the raw means with the noise taken out level
  // by level, q_a(p) - q_m(0.5) = sign sqrt((q_m(p) - q_m(0.5))^2 - z_p^2
  // noise), z_p = Phi^-1(p): exact for Gaussian a; in a heavy tail, where
  // the noise barely moves the quantiles, it barely shrinks them (variance
  // matching would shrink every level by sqrt(rho) and widen a narrow
  // body). Below the 0.001 level: the GPD of the variance-matched means.
  {
    const auto& levels = EpsQuantileLevels();
    std::vector<double> q = SelectQuantiles(&raw, levels);
    std::vector<double> median_only = {0.5};
    const double med = SelectQuantiles(&raw, median_only)[0];
    for (std::size_t k = 0; k < q.size(); ++k) {
      const double d = q[k] - med, z = NormalQuantile(levels[k]);
      const double d2 = std::max(0.0, d * d - z * z * noise);
      q[k] = med + (d < 0 ? -1.0 : 1.0) * std::sqrt(d2);
      if (k > 0) q[k] = std::max(q[k], q[k - 1]);
    }
    out->offset_quantiles = q;
  }
  out->within_quantiles = SelectQuantiles(&within, EpsQuantileLevels());
  if (innovations.size() >= 1000) {
    FitLowerTail(
        innovations, &out->innovation_tail_xi, &out->innovation_tail_scale);
    out->innovation_quantiles =
        SelectQuantiles(&innovations, EpsQuantileLevels());
    // H as the stationary law of that AR(1): consistent with the chain of
    // the hold, and free of the deviations' rescaling (which inflates a
    // heavy tail: one shock moves u_t fully but the episode mean little).
    // The deviations' GPD tail shape is kept below the 0.001 level.
    out->within_quantiles = StationaryQuantiles(out->innovation_quantiles,
                                                out->innovation_tail_xi,
                                                out->innovation_tail_scale,
                                                phi,
                                                std::sqrt(var_u));
  }
  out->valid = true;
}

}  // namespace

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
  FitLowerTail(std::vector<double>(residuals.begin(), residuals.begin() + n),
               &out.tail_xi,
               &out.tail_scale);
  FitOffsetModel(
      residuals, lengths, mean, phi, out.offset_fraction, &out.offset);
  out.min_instant_risk = std::max(1e-6, 1.0 / n_eff);
  out.valid = true;
  return out;
}

}  // namespace frictiond
