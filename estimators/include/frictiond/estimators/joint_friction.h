#pragma once
/// @file
/// Mixed-lubrication joint friction (paper 002, Rezala & Arbaoui, "Analysis
/// of random causes of repeatability errors induced by friction at joints in
/// industrial robots", IJE 2022, Section 4).
///
/// Model:
///
///     f     = alpha f_s + (1 - alpha) f_l                          (eq. 1)
///     S     = eta V / p            (Sommerfeld number, Section 5.1)  [um]
///     d     = d_ref (S / S_ref)^n  (mean film thickness)             [um]
///     alpha = P(z > d) = 1/2 erfc((d - Alt) / (SAlt sqrt 2))  (eqs. 2, 7)
///
/// Summit altitudes z are Gaussian (eq. 2, mean Alt, rms SAlt, eq. 3);
/// summits above the film thickness d are in solid (thin film) contact with
/// friction f_s, the rest are in the fluid (thick) film with f_l. Each summit
/// carries load in proportion to its Hertz stiffness sqrt(R); the radii are
/// lognormal (eqs. 4-5) and independent of the altitudes (eq. 7), so the
/// mean load fraction of the solid summits is the number fraction above (the
/// radius integral cancels) and the radii set the dispersion: for a contact
/// with N summits the load fraction is a ratio of sums whose variance is, to
/// first order in 1/N,
///
///     Var(alpha) = alpha (1 - alpha) E[R] / (E[sqrt R])^2 / N
///                = alpha (1 - alpha) exp(a^2 / 4) / N
///
/// (a: log-sd of the radius, eq. 4). The friction of one contact then
/// scatters with sd (f_s - f_l) sqrt(Var(alpha)): none in full film or full
/// solid contact, most in the mixed regime, as in paper 002 Fig. 6.
///
/// The film law d = d_ref (S/S_ref)^n is the hydrodynamic scaling of film
/// thickness with eta V / p (n = 1/2 for a rigid hydrodynamic wedge, about
/// 0.7 for EHL); the paper computes d numerically and gives no closed form.
/// S is kept in micrometres (eta [Pa s] * V [m/s] / p [Pa] * 1e6), S_ref =
/// kSommerfeldRefUm. Temperature enters only through eta(T) (Vogel), hence
/// through S.
///
/// Usage:
/// @code
///   const MixedFrictionTheta theta = MakeMixedFrictionTheta(0.1, 0.004,
///   0.5, 0.6); const JointState s = {200.0, 100.0, 40.0};  // mm/s, N, C
///   const double eta = CalcViscosity(Lubricant{}, s.temp_c);
///   const double S = CalcSommerfeldUm(eta, s.v_mm_s, s.load_n, contact);
///   const double f = CalcMixedFriction(theta, surface, S);
/// @endcode

#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace frictiond {

/// Reference Sommerfeld number of the film law [um].
constexpr double kSommerfeldRefUm = 0.01;

/// Statistical surface of the summits (paper 002 Section 4.2). Copyable.
struct AsperitySurface {
  double alt_um = 0.5;    ///< Alt, mean summit altitude over the mean line [um]
  double salt_um = 0.15;  ///< SAlt, rms of the summit altitude [um], > 0
  double radius_log_sd = 0.8;    ///< a of eq. 4 (log-sd of R*), >= 0
  double radius_log_mean = 0.0;  ///< b of eq. 4 (log-mean of R*)
  double srad_um = 20.0;         ///< SRAD of eq. 5 (radius scale) [um], > 0
  double summits = 400.0;        ///< N, summits in one nominal contact, >= 1
};

/// Surface from roughness parameters (eqs. 2-3): Alt = R/2 and
/// SAlt = 0.35 sqrt(W^2 + SW^2), radii defaults otherwise.
/// @throws std::invalid_argument naming a non-positive or non-finite input.
AsperitySurface MakeSurfaceFromRoughness(double r_um,
                                         double w_um,
                                         double sw_um);

/// @throws std::invalid_argument naming the field, its value and the rule.
void ValidateSurface(const AsperitySurface& surface);

