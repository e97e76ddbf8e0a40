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

}  // namespace frictiond::mujoco
