#pragma once
/// @file
/// Friction of a contact at one operating point as one distribution of mu,
/// the single numbers a simulator takes from it for a stated slip risk, and
/// the combination of two materials' distributions by a simulator's rule.
///
/// At an operating point x = (Fn, v, ...) the stochastic model of paper 000
///   mu = b0 + b1*v + b2*Fn + eps                       (eq. 1)
/// gives mu's predictive distribution
///   Q_mu(p) = m(x) + w(x) * Q_eps(p),   m(x) = beta' x,
///   w(x) = sqrt(sigma_eps^2 + x' P_beta x) / sigma_eps
/// where Q_eps is eps's empirical quantile function (stored at
/// EpsQuantileLevels(), linear in between) and w >= 1 widens it by the
/// coefficients' uncertainty (the same widening PredictMu uses for its 95 %
/// interval; w = 1 when P_beta = 0). The slip risk r of a constant
/// simulator mu is P(true mu < exported mu), so the exported sliding value is
/// Q_mu(r) (section IV-A's risk-based reasoning applied to a fixed mu).
///
/// Simulators give each geometry one mu and combine two geometries' values
/// by a rule (MuJoCo: max; Drake: harmonic mean 2ab/(a+b); PhysX: average).
/// CombineMuDistributions propagates two independent distributions through
/// such a rule.
///
/// @code
///   const InputValues x = {{"fn_n", 2.0}, {"v_mm_s", 20.0}};
///   MuDistribution d = CalcMuDistribution(model, x);
///   SimFrictionValues s = CalcSimFrictionValues(d, /*risk=*/0.05);
///   MuDistribution pair =
///       CombineMuDistributions(d, other, CombineRule::kHarmonicMean);
/// @endcode

#include <string>
#include <vector>

#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// mu at one operating point, represented by its quantiles at
/// EpsQuantileLevels() (linear in between, clamped beyond the outer levels),
/// the same representation the model stores for eps. Copyable and movable.
struct MuDistribution {
  double mean = 0.0;              ///< E[mu] (dimensionless)
  double sigma = 0.0;             ///< standard deviation of mu
  std::vector<double> levels;     ///< probability levels, ascending
  std::vector<double> quantiles;  ///< mu quantiles at `levels`, ascending
  bool extrapolated = false;      ///< an input lies outside the fitted range
  std::vector<std::string> extrapolated_inputs;

  /// Quantile of mu at probability p: linear between stored levels, the
  /// outer stored value beyond them. NaN when no quantiles are stored.
  double Quantile(double p) const;
};

/// The predictive distribution Q_mu(p) = m(x) + w(x) Q_eps(p) of the mu model
/// at `inputs` (fn_n, v_mm_s and any covariates the model uses; missing ones
/// take their fitted mean, as in PredictMu). For a model without stored eps
/// quantiles Q_eps is the normal quantile with sigma_eps.
MuDistribution CalcMuDistribution(const StochasticFrictionModel& model,
                                  const InputValues& inputs);

/// The numbers a simulator takes from a distribution for slip risk r.
struct SimFrictionValues {
  double risk = 0.0;        ///< slip risk r = P(true mu < sliding)
  double sliding = 0.0;     ///< Q_mu(r): the constant mu to simulate
  double range_low = 0.0;   ///< Q_mu(r): low end of a randomisation range
  double range_high = 0.0;  ///< Q_mu(1 - r): high end of that range
};

/// Smallest and largest accepted slip risk. The stored eps quantiles start
/// at level 0.001, so a smaller risk could not be told apart from 0.001;
/// above 0.5 the range [Q(r), Q(1-r)] would be inverted.
inline constexpr double kMinSlipRisk = 0.001;
inline constexpr double kMaxSlipRisk = 0.5;

/// Values for slip risk `risk`.
/// @throws std::invalid_argument when risk is outside [kMinSlipRisk,
/// kMaxSlipRisk] (message names "risk", its value and the rule) or when the
/// distribution holds no quantiles.
SimFrictionValues CalcSimFrictionValues(const MuDistribution& mu, double risk);

/// How a simulator turns two geometries' mu into the contact's mu.
enum class CombineRule {
  kMax,           ///< max(a, b): MuJoCo (geoms of equal priority)
  kHarmonicMean,  ///< 2ab / (a + b): Drake (0 when a + b = 0)
  kAverage,       ///< (a + b) / 2: PhysX's default combine mode
};

/// "max", "harmonic" or "average".
const char* CombineRuleName(CombineRule rule);
/// "MuJoCo", "Drake" or "PhysX".
const char* CombineRuleEngine(CombineRule rule);
/// Parses CombineRuleName()'s output.
/// @throws std::invalid_argument naming "rule", the value and the choices.
CombineRule ParseCombineRule(const std::string& name);

/// Distribution of rule(A, B) for independent A ~ a and B ~ b. Each side is
/// discretised into `samples_per_side` equally likely values (its quantiles
/// at (i + 0.5) / n, clamped at 0 because no simulator accepts a negative
/// mu); the n^2 combinations give the mean, sigma and quantiles at
/// EpsQuantileLevels(). Point masses combine exactly.
/// @throws std::invalid_argument when either side has no quantiles or
/// samples_per_side is outside [2, 2000].
MuDistribution CombineMuDistributions(const MuDistribution& a,
                                      const MuDistribution& b,
                                      CombineRule rule,
                                      int samples_per_side = 200);

}  // namespace frictiond
