#pragma once
/// @file
/// Two-stroke identification of the LuGre model (paper 001, Section III):
///
/// - Step 1, quasi-static fit (eqs. 4-5): mu_s, mu_c, v0, sigma2 from a
///   low-acceleration stroke (<= 3 mm/s^2) where dz/dt ~ 0 and
///   mu = sign(v) g(v) + sigma2 v. Samples are folded onto |v| and averaged
///   in speed bins, which averages the increasing- and decreasing-velocity
///   branches as the paper does. Gauss-Newton (the paper's "GNR") or
///   Levenberg-Marquardt, both with box bounds.
/// - Step 2, dynamic fit (eqs. 10-15): sigma0, sigma1 and the initial
///   bristle deflection z0 from a faster stroke (>= 5 mm/s^2) with a
///   hysteresis loop, by LM-1 (sigma1 tied to sigma0, see CalcDampingGain),
///   LM-2 (sigma0, sigma1, z0 free), LM-6 (all six plus z0), or by an EKF on
///   the state [sigma0, z] (sigma1 tied).
///
/// Noise model: mu samples carry independent zero-mean Gaussian noise of
/// constant variance; velocities and times are exact. Covariances are
/// P = s^2 (J^T J)^-1 with s^2 = cost / (m - n) (m residuals, n free
/// parameters).
///
/// Observability (paper eq. 10 and the text after it): sigma0 and sigma1
/// are only observable from samples where dz/dt != 0 (presliding, reversal,
/// fast velocity changes). Fits count such samples under the final estimate
/// and return kNotObservable when there are too few, or when the scaled
/// J^T J is numerically rank deficient.
///
/// Usage:
/// @code
///   LuGreFitResult qs = FitLuGreQuasiStatic(slow_stroke, Eigen::Vector4d(0.5,
///   0.3, 1, 0)); LuGreTheta guess = qs.theta; guess[LuGreIndex::kStiffness] =
///   10; guess[LuGreIndex::kDamping] = 0.01; LuGreFitResult dyn =
///   FitLuGreDynamic(fast_stroke, guess, 0.0); if (dyn.status !=
///   LuGreFitStatus::kConverged) { /* dyn.why */ }
/// @endcode

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "frictiond/estimators/lugre.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond {

struct IdentificationMemo;  // identification_memo.h

/// One stroke in signed form. Copyable and movable value type.
struct LuGreStroke {
  Eigen::VectorXd t_s;     ///< sample times [s], strictly increasing
  Eigen::VectorXd v_mm_s;  ///< signed sliding velocity [mm/s]
  Eigen::VectorXd mu;  ///< signed friction ratio Ft/Fn [-], > 0 opposing v > 0

  /// Number of samples.
  Eigen::Index size() const { return t_s.size(); }
  /// True if the three columns have one size, t_s is strictly increasing
  /// and everything is finite; otherwise *why names the row and value.
  bool IsValid(std::string* why) const;
};

/// Outcome of a fit.
enum class LuGreFitStatus {
  kConverged,      ///< the step or cost change fell below tolerance
  kMaxIterations,  ///< max_iterations used up; theta is the last iterate
  kNotObservable,  ///< too few samples with dz/dt != 0, or J^T J rank deficient
  kNotEnoughData,  ///< fewer usable samples than free parameters
  kFailed,  ///< the model became non-finite; theta is the last good iterate
};

/// Returns a short name ("converged", ...).
const char* ToString(LuGreFitStatus status);

/// Result of every fit. Entries of theta that the fit does not estimate are
/// copied from its input (NaN for sigma0, sigma1 after the quasi-static
/// fit); their rows and columns in P_theta are zero.
struct LuGreFitResult {
  LuGreFitStatus status = LuGreFitStatus::kFailed;
  LuGreTheta theta = LuGreTheta::Zero();
  LuGreThetaCov P_theta = LuGreThetaCov::Zero();
  /// Initial bristle deflection z0 [mm] (dynamic fits); for the EKF, the
  /// filtered z at the last sample. NaN after the quasi-static fit.
  double z0_mm = 0.0;
  /// Standard error of z0 [mm] (EKF: of the final z).
  double z0_std_mm = 0.0;
  /// Solver iterations (EKF: samples processed).
  int iterations = 0;
  /// RMS of the residuals mu_model - mu at the solution [-] (quasi-static:
  /// per-sample equivalent of the binned fit; EKF: of the innovations).
  double residual_rms = 0.0;
  /// Samples with |dz/dt| > excitation_fraction * max|v| under the result
  /// (0 after the quasi-static fit).
  int excited_samples = 0;
  /// Reciprocal condition number of the scaled J^T J (1 for the EKF).
  double rcond = 0.0;
  std::string why;  ///< reason for a status other than kConverged
};

