#pragma once
/// @file
/// Identification of joint friction from joint data (paper 002, issue 9
/// item 2): the mixed-lubrication model of joint_friction.h beside two
/// classic velocity-only models, compared by held-out error.
///
/// Models (mu: friction coefficient, v: sliding speed [mm/s] >= 0):
///
/// - kMixed (paper 002, eq. 1): mu = f(S, W), S = eta(T) v / p, alpha the
///   solid LOAD fraction at load W (joint_friction.h, eqs. 6-7);
///   theta = [f_s, f_l, d_ref_um, n]. Needs load and viscosity per sample.
/// - kStribeckViscous (generalised Stribeck with viscous term, Bo &
///   Pavelescu / Armstrong): mu = f_c + (f_st - f_c) exp(-(v/v_s)^delta)
///   + k_v v; theta = [f_c, f_st, v_s (mm/s), delta, k_v (s/mm)].
/// - kLuGreSteadyState (paper 001, eq. 4 for v > 0): mu = mu_c + (mu_s -
///   mu_c) exp(-(v/v0)^2) + sigma2 v; theta = [mu_s, mu_c, v0, sigma2],
///   evaluated by CalcSteadyStateFrictionRatio of lugre.h.
///
/// Solver: Levenberg-Marquardt with Marquardt scaling and box bounds,
/// analytic Jacobians. Noise model: independent zero-mean errors whose
/// variance may change with the state (the mixed regime scatters most), so
/// P_theta is the heteroscedasticity-robust sandwich
/// (J^T J)^-1 J^T diag(r^2) J (J^T J)^-1 scaled by m / (m - p).
///
/// Usage:
/// @code
///   JointFitResult r = FitJointModel(JointModelKind::kMixed, data, config);
///   if (r.status == JointFitStatus::kConverged) use(r.theta, r.P_theta);
/// @endcode

#include <string>
#include <vector>

#include <Eigen/Core>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/joint_friction.h"

