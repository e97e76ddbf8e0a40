#pragma once
/// @file
/// Fast draws of mu from a fetched stochastic model, for simulators and
/// domain randomisation (the Python module's sample_mu and
/// sample_mu_episodes call these):
///
///   mu = b0 + b1*v + b2*Fn + eps,   eps = Q_eps(u),  u ~ U(0, 1)   (eq. 1)
///
/// where Q_eps is the empirical eps quantile function of the model
/// (CalcEpsQuantile, linear between the stored quantiles). MuSampler gives
/// exactly the values of PredictMu(model, fn_n, v_mm_s).mu and
/// CalcEpsQuantile(model.mu, p) (the unit test checks equality bit for bit),
/// but without allocation and with an O(1) table lookup of the quantile
/// segment instead of a binary search, so it can draw ~1e8 samples/s.
///
/// Draws leave out the uncertainty of the coefficients (they sample the
/// model's eps, not a posterior predictive); PredictMu's sigma and interval
/// include it.
///
/// Usage:
/// @code
///   const frictiond::MuSampler sampler(*client.FetchModel("felt").stochastic);
///   std::mt19937_64 gen(7);
///   std::uniform_real_distribution<double> unif(0.0, 1.0);
///   double mu = sampler.Draw(/*fn_n=*/2.0, /*v_mm_s=*/20.0, unif(gen));
/// @endcode

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// A stream of uniform doubles in [0, 1): a C function and its state, the
/// shape of NumPy's bitgen_t::next_double, so a numpy.random.Generator can
/// drive the C++ draws (same numbers as its random()).
struct UniformSource {
  double (*next)(void* state) = nullptr;
  void* state = nullptr;
  double operator()() const { return next(state); }
};

/// PredictMu's numbers at (fn_n, v_mm_s), without its names and allocations.
struct MuPoint {
  double mu = 0.0;            ///< mean mu [-]
  double sigma = 0.0;         ///< sqrt(sigma_eps^2 + x' P_beta x) [-]
  double lo95 = 0.0;          ///< 2.5 % quantile [-]
  double hi95 = 0.0;          ///< 97.5 % quantile [-]
  bool extrapolated = false;  ///< fn_n or v_mm_s outside its fitted range
};

/// Draws mu from a stochastic model, and evaluates PredictMu's numbers on
/// many points (the Python module's predict). Copyable; keeps a copy of the
/// model, so the model it was built from may go away. Thread-safe (const).
class MuSampler {
 public:
  /// @throws std::invalid_argument when the model has no coefficients
  /// (beta's size differs from the number of terms).
  explicit MuSampler(const StochasticFrictionModel& model);

  /// Mean mu at (fn_n [N], v_mm_s [mm/s]); inputs of an extended model other
  /// than these take their fitted mean. Equals PredictMu(model, fn_n,
  /// v_mm_s).mu.
  double CalcMean(double fn_n, double v_mm_s) const;
  /// mu, sigma, interval and extrapolation at (fn_n, v_mm_s). Equals the
  /// same fields of PredictMu(model, fn_n, v_mm_s) bit for bit (the
  /// extrapolated input names are left out).
  MuPoint CalcPrediction(double fn_n, double v_mm_s) const;
  /// Empirical eps quantile at probability p. Equals
  /// CalcEpsQuantile(model.mu, p).
  double CalcEpsQuantile(double p) const;
  /// eps scale factor at (fn_n, v_mm_s): CalcEpsScaleFactor(model, {fn_n,
  /// v_mm_s}) of a model with an eps scale (eps_scale.h), exactly 1
  /// without one.
  double CalcEpsScale(double fn_n, double v_mm_s) const;
  /// One draw: CalcMean(fn_n, v_mm_s) + CalcEpsScale(fn_n, v_mm_s) *
  /// CalcEpsQuantile(u), u in [0, 1) (without an eps scale model the
  /// factor is 1: CalcMean + CalcEpsQuantile).
  double Draw(double fn_n, double v_mm_s, double u) const {
    return CalcMean(fn_n, v_mm_s) +
           CalcEpsScale(fn_n, v_mm_s) * CalcEpsQuantile(u);
  }

  const StochasticFrictionModel& model() const { return model_; }