/// Solver of the quasi-static fit.
enum class QuasiStaticSolver {
  kGaussNewton,         ///< Gauss-Newton with step halving (paper's GNR)
  kLevenbergMarquardt,  ///< Marquardt-scaled LM (eq. 14 form)
};

/// Options of FitLuGreQuasiStatic. Copyable value type.
struct QuasiStaticFitOptions {
  QuasiStaticSolver solver = QuasiStaticSolver::kLevenbergMarquardt;
  /// Samples with |v| < fraction * max|v| are dropped (presliding and the
  /// undefined sign near v = 0), in [0, 1).
  double min_speed_fraction = 0.03;
  /// Speed bins for up/down averaging, >= 0 (0: fit every sample).
  int num_speed_bins = 50;
  /// Iteration limit, > 0.
  int max_iterations = 100;
  /// Stop when an accepted step lowers the cost by less than this fraction,
  /// in (0, 1).
  double cost_tolerance = 1e-12;
  /// Initial LM damping lambda, > 0.
  double initial_lambda = 1e-3;
  /// rcond of the scaled J^T J below this: kNotObservable, in [0, 1).
  double min_rcond = 1e-12;
  /// Box bounds on [mu_s, mu_c, v0 (mm/s), sigma2 (s/mm)], lower < upper.
  Eigen::Vector4d lower_bounds = Eigen::Vector4d(1e-4, 1e-4, 1e-4, -1.0);
  Eigen::Vector4d upper_bounds = Eigen::Vector4d(10.0, 10.0, 1e4, 1.0);

  /// True if all fields satisfy their rules; otherwise *why names the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// Step 1: fits p = [mu_s, mu_c, v0, sigma2] of eq. 4 to a low-acceleration
/// stroke from initial_guess (which must lie inside the bounds).
/// @throws std::invalid_argument for an invalid stroke, guess or options.
LuGreFitResult FitLuGreQuasiStatic(
    const LuGreStroke& stroke,
    const Eigen::Vector4d& initial_guess,
    const QuasiStaticFitOptions& options = QuasiStaticFitOptions());

/// Which parameters the dynamic fit estimates.
enum class DynamicFitVariant {
  kLm1,  ///< [sigma0, z0]; sigma1 = damping_gain * sqrt(sigma0)
  kLm2,  ///< [sigma0, sigma1, z0]
  kLm6,  ///< [mu_s, mu_c, v0, sigma2, sigma0, sigma1, z0] in one go
};

/// Options of FitLuGreDynamic. Copyable value type.
struct DynamicFitOptions {
  DynamicFitVariant variant = DynamicFitVariant::kLm2;
  /// LM-1 tie sigma1 = damping_gain sqrt(sigma0) [s/mm^(1/2)], > 0. The
  /// default is CalcDampingGain(1 kg, 5 N, 0.5), the paper's relation
  /// sigma1 = 0.0316 sqrt(sigma0) (force units) at Fn = 5 N.
  double damping_gain = 0.0141421356237;
  /// Iteration limit, > 0.
  int max_iterations = 200;
  /// Stop when an accepted step lowers the cost by less than this fraction,
  /// in (0, 1).
  double cost_tolerance = 1e-12;
  /// Initial LM damping lambda, > 0.
  double initial_lambda = 1e-3;
  /// A sample is excited when |dz/dt| > fraction * max|v|, in (0, 1).
  double excitation_fraction = 0.02;
  /// Fewer excited samples than this: kNotObservable, >= 1.
  int min_excited_samples = 5;
  /// rcond of the scaled J^T J below this: kNotObservable, in [0, 1).
  double min_rcond = 1e-12;
  /// Box bounds on [mu_s, mu_c, v0, sigma2, sigma0, sigma1, z0 (mm)];
  /// lower < upper. Only the free entries are used.
  Eigen::Matrix<double, 7, 1> lower_bounds =
      (Eigen::Matrix<double, 7, 1>() << 1e-4,
       1e-4,
       1e-4,
       -1.0,
       1e-3,
       0.0,
       -10.0)
          .finished();
  Eigen::Matrix<double, 7, 1> upper_bounds =
      (Eigen::Matrix<double, 7, 1>() << 10.0, 10.0, 1e4, 1.0, 1e6, 1e3, 10.0)
          .finished();