/// Vogel viscosity law eta(T) = A exp(B / (T + C)), T in degrees C. The
/// defaults are an ISO VG 68 mineral oil (68 cSt at 40 C, 8.7 cSt at 100 C,
/// density 0.87 g/ml, C = 95 C): A = 7.39e-5 Pa s, B = 902.5 C.
struct Lubricant {
  double vogel_a_pa_s = 7.39e-5;  ///< A [Pa s], > 0
  double vogel_b_c = 902.5;       ///< B [degrees C], > 0
  double vogel_c_c = 95.0;        ///< C [degrees C]; T + C must stay > 0
};

/// @throws std::invalid_argument naming the field, its value and the rule.
void ValidateLubricant(const Lubricant& lubricant);

/// Dynamic viscosity eta(T) [Pa s]. NaN when temp_c + C <= 0.
double CalcViscosity(const Lubricant& lubricant, double temp_c);

/// Nominal contact of the joint's sliding pair (pressure p = load / area).
struct JointContact {
  double area_mm2 = 50.0;  ///< apparent contact area [mm^2], > 0
};

/// Sommerfeld number S = eta V / p [um] from eta [Pa s], V [mm/s] and the
/// load [N] over the contact area (Section 5.1). Precondition: load_n > 0.
double CalcSommerfeldUm(double eta_pa_s,
                        double v_mm_s,
                        double load_n,
                        const JointContact& contact);

/// Parameters [f_s, f_l, d_ref (um), n]: solid (thin film) friction [-],
/// fluid (thick film) friction [-], film thickness at S = S_ref [um], film
/// exponent [-].
using MixedFrictionTheta = Eigen::Matrix<double, 4, 1>;
using MixedFrictionThetaCov = Eigen::Matrix<double, 4, 4>;
using MixedFrictionThetaRow = Eigen::Matrix<double, 1, 4>;

/// Indices into MixedFrictionTheta.
struct MixedFrictionIndex {
  static constexpr int kSolid = 0;      ///< f_s [-]
  static constexpr int kFluid = 1;      ///< f_l [-]
  static constexpr int kFilmRef = 2;    ///< d_ref [um]
  static constexpr int kFilmPower = 3;  ///< n [-]
};

MixedFrictionTheta MakeMixedFrictionTheta(double f_s,
                                          double f_l,
                                          double d_ref_um,
                                          double n);

/// True when usable: finite, f_s >= f_l >= 0, d_ref > 0, 0 < n <= 3;
/// otherwise *why names the field, value and rule.
bool IsValidMixedFrictionTheta(const MixedFrictionTheta& theta,
                               std::string* why = nullptr);

/// Film thickness d = d_ref (S/S_ref)^n [um]. Precondition: S > 0.
double CalcFilmThicknessUm(const MixedFrictionTheta& theta,
                           double sommerfeld_um);

/// Solid-contact load fraction alpha = P(z > d) for film thickness d [um]
/// (eqs. 2, 7; closed form of the Gaussian integral). Optional
/// J_alpha_d [1/um].
double CalcSolidFraction(const AsperitySurface& surface,
                         double film_um,
                         double* J_alpha_d = nullptr);

/// Mixed friction coefficient f(S) (eq. 1) [-]. Optional J_f_theta and
/// J_f_s [1/um]. S <= 0 means no film (d = 0): alpha = P(z > 0), which
/// is f_s only up to the summits below the mean line.
double CalcMixedFriction(const MixedFrictionTheta& theta,
                         const AsperitySurface& surface,
                         double sommerfeld_um,
                         MixedFrictionThetaRow* J_f_theta = nullptr,
                         double* J_f_s = nullptr);

/// Standard deviation of f between contacts from the finite number of
/// summits with lognormal radii (see the file comment) [-].
double CalcMixedFrictionDispersion(const MixedFrictionTheta& theta,
                                   const AsperitySurface& surface,
                                   double sommerfeld_um);