 private:
  // Where term k's input comes from.
  // (kFnLinear, kVLinear: a linear term, x = the input itself.)
  // (kFnV, kFnTimes, kVTimes: a product column "x*y" of fn_n and v_mm_s,
  // or of one of them and a constant factor, eps_scale.h.)
  enum class Source {
    kFn,
    kV,
    kFnLinear,
    kVLinear,
    kConstant,
    kFnV,
    kFnTimes,
    kVTimes
  };
  // Fills x (PredictMu's regressors); false when the model has more terms
  // than the stack buffer (callers then use PredictMu).
  bool FillRegressors(double fn_n, double v_mm_s, double* x) const;
  StochasticFrictionModel model_;
  std::vector<Source> source_;    // per term
  std::vector<double> constant_;  // per term: its x when kConstant,
                                  // the other factor for k*Times
  // Where the eps scale's input comes from (kNone: no scale model;
  // kGeneral: a product column, CalcEpsScaleFactor at (fn_n, v_mm_s)).
  enum class ScaleSource { kNone, kFn, kV, kConstant, kGeneral };
  ScaleSource scale_source_ = ScaleSource::kNone;
  double scale_constant_ = 1.0;         // the factor when kConstant
  double q_lo95_ = 0.0, q_hi95_ = 0.0;  // eps quantiles at 0.025, 0.975
  // Fitted ranges of fn_n and v_mm_s (empty range = not fitted: never
  // flagged).
  bool has_fn_range_ = false, has_v_range_ = false;
  double fn_min_ = 0, fn_max_ = 0, v_min_ = 0, v_max_ = 0;
  bool table_ = false;
  std::vector<double> levels_;  // EpsQuantileLevels(), kept at hand // eps
                                // quantiles usable for the table
  std::vector<std::uint16_t> segment_;  // per bucket: first level index > p
};

/// Options of SampleMuEpisodes.
struct EpisodeSampleOptions {
  int envs = 1;   ///< N parallel environments (rows), > 0
  int steps = 1;  ///< T steps per episode (columns), > 0
  /// Step-to-step correlation of eps, in [0, 1]: 0 = independent draws per
  /// step, 1 = one draw per environment held for the whole episode, in
  /// between an AR(1) process with this coefficient (see SampleMuEpisodes).
  double ar1 = 0.0;
  /// Share f of the normal scores' variance that stays constant within an
  /// episode (a per-episode offset A ~ N(0, 1), drawn once per
  /// environment), in [0, 1]: 0 = none, 1 = one draw per episode.
  double offset_fraction = 0.0;
  /// True when usable; otherwise *why names the field, value and rule.
  bool IsValid(std::string* why) const;
};

/// An (N, T) array of inputs read with element strides (0 = broadcast), so
/// a scalar, a per-environment column or a full array can be given.
struct StridedInput {
  const double* data = nullptr;
  std::ptrdiff_t env_stride = 0;   ///< elements between environments
  std::ptrdiff_t step_stride = 0;  ///< elements between steps
  double at(int env, int step) const {
    return data[env * env_stride + step * step_stride];
  }
};

/// Per-environment, per-step mu for N parallel simulated environments over
/// one episode of T steps at (fn_n [N], v_mm_s [mm/s]) of each environment
/// and step, written row-major to out[env * steps + step] (N*T doubles).
///
/// eps keeps the model's empirical marginal distribution at every step; its
/// time structure is a Gaussian copula, the process of EpsTimeModel
/// (eps_time.h): with f = offset_fraction and phi = ar1,
///   z_t = sqrt(f) A + sqrt(1 - f) w_t,  A ~ N(0, 1) once per episode,
///   w_0 ~ N(0, 1),  w_t = phi w_{t-1} + sqrt(1 - phi^2) e_t,
///   eps_t = Q_eps(Phi(z_t)),
/// so corr(z_t, z_{t+k}) = f + (1 - f) phi^k. With phi = f = 0 each
/// eps_t = Q_eps(u_t) uses one uniform (as MuSampler::Draw); otherwise each
/// step uses one uniform through Phi^-1 (plus one per episode for A when
/// f > 0). The correlation of eps itself is close to that of z (Spearman's
/// rho of eps is (6/pi) asin(rho_z/2)).
///
/// Models that store the offset decomposition (EpsTimeModel::offset,
/// eps_time.h) serve hold risks from that process, not from this copula;
/// with heavy-tailed data the copula has more independent chances per hold,
/// so episodes sampled here slip more often at a served force than the risk
/// promises. Sample the decomposition with CalcOffsetQuantile,
/// CalcWithinQuantile, CalcInnovationQuantile and CalcOffsetSumCdf
/// (eps_time.h) to reproduce served risks exactly.
/// @throws std::invalid_argument for invalid options (nothing written).
void SampleMuEpisodes(const MuSampler& sampler,
                      StridedInput fn_n,
                      StridedInput v_mm_s,
                      const EpisodeSampleOptions& options,
                      UniformSource uniform,
                      double* out);

}  // namespace frictiond
