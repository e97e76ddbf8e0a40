#include "frictiond/estimators/contact_friction.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frictiond/estimators/number_text.h"
#include "frictiond/estimators/stats.h"

namespace frictiond {

namespace {

double Combine(CombineRule rule, double a, double b) {
  switch (rule) {
    case CombineRule::kMax:
      return std::max(a, b);
    case CombineRule::kHarmonicMean:
      return a + b > 0 ? 2 * a * b / (a + b) : 0.0;
    case CombineRule::kAverage:
      return 0.5 * (a + b);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

double MuDistribution::Quantile(double p) const {
  const std::size_t n = std::min(levels.size(), quantiles.size());
  if (n == 0 || std::isnan(p)) return std::numeric_limits<double>::quiet_NaN();
  if (p <= levels.front()) return quantiles.front();
  if (p >= levels[n - 1]) return quantiles[n - 1];
  const auto it = std::upper_bound(levels.begin(), levels.begin() + n, p);
  const std::size_t k = it - levels.begin();
  const double w = (p - levels[k - 1]) / (levels[k] - levels[k - 1]);
  return quantiles[k - 1] + w * (quantiles[k] - quantiles[k - 1]);
}

MuDistribution CalcMuDistribution(const StochasticFrictionModel& model,
                                  const InputValues& inputs) {
  const MuPrediction p = PredictMu(model, inputs);
  MuDistribution d;
  d.mean = p.mu;
  d.sigma = p.sigma;
  d.extrapolated = p.extrapolated;
  d.extrapolated_inputs = p.extrapolated_inputs;
  d.levels = EpsQuantileLevels();
  d.quantiles.reserve(d.levels.size());
  const double sigma_eps = model.mu.sigma_eps;
  for (double level : d.levels) {
    if (sigma_eps > 0) {
      const double widen = p.sigma / sigma_eps;
      d.quantiles.push_back(p.mu + widen * CalcEpsQuantile(model.mu, level));
    } else {
      // No residual spread: only the coefficients' uncertainty (normal).
      d.quantiles.push_back(p.mu + p.sigma * NormalQuantile(level));
    }
  }
  return d;
}

SimFrictionValues CalcSimFrictionValues(const MuDistribution& mu, double risk) {
  if (!(risk >= kMinSlipRisk && risk <= kMaxSlipRisk)) {
    throw std::invalid_argument(
        "risk = " + NumberText(risk) + " (must be in [" +
        NumberText(kMinSlipRisk) + ", " + NumberText(kMaxSlipRisk) +
        "]: the smallest stored quantile level is 0.001, and above 0.5 the "
        "range [Q(risk), Q(1 - risk)] would be inverted)");
  }
  if (mu.quantiles.empty() || mu.levels.size() != mu.quantiles.size())
    throw std::invalid_argument("mu: the distribution holds no quantiles");
  SimFrictionValues v;
  v.risk = risk;
  v.sliding = mu.Quantile(risk);
  v.range_low = v.sliding;
  v.range_high = mu.Quantile(1.0 - risk);
  return v;
}

const char* CombineRuleName(CombineRule rule) {
  switch (rule) {
    case CombineRule::kMax:
      return "max";
    case CombineRule::kHarmonicMean:
      return "harmonic";
    case CombineRule::kAverage:
      return "average";
  }
  return "?";
}

const char* CombineRuleEngine(CombineRule rule) {
  switch (rule) {
    case CombineRule::kMax:
      return "MuJoCo";
    case CombineRule::kHarmonicMean:
      return "Drake";
    case CombineRule::kAverage:
      return "PhysX";
  }
  return "?";
}

CombineRule ParseCombineRule(const std::string& name) {
  for (CombineRule r :
       {CombineRule::kMax, CombineRule::kHarmonicMean, CombineRule::kAverage}) {
    if (name == CombineRuleName(r)) return r;
  }
  throw std::invalid_argument("rule = '" + name.substr(0, 64) +
                              "' (must be one of max, harmonic, average)");
}

MuDistribution CombineMuDistributions(const MuDistribution& a,
                                      const MuDistribution& b,
                                      CombineRule rule,
                                      int samples_per_side) {
  if (a.quantiles.empty() || b.quantiles.empty())
    throw std::invalid_argument("mu: a distribution holds no quantiles");
  if (samples_per_side < 2 || samples_per_side > 2000)
    throw std::invalid_argument(
        "samples_per_side = " + std::to_string(samples_per_side) +
        " (must be in [2, 2000])");
  const int n = samples_per_side;
  std::vector<double> xa(n), xb(n);
  for (int i = 0; i < n; ++i) {
    const double p = (i + 0.5) / n;
    xa[i] = std::max(0.0, a.Quantile(p));
    xb[i] = std::max(0.0, b.Quantile(p));
  }
  std::vector<double> c;
  c.reserve(static_cast<std::size_t>(n) * n);
  for (double u : xa) {
    for (double w : xb) c.push_back(Combine(rule, u, w));
  }
  std::sort(c.begin(), c.end());
  MuDistribution out;
  // Compensated (Neumaier) sum: n^2 terms would otherwise lose ~1e-13.
  double sum = 0.0, carry = 0.0;
  for (double x : c) {
    const double t = sum + x;
    carry += std::fabs(sum) >= std::fabs(x) ? (sum - t) + x : (x - t) + sum;
    sum = t;
  }
  out.mean = (sum + carry) / c.size();
  double ss = 0.0;
  for (double x : c) ss += (x - out.mean) * (x - out.mean);
  out.sigma = std::sqrt(ss / c.size());
  out.levels = EpsQuantileLevels();
  out.quantiles.reserve(out.levels.size());
  for (double level : out.levels)
    out.quantiles.push_back(SortedQuantile(c, level));
  out.extrapolated = a.extrapolated || b.extrapolated;
  out.extrapolated_inputs = a.extrapolated_inputs;
  for (const auto& s : b.extrapolated_inputs) {
    if (std::find(out.extrapolated_inputs.begin(),
                  out.extrapolated_inputs.end(),
                  s) == out.extrapolated_inputs.end())
      out.extrapolated_inputs.push_back(s);
  }
  return out;
}

}  // namespace frictiond