namespace frictiond {

/// Joint measurements; all vectors have the same length.
struct JointData {
  std::vector<double> v_mm_s;    ///< sliding speed at the contact [mm/s], > 0
  std::vector<double> load_n;    ///< normal load of the contact [N], > 0
  std::vector<double> eta_pa_s;  ///< lubricant viscosity [Pa s], > 0
  std::vector<double> temp_c;    ///< temperature [C] (may be empty)
  std::vector<double> mu;        ///< measured friction coefficient [-]
  std::size_t size() const { return mu.size(); }
};

/// Throws FieldError naming the first bad sample's field (message "sample
/// i: field = value (rule)") or the column whose length differs from mu's.
void ValidateJointData(const JointData& data);

/// Fixed, known properties of the joint used by the mixed model.
struct JointConfig {
  AsperitySurface surface;
  JointContact contact;
  Lubricant lubricant;
};

enum class JointModelKind { kMixed, kStribeckViscous, kLuGreSteadyState };
/// "mixed", "stribeck_viscous", "lugre_steady_state".
std::string ToString(JointModelKind kind);
/// Number of parameters of a model (4, 5, 4).
int ParameterCount(JointModelKind kind);
/// Parameter names in order, e.g. {"f_s", "f_l", "d_ref_um", "n"}.
std::vector<std::string> ParameterNames(JointModelKind kind);

/// Model prediction at one sample; optional row Jacobian (resized).
double PredictJointFriction(JointModelKind kind,
                            const Eigen::Ref<const Eigen::VectorXd>& theta,
                            const JointConfig& config,
                            double v_mm_s,
                            double load_n,
                            double eta_pa_s,
                            Eigen::RowVectorXd* J_mu_theta = nullptr);

enum class JointFitStatus {
  kConverged,
  kMaxIterations,
  kNotObservable,
  kFailed
};
std::string ToString(JointFitStatus status);

/// Result of FitJointModel.
struct JointFitResult {
  JointModelKind kind = JointModelKind::kMixed;
  JointFitStatus status = JointFitStatus::kFailed;
  Eigen::VectorXd theta;    ///< estimate (units as in the model list)
  Eigen::MatrixXd P_theta;  ///< robust covariance of theta
  double residual_rms = 0;  ///< RMS of mu_model - mu on the fitted samples
  int iterations = 0;
  double rcond = 0;  ///< reciprocal condition of the scaled J^T J
  std::string why;   ///< reason for a status other than kConverged
};

/// Options of FitJointModel.
struct JointFitOptions {
  int max_iterations = 200;       ///< > 0
  double cost_tolerance = 1e-12;  ///< relative cost decrease to stop
  double min_rcond = 1e-12;       ///< below: kNotObservable
  /// Start; empty -> a data-driven guess (quantiles of mu, median speed).
  Eigen::VectorXd start;
};

/// Fits one model to all samples of `data` (or the subset `rows`, if not
/// empty). Numerical problems come back as statuses.
/// @throws std::invalid_argument for invalid data, config or options.
JointFitResult FitJointModel(JointModelKind kind,
                             const JointData& data,
                             const JointConfig& config,
                             const JointFitOptions& options = {},
                             const std::vector<std::size_t>& rows = {});

/// The identified mixed model (FitJointModel's kMixed result) at a joint
/// state: the mean friction coefficient (eq. 1) and its sd, from the
/// contact scatter (CalcMixedFrictionDispersion) and the parameters'
/// uncertainty (J P_theta J', J = df/dtheta), with the film and the solid
/// fraction. The 95 % interval is mu +- 1.96 sigma with its lower bound
/// floored at 0 (a friction coefficient is a ratio of magnitudes; the rule
/// of mu_admissibility.h): where the sd is large against the mean (a thick
/// film, little solid contact), the Gaussian interval would reach below 0.
/// Departure from paper 002: the paper gives the mean and the contact
/// scatter; the parameter term and the floor are ours.
struct MixedFrictionPrediction {
  double mu = 0;                 ///< mean friction coefficient [-]
  double sigma = 0;              ///< hypot(sigma_contact, sigma_param) [-]
  double sigma_contact = 0;      ///< between contacts [-]
  double sigma_param = 0;        ///< from P_theta [-]
  double lo95 = 0, hi95 = 0;     ///< mu -+ 1.96 sigma, lo95 floored at 0
  bool floored_at_zero = false;  ///< lo95 was below 0 before the floor
  double film_um = 0;            ///< film thickness [um]
  double alpha = 0;              ///< solid-contact load fraction [0, 1]
};

/// PredictMixedFriction's answer for `mixed` (theta of 4 parameters and
/// its covariance) at Sommerfeld number sommerfeld_um [um] and load load_n
/// [N] > 0. Numbers may be non-finite where the terms overflow (the caller
/// refuses those inputs).
MixedFrictionPrediction PredictMixedFriction(const JointFitResult& mixed,
                                             const AsperitySurface& surface,
                                             double sommerfeld_um,
                                             double load_n);

/// Held-out comparison of the three models.
struct JointModelScore {
  JointModelKind kind = JointModelKind::kMixed;
  double heldout_rmse = 0;  ///< RMS error on held-out samples [-]
  double heldout_mae = 0;   ///< mean absolute held-out error [-]
  int folds_fitted = 0;     ///< folds whose fit converged
};

/// K-fold cross-validation. `fold` (same length as data, values 0..k-1)
/// assigns samples to folds; empty -> sample i goes to fold i % k.
/// @throws std::invalid_argument for k < 2 or a bad fold vector.
std::vector<JointModelScore> CompareJointModels(
    const JointData& data,
    const JointConfig& config,
    int k = 5,
    const std::vector<int>& fold = {});

/// Simulated joint data: mu = f(S, W) + (contact scatter of N Hertz summits,
/// SampleContactFriction) + N(0, noise^2), at the given states. eta from
/// temp_c via the lubricant.
JointData SimulateJointData(const MixedFrictionTheta& theta,
                            const JointConfig& config,
                            const std::vector<double>& v_mm_s,
                            const std::vector<double>& load_n,
                            const std::vector<double>& temp_c,
                            double noise,
                            unsigned seed);

}  // namespace frictiond
