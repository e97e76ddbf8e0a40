#pragma once
/// @file
/// Control with the stochastic friction model (paper 000, section III-D).
///
/// Controlled sliding, eq. (3): the tangential force that makes the contact
/// slide at a desired speed v_d under normal force Fn,
///   Ft_target = b0*Fn + b1*v_d*Fn + b2*Fn^2            (eq. 3)
/// i.e. Ft_target = mu_hat(Fn, v_d) * Fn with mu_hat from eq. (1).
///
/// Velocity prediction, eq. (4): the sliding speed implied by measured forces
/// of a slipping contact,
///   v_hat = (Ft/Fn|slip - b0 - b2*Fn) / b1             (eq. 4)
///
/// Models extended with further terms (covariates, non-linear Fn forms) are
/// handled by evaluating mu_hat through PredictMu: eq. (3) becomes
/// mu_hat(Fn, v_d, covariates) * Fn, and eq. (4) needs mu to be linear in v
/// (one linear `v_mm_s` term), with mu_hat(Fn, v = 0) in place of b0 + b2 Fn.
/// Covariates not given take their fitted mean.
///
/// Noise: eps of eq. (1) makes both answers distributions. The intervals
/// below come from the empirical eps quantiles of the fit (widened by the
/// parameter uncertainty for eq. 3), not from a normal assumption.
///
/// Usage:
/// @code
///   TargetForce f = CalcTargetTangentialForce(model, /*fn_n=*/2.0,
///                                             /*v_mm_s=*/30.0);
///   SlidingSpeed s = PredictSlidingSpeed(model, /*fn_n=*/2.0, f.ft_n);
///   // s.v_mm_s == 30 (up to rounding) when s.status == kOk.
/// @endcode

#include <string>
#include <vector>

#include "frictiond/estimators/stochastic_model.h"

namespace frictiond {

/// Answer of eq. (3).
struct TargetForce {
  double ft_n = 0.0;          ///< target tangential force [N], mu_hat * Fn
  double mu = 0.0;            ///< mu_hat(Fn, v_d)
  double ft_lo95_n = 0.0;     ///< Ft at the 2.5 % quantile of mu [N]
  double ft_hi95_n = 0.0;     ///< Ft at the 97.5 % quantile of mu [N]
  bool extrapolated = false;  ///< Fn or v_d outside the fitted range
  std::vector<std::string> extrapolated_inputs;
};

/// Eq. (3): target tangential force for sliding at v_mm_s under fn_n.
/// Other model inputs may be given in `covariates` (else their mean).
/// @throws std::invalid_argument for fn_n <= 0 or v_mm_s < 0 (or NaN),
/// naming the argument and its value.
TargetForce CalcTargetTangentialForce(const StochasticFrictionModel& model,
                                      double fn_n,
                                      double v_mm_s,
                                      const InputValues& covariates = {});

/// Status of eq. (4).
enum class SlidingSpeedStatus {
  kOk,            ///< v_mm_s is the eq. (4) estimate
  kNoSpeedTerm,   ///< the model has no identified linear v_mm_s term (b1 = 0,
                  ///< e.g. fitted on a constant-speed stroke): v is not
                  ///< identifiable from forces
  kNonLinearInV,  ///< another model term reads v_mm_s; eq. (4) needs mu
                  ///< linear in v
};
const char* ToString(SlidingSpeedStatus s);

/// Answer of eq. (4).
struct SlidingSpeed {
  SlidingSpeedStatus status = SlidingSpeedStatus::kNoSpeedTerm;
  std::string why;      ///< reason when status != kOk
  double v_mm_s = 0.0;  ///< eq. (4) estimate [mm/s]; may be < 0 (see below)
  double v_lo95_mm_s = 0.0;  ///< 2.5 % quantile of v given eps [mm/s]
  double v_hi95_mm_s = 0.0;  ///< 97.5 % quantile of v given eps [mm/s]
  double ratio = 0.0;        ///< Ft/Fn
  double b1 = 0.0;           ///< coefficient of v used [1/(mm/s)]
  double b1_t = 0.0;  ///< b1 / SE(b1): below ~2 the speed is mostly noise
  /// v_mm_s < 0: the ratio lies below mu_hat(Fn, 0) when b1 > 0 (above it
  /// when b1 < 0), i.e. not a sliding state of the model; the contact is
  /// expected to stick. Also when Ft = 0 (no tangential force drives no
  /// sliding), whatever v the line gives.
  bool below_model_range = false;
  bool extrapolated = false;  ///< v_mm_s or fn_n outside the fitted range
};

/// Eq. (4): sliding speed of a slipping contact from measured Fn and Ft.
/// @throws std::invalid_argument for fn_n <= 0 or ft_n < 0 (or NaN).
SlidingSpeed PredictSlidingSpeed(const StochasticFrictionModel& model,
                                 double fn_n,
                                 double ft_n,
                                 const InputValues& covariates = {});

}  // namespace frictiond