  /// True if all fields satisfy their rules; otherwise *why names the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// Step 2: fits the free parameters of `variant` to a dynamic stroke from
/// initial_theta (fixed entries are kept) and z0_guess_mm. The model is the
/// exact-exponential discretisation of eq. 1 (CalcBristleStep) with the
/// velocity at the interval midpoint, and eq. 9 at the samples (eqs. 11-12).
/// @throws std::invalid_argument for an invalid stroke, theta, guess
/// outside the bounds, or invalid options.
LuGreFitResult FitLuGreDynamic(
    const LuGreStroke& stroke,
    const LuGreTheta& initial_theta,
    double z0_guess_mm,
    const DynamicFitOptions& options = DynamicFitOptions());

/// The discrete model used by FitLuGreDynamic: mu at every sample for
/// z(t_s[0]) = z0_mm (eqs. 11-12). Optional J_mu_x, n x 7, with respect to
/// x = [theta, z0]. Outputs are resized only when their size differs.
/// @throws std::invalid_argument for invalid theta or sizes.
void CalcLuGreDiscreteResponse(
    const LuGreTheta& theta,
    double z0_mm,
    const Eigen::Ref<const Eigen::VectorXd>& t_s,
    const Eigen::Ref<const Eigen::VectorXd>& v_mm_s,
    Eigen::VectorXd* mu,
    Eigen::Matrix<double, Eigen::Dynamic, 7>* J_mu_x = nullptr,
    Eigen::VectorXd* z_mm = nullptr);

/// Observability check (paper Section III): number of samples whose bristle
/// rate under (theta, z0) exceeds excitation_fraction * max|v|.
int CountExcitedSamples(const LuGreTheta& theta,
                        double z0_mm,
                        const Eigen::Ref<const Eigen::VectorXd>& t_s,
                        const Eigen::Ref<const Eigen::VectorXd>& v_mm_s,
                        double excitation_fraction);

/// Options of the EKF (paper Section III, "Extended Kalman Filter based
/// Estimation"). Copyable value type.
struct LuGreEkfOptions {
  /// sigma1 = damping_gain sqrt(sigma0) [s/mm^(1/2)], > 0 (see
  /// DynamicFitOptions::damping_gain).
  double damping_gain = 0.0141421356237;
  /// Initial state [sigma0 (1/mm), z (mm)]; sigma0 > 0.
  Eigen::Vector2d x0 = Eigen::Vector2d(10.0, 0.0);
  /// Initial covariance, symmetric positive definite.
  Eigen::Matrix2d P0 = (Eigen::Matrix2d() << 1e4, 0.0, 0.0, 1e-4).finished();
  /// Process noise per step on [sigma0, z], symmetric positive
  /// semi-definite (paper: diag(1e-2, 1e-9) in its units).
  Eigen::Matrix2d Q = (Eigen::Matrix2d() << 1e-4, 0.0, 0.0, 1e-12).finished();
  /// Measurement noise variance of mu [-], > 0.
  double R = 2.5e-5;
  /// sigma0 is kept >= this [1/mm], > 0.
  double min_sigma0 = 1e-3;
  /// See DynamicFitOptions.
  double excitation_fraction = 0.02;
  int min_excited_samples = 5;
  /// kConverged needs std(sigma0) <= this fraction of sigma0 at the end,
  /// in (0, 1]; otherwise kNotObservable.
  double max_relative_std = 0.1;