/// Friction of one simulated contact: draws round(N) summit altitudes
/// (eq. 2) and radii (eqs. 4-5) from `rng` and returns alpha_sample f_s +
/// (1 - alpha_sample) f_l, alpha_sample being the sqrt(R)-weighted fraction
/// of summits above d. Checks the dispersion formula; simulators use it.
double SampleContactFriction(const MixedFrictionTheta& theta,
                             const AsperitySurface& surface,
                             double sommerfeld_um,
                             std::mt19937_64* rng);

/// Fast evaluation of f at a joint state for a fixed model (the hot path of
/// a robot's control loop and of the mixed_friction_eval benchmark). For a
/// fixed theta f depends on the state only through u = ln S, and
///
///     ln S = ln A + B / (T + C) + ln V - ln p + const    (Vogel, no exp)
///
/// so f(u) is tabulated once on a uniform grid in u with its exact slope
/// (cubic Hermite); outside the grid f is constant to double precision
/// (alpha is 0 or its d = 0 limit there). Interpolation error is below
/// 1e-9 (tested). Copyable; not thread-hostile (read-only after build).
class MixedFrictionTable {
 public:
  /// Builds the table (about 50 us).
  /// @throws std::invalid_argument for invalid theta, surface, lubricant or
  /// contact (naming the field).
  MixedFrictionTable(const MixedFrictionTheta& theta,
                     const AsperitySurface& surface,
                     const Lubricant& lubricant,
                     const JointContact& contact);

  /// f at S [um], S > 0.
  double EvalSommerfeld(double sommerfeld_um) const;
  /// f at a state: speed [mm/s] > 0, load [N] > 0, temperature [C] inside
  /// the lubricant's Vogel range (NaN otherwise).
  double Eval(double v_mm_s, double load_n, double temp_c) const;

 private:
  double EvalLog(double u) const;
  double log_a_ = 0, b_ = 0, c_ = 0, log_const_ = 0;
  double u_min_ = 0, u_max_ = 0, inv_du_ = 0, du_ = 0;
  double f_low_ = 0, f_high_ = 0;
  std::vector<double> f_, slope_;  // f and df/du at the nodes
};

// ---------------------------------------------------------------- wear

/// Archard wear generalised to mixed lubrication (paper 002 Section 5.4):
/// only the load carried by the solid summits wears, so the wear volume
/// rate per sliding distance is
///
///     dV/ds = K(S) W / H,    K(S) = k_solid alpha(S)
///
/// (k_solid: dry Archard coefficient, H: hardness). Wear removes summit
/// altitude: the worn height h = V / A_nominal lowers Alt, which thickens
/// the effective film margin (d - Alt) and lowers friction (running-in).
struct WearParams {
  double k_solid = 1e-6;       ///< dimensionless dry Archard coefficient
  double hardness_mpa = 2000;  ///< H [MPa] (N/mm^2), > 0
};

/// Wear coefficient K(S) = k_solid alpha(S) [-].
double CalcWearCoefficient(const MixedFrictionTheta& theta,
                           const AsperitySurface& surface,
                           const WearParams& wear,
                           double sommerfeld_um);

/// One point of a wear run.
struct WearPoint {
  double distance_mm = 0;       ///< sliding distance
  double worn_um = 0;           ///< worn summit height
  double friction = 0;          ///< f at that state [-]
  double wear_coefficient = 0;  ///< K [-]
};

/// Friction drift with sliding distance at a constant state: integrates the
/// worn height h(s) (dh/ds = K(S) p / H, p the nominal pressure) with the
/// surface's Alt reduced by h (summits cannot wear below the mean line:
/// Alt >= 0). Returns `points` samples from 0 to distance_mm.
/// @throws std::invalid_argument for non-positive distance, points < 2 or
/// invalid parameters.
std::vector<WearPoint> PredictWearDrift(const MixedFrictionTheta& theta,
                                        const AsperitySurface& surface,
                                        const WearParams& wear,
                                        const JointContact& contact,
                                        double sommerfeld_um,
                                        double load_n,
                                        double distance_mm,
                                        int points);

}  // namespace frictiond
