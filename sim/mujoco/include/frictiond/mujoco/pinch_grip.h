#pragma once
/// @file
/// Grip force of a two-fingertip pinch (issue 21's drop-rate scene,
/// docs/mujoco.md): two contacts with their own stochastic models a and b
/// press a rigid object with the same normal force Fn and share the load L.
/// The object cannot move while some split of L lies inside both friction
/// cones, so it slips (and, with velocity-weakening friction, drops) when
///
///     Fn (mu_a + mu_b) < L,  mu_x = b0_x + b2_x Fn + eps_x  (paper 000 eq. 1
///                                                         at rest, v = 0)
///
/// with eps_a, eps_b independent (different contacts) and each drawn as the
/// adapter draws it (CalcEpsQuantile of a uniform: the stored empirical
/// quantiles). CalcPinchSlipProbability evaluates P(slip) by the exact
/// convolution of the two quantile functions on a grid of `grid` midpoint
/// levels each (error about 1 / grid); CalcPinchGripForce solves
/// P(slip) = risk for Fn by bisection.
///
/// Departure from the service's grip-force (CalcGripForce, one contact
/// holding load_n): asking it for L / 2 per finger assumes both fingers
/// slip together only when each one alone would, which for independent eps
/// is conservative (the drop rate is below the requested risk; numbers in
/// docs/mujoco.md). Only eps held per contact episode is modelled here
/// (eps_time offset fraction 1): then the risk of a hold is the risk of one
/// instant.

#include <cstdint>
#include <vector>

#include "frictiond/estimators/stochastic_model.h"

namespace frictiond::mujoco {

/// Midpoint levels per eps distribution in the convolution.
constexpr int kPinchGridLevels = 20000;

/// P(Fn (mu_a + mu_b) < load_n) at rest (file comment).
/// @throws std::invalid_argument for fn_n or load_n not finite and > 0.
double CalcPinchSlipProbability(const StochasticFrictionModel& a,
                                const StochasticFrictionModel& b,
                                double fn_n,
                                double load_n,
                                int grid = kPinchGridLevels);

/// Outcome of CalcPinchGripForce.
struct PinchGripForce {
  bool attainable = false;  ///< false: no Fn in (0, fn_max_n] reaches risk
  double fn_n = 0.0;        ///< smallest Fn per finger with P(slip) <= risk
  double slip_probability = 0.0;  ///< P(slip) at fn_n
};

/// Smallest per-finger Fn in (0, fn_max_n] with P(slip) <= risk, by
/// bisection to 1e-6 N (P(slip) decreases with Fn while Fn (b0 + b2 Fn)
/// increases, i.e. below the force of largest friction, which bounds the
/// search).
/// @throws std::invalid_argument for load_n, fn_max_n not finite and > 0
/// or risk outside (0, 1).
PinchGripForce CalcPinchGripForce(const StochasticFrictionModel& a,
                                  const StochasticFrictionModel& b,
                                  double load_n,
                                  double risk,
                                  double fn_max_n = 100.0);

/// Options of PinchHoldRisk.
struct PinchHoldOptions {
  double hold_s = 0.5;     ///< seconds the load is held
  int paths = 200000;      ///< Monte Carlo paths of (eps_a, eps_b)
  std::uint64_t seed = 1;  ///< seed of the paths (answers reproduce)
};

/// The two-contact risk of a hold with time-correlated eps (eps_time.h):
/// each contact's eps follows its model's latent process,
///
///   eps_x(t) = F_x^-1(Phi(z_x(t))),  z_x = sqrt(f_x) A_x + sqrt(1 - f_x) w_x,
///
/// sampled every eps_time.dt_s of its model (1 + round(hold_s / dt_s)
/// samples, as CalcGripForce's hold risk counts them), A_x once per hold,
/// w_x a stationary AR(1) with the model's phi, F_x^-1 =
/// CalcEpsQuantileExtended (what FrictionAdapter draws with
/// EpsTime::kIdentified). A model without a valid eps time model, or
/// offset fraction 1, holds one draw (CalcEpsQuantile) for the hold. The
/// pinch slips when at some sample of either contact
///
///   Fn (b0_a + b2_a Fn + eps_a(t) + b0_b + b2_b Fn + eps_b(t)) < L   (eq. 1
///                                                          at rest, v = 0)
///
/// so P(slip) = P(min_t (eps_a(t) + eps_b(t)) < L / Fn - mean mu_a - mean
/// mu_b). The constructor draws `paths` independent holds and keeps the
/// sorted minima; SlipProbability and GripForce then cost a binary search
/// (Monte Carlo error sqrt(r (1 - r) / paths), 2.2e-4 at r = 0.01 with
/// 200,000 paths).
///
/// Departure from the service (CalcGripForce: one contact, exact AR(1)
/// survival by quadrature): two contacts, by simulation. With offset
/// fraction 1 on both models it reduces to CalcPinchSlipProbability.
class PinchHoldRisk {
 public:
  /// @throws std::invalid_argument for load_n not finite and > 0, hold_s
  /// outside [0, 3600] or paths < 100.
  PinchHoldRisk(const StochasticFrictionModel& a,
                const StochasticFrictionModel& b,
                double load_n,
                const PinchHoldOptions& options = {});

  /// P(slip during the hold) with both fingers at fn_n.
  /// @throws std::invalid_argument for fn_n not finite and > 0.
  double SlipProbability(double fn_n) const;

  /// Smallest per-finger Fn in (0, fn_max_n] with P(slip during the hold)
  /// <= risk (bisection to 1e-6 N below the force of largest mean
  /// friction, as CalcPinchGripForce).
  /// @throws std::invalid_argument for risk outside (0, 1) or fn_max_n not
  /// finite and > 0.
  PinchGripForce GripForce(double risk, double fn_max_n = 100.0) const;

  /// Samples per hold of contact a and b.
  int samples_a() const { return samples_a_; }
  int samples_b() const { return samples_b_; }

 private:
  double b0_ = 0.0;  ///< b0_a + b0_b
  double b2_ = 0.0;  ///< b2_a + b2_b
  double load_n_ = 0.0;
  int samples_a_ = 1;
  int samples_b_ = 1;
  std::vector<double> minima_;  ///< sorted min_t (eps_a + eps_b) per path
};

}  // namespace frictiond::mujoco