  /// True if all fields satisfy their rules; otherwise *why names the
  /// field, its value and the rule.
  bool IsValid(std::string* why) const;
};

/// EKF on x = [sigma0, z] with sigma1 = c sqrt(sigma0) and fixed quasi-static
/// parameters. Process model: sigma0 constant, z by CalcBristleStep (exact
/// for constant v; the paper's Euler step is unstable at 200 Hz). Measurement
/// model: mu = sigma0 z + sigma1 dz/dt + sigma2 v (eq. 9). All matrices are
/// fixed-size members, so Predict/Update never allocate. Inline so that a
/// caller built with EIGEN_RUNTIME_NO_MALLOC checks them. Copyable, movable.
class LuGreStiffnessEkf {
 public:
  using State = Eigen::Vector2d;     ///< [sigma0 (1/mm), z (mm)]
  using StateCov = Eigen::Matrix2d;  ///< P_x
  using Row = Eigen::RowVector2d;

  /// @param theta quasi-static parameters (entries 0-3 used; 4-5 ignored).
  /// @throws std::invalid_argument for invalid options or theta[0..3].
  LuGreStiffnessEkf(const LuGreTheta& theta, const LuGreEkfOptions& options);

  /// Process model x1 = f(x) over dt [s] at mid-interval velocity [mm/s],
  /// with optional J_x1_x (the paper's Phi).
  State CalcProcess(const State& x,
                    double dt_s,
                    double v_mid_mm_s,
                    StateCov* J_x1_x) const {
    theta_work_[LuGreIndex::kStiffness] = x[0];
    double J_z1_z = 1.0;
    LuGreThetaRow J_z1_theta;
    const double z1 = CalcBristleStep(theta_work_,
                                      v_mid_mm_s,
                                      dt_s,
                                      x[1],
                                      &J_z1_z,
                                      J_x1_x ? &J_z1_theta : nullptr);
    if (J_x1_x) *J_x1_x << 1.0, 0.0, J_z1_theta[LuGreIndex::kStiffness], J_z1_z;
    return State(x[0], z1);
  }

  /// Measurement model mu = r(x) at velocity v [mm/s] with optional
  /// J_mu_x (the paper's R), including d sigma1 / d sigma0.
  double CalcMeasurement(const State& x, double v_mm_s, Row* J_mu_x) const {
    const double sqrt_s0 = std::sqrt(x[0]);
    theta_work_[LuGreIndex::kStiffness] = x[0];
    theta_work_[LuGreIndex::kDamping] = damping_gain_ * sqrt_s0;
    double J_mu_z = 0.0;
    LuGreThetaRow J_mu_theta;
    const double mu = CalcFrictionRatio(
        theta_work_, v_mm_s, x[1], &J_mu_z, J_mu_x ? &J_mu_theta : nullptr);
    if (J_mu_x) {
      (*J_mu_x)[0] =
          J_mu_theta[LuGreIndex::kStiffness] +
          J_mu_theta[LuGreIndex::kDamping] * damping_gain_ / (2.0 * sqrt_s0);
      (*J_mu_x)[1] = J_mu_z;
    }
    return mu;
  }

  /// Time update over dt [s] with mid-interval velocity [mm/s].
  void Predict(double dt_s, double v_mid_mm_s) {
    x_ = CalcProcess(x_, dt_s, v_mid_mm_s, &Phi_);
    PPhiT_.noalias() = P_ * Phi_.transpose();
    P_.noalias() = Phi_ * PPhiT_;
    P_ += Q_;
  }

  /// Measurement update with mu [-] at velocity v [mm/s]; returns the
  /// innovation mu - r(x_prior).
  double Update(double v_mm_s, double mu) {
    const double innovation = mu - CalcMeasurement(x_, v_mm_s, &H_);
    PHt_.noalias() = P_ * H_.transpose();
    const double S = H_.dot(PHt_) + R_;
    K_ = PHt_ / S;
    x_.noalias() += K_ * innovation;
    if (x_[0] < min_sigma0_) x_[0] = min_sigma0_;
    // Joseph form keeps P symmetric positive semi-definite.
    IKH_.setIdentity();
    IKH_.noalias() -= K_ * H_;
    PPhiT_.noalias() = P_ * IKH_.transpose();
    P_.noalias() = IKH_ * PPhiT_;
    P_.noalias() += (K_ * R_) * K_.transpose();
    return innovation;
  }

  /// Current state estimate and covariance.
  const State& state() const { return x_; }
  const StateCov& P_x() const { return P_; }
  /// sigma1 [s/mm] tied to the current sigma0.
  double sigma1() const { return damping_gain_ * std::sqrt(x_[0]); }

 private:
  mutable LuGreTheta theta_work_;
  double damping_gain_;
  double R_;
  double min_sigma0_;
  StateCov Q_;
  State x_;
  StateCov P_;
  // Temporaries, allocated once (fixed size).
  StateCov Phi_;
  StateCov PPhiT_;
  StateCov IKH_;
  Row H_;
  Eigen::Vector2d PHt_;
  Eigen::Vector2d K_;
};

/// Runs LuGreStiffnessEkf over the stroke (update at sample 0, then predict
/// and update per sample) and reports sigma0, the tied sigma1 and their
/// covariance (delta method for sigma1). Entries 0-3 of theta are copied
/// from quasi_static_theta.
/// @throws std::invalid_argument for an invalid stroke, theta or options.
LuGreFitResult FitLuGreEkf(const LuGreStroke& stroke,
                           const LuGreTheta& quasi_static_theta,
                           const LuGreEkfOptions& options = LuGreEkfOptions());

// ---------------------------------------------------------------------------
// Identification from a material's recorded strokes (the daemon's rule)
// ---------------------------------------------------------------------------

/// One identified LuGre model, as a model set stores it (the JSON form is
/// proto/lugre_json.h). Copyable value type.
struct LuGreFamily {
  /// [mu_s, mu_c, v0, sigma2, sigma0, sigma1] (units in LuGreTheta).
  LuGreTheta theta = LuGreTheta::Zero();
  /// Covariance of theta. Block-diagonal when identified in two steps: Step 2
  /// (sigma0, sigma1) conditions on the Step-1 estimate.
  LuGreThetaCov P_theta = LuGreThetaCov::Zero();
  /// Status of the identification ("converged", ...; LuGreFitStatus names).
  std::string status = "converged";
  /// Step-2 variant: "lm1", "lm2", "lm6" or "ekf".
  std::string variant = "lm2";
  /// Solver iterations, both steps together.
  int iterations = 0;
  /// RMS of mu_model - mu on the dynamic stroke(s) [-].
  double residual_rms = 0.0;
  /// RMS of the quasi-static fit on its stroke(s) [-].
  double quasi_static_residual_rms = 0.0;
  /// Initial bristle deflection fitted on the (newest) dynamic stroke [mm].
  double z0_mm = 0.0;
  /// Samples with |dz/dt| above the excitation threshold (Step 2).
  int excited_samples = 0;
  /// Strokes used by Step 1 (low acceleration) and Step 2 (high acceleration).
  int strokes_quasi_static = 0;
  int strokes_dynamic = 0;
};

/// Kind of a recognised stroke (paper 001, Section III).
enum class LuGreStrokeKind {
  kQuasiStatic,   ///< acceleration <= 3 mm/s^2: Step 1
  kDynamic,       ///< acceleration >= 5 mm/s^2: Step 2
  kIntermediate,  ///< in between: not used
  kTooShort,      ///< fewer than 20 moving samples: not used
};

/// One stroke recognised in a material's samples, in signed form.
/// Copyable and movable value type.
struct RecognizedStroke {
  std::vector<double> t_s;     ///< sample times [s]
  std::vector<double> v_mm_s;  ///< signed velocity [mm/s]
  std::vector<double> mu;      ///< signed friction ratio [-]
  double accel_mm_s2 = 0.0;    ///< 95th percentile |dv/dt| over moving samples
  double fn_mean_n = 0.0;      ///< mean normal force over the stroke [N]
  int moving = 0;              ///< moving samples
  LuGreStrokeKind kind = LuGreStrokeKind::kTooShort;
};

/// Recognises strokes in recorded samples (docs/lugre.md, "Service"):
/// 1. Signs. v_mm_s and ft_n are magnitudes. Without a `dir_sign` covariate
///    every stroke is one-directional: v = v_mm_s >= 0 and mu = ft_n/fn_n.
///    With a finite `dir_sign` column (+1/-1/0) v = dir_sign * v_mm_s, and
///    the force takes the new direction where |Ft|/Fn passes its minimum
///    between 0.2 s before the reversal and 1 s after the speed left the
///    rest band.
/// 2. Runs: cut at time gaps (> 10 median steps) and where time goes
///    backwards (a new upload).
/// 3. Strokes: speed median-filtered over 50 ms; samples at or below 5 % of
///    the run's peak filtered speed are at rest; a rest of >= 0.25 s splits
///    strokes; a stroke is its moving samples plus up to 0.1 s of rest on
///    either side.
/// 4. Acceleration: least-squares slope of v over +-50 ms (>= +-2 samples);
///    a stroke's is the 95th percentile of |dv/dt| over its moving samples.
/// 5. Kinds: quasi-static <= 3 mm/s^2, dynamic >= 5 mm/s^2 (paper 001,
///    Section III); in between, or fewer than 20 moving samples, unused.
/// Returns the strokes oldest first. `data` need not be labelled.
std::vector<RecognizedStroke> RecognizeLuGreStrokes(const StrokeData& data);

/// Result of IdentifyLuGreFromStrokes.
struct LuGreIdentification {
  /// True when a family was identified; otherwise `why` says what is
  /// missing (a normal outcome: e.g. no high-acceleration stroke yet, or
  /// a low-acceleration stroke that is not quasi-static). When identified,
  /// `why` says which variant was kept and why.
  bool identified = false;
  LuGreFamily family;
  std::string why;
  int strokes_quasi_static = 0;  ///< recognised, of each kind
  int strokes_dynamic = 0;
  int strokes_intermediate = 0;
  int strokes_too_short = 0;
};

/// The two-step identification from a material's samples (paper 001,
/// Section III), as the daemon runs it on every upload: recognise strokes
/// (RecognizeLuGreStrokes); Step 1 fits all quasi-static strokes together
/// (newest first, up to 1e6 samples; FitLuGreQuasiStatic by LM from three
/// starts, the best converged kept); Step 2 fits dynamic strokes, newest
/// first, one at a time (LM-2 from sigma0 = 10 and 100 /mm, else LM-1 with
/// sigma1 tied by CalcDampingGain(1 kg, the stroke's mean Fn, 0.5)). A
/// Step-2 fit is accepted when it converged, z0 is not at a bound and its
/// residual RMS is at most 3 times Step 1's. Up to four accepted fits (of
/// at most twelve tried, 40 000 samples) are combined by their information
/// matrices (sigma0, sigma1), LM-2 fits preferred over LM-1.
/// Then Step 1's premise (eq. 4, dz/dt ~ 0 on the slow stroke) is checked:
/// its residual RMS must be <= 2x the noise of mu estimated from second
/// differences of the slow strokes. Where it fails (compliant bristles as in
/// paper 001 Tables I, III, V: the slow stroke keeps a hysteresis and Step 1
/// flattens the Stribeck curve), LM-6 is run on the newest accepted dynamic
/// stroke from the two-step result and kept ("lm6") only if it converged,
/// fits to <= 2x the noise and has std/value <= 0.1 for mu_s, mu_c and
/// <= 0.2 for v0, sigma1; otherwise identified = false and `why` says the
/// strokes cannot identify the model (docs/lugre.md, "Paper regime").
/// Departure from the paper: the paper fits one stroke of each kind; this
/// pools every recognised stroke so that later uploads refine the model.
/// Needs at least one stroke of each kind; otherwise identified = false
/// with the reason. Never throws for data (statuses are results).
/// `memo` (optional, identification_memo.h): the recognition of a run seen
/// by an earlier call with the same memo is looked up; the answer is the
/// same with or without it.
LuGreIdentification IdentifyLuGreFromStrokes(
    const StrokeData& data, IdentificationMemo* memo = nullptr);

}  // namespace frictiond
