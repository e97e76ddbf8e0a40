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
///     alpha = W_solid(d) / W       (load fraction, eqs. 2, 4-7)
///
/// alpha is the share of the normal load W carried by the summits in solid
/// (thin film) contact, as paper 002 Section 4.1 defines it ("the fraction
/// of force alpha passing through the contacts working in thin film"), not
/// the fraction of summits that touch. The summits above d are crushed by
/// delta = z - d and carry the Hertz load P = 4/3 E* R^1/2 delta^3/2 each
/// (the elastic term W_E of eq. 6); the fluid carries the rest of W (the
/// W_PVR, W_EHD terms). Summing over N summits with the density
/// p(z, R) = p1(z) p2(R) (eqs. 2, 4-5, 7), the R integral factorises
/// (independence, eq. 7) and has a closed form (lognormal moment), the z
/// integral is the Greenwood-Williamson function F_3/2:
///
///     W_solid(d) = K F_3/2(lambda),   lambda = (d - Alt) / SAlt
///     K          = N 4/3 E* E[sqrt R] SAlt^3/2,
///     E[sqrt R]  = sqrt(SRAD) exp(b/2 + a^2/8)
///     F_nu(l)    = int_l^inf (s - l)^nu phi(s) ds      (phi: N(0,1) density)
///     alpha      = min(1, K F_3/2(lambda) / W)
///
/// F_3/2 has no elementary form; CalcSummitIntegrals evaluates it by a fixed
/// 128-node Gauss-Legendre rule after s = lambda + u^2 (relative error below
/// 1e-12 against a dense independent quadrature over lambda in [-60, 30],
/// tested). alpha -> 1 (dry) as d falls to the separation d_dry at which the
/// summits alone carry W (K F_3/2 = W), alpha -> 0 (full film) as d grows.
///
/// Departures from paper 002 (stated here and in docs/joint.md):
/// - Only the elastic Hertz term of eq. 6 is kept for the summits; the
///   elasto-plastic and plastic terms (W_EP, W_P) are not modelled (their
///   onset is the plasticity index (E*/H) sqrt(SAlt/R), see docs).
/// - The fluid load is not computed from HD/EHD mechanics: the fluid carries
///   W - W_solid(d) at the film thickness d(S) of the film law below.
/// - When W exceeds K F_3/2(-Alt/SAlt) (the Hertz load of the summits pressed
///   to the mean line), d_dry < 0 and the film thickness is counted from d_dry
///   instead of the mean line, d = d_film(S) + min(0, d_dry(W)), so that
///   S -> 0 is dry contact (alpha = 1) at every load.
///
/// Dispersion: alpha of one contact is a ratio W_solid / W of a sum over N
/// summits, whose variance at a fixed load W is, to first order in 1/N,
///
///     Var(alpha) = alpha^2 (exp(a^2/4) F_3(lambda) / F_3/2(lambda)^2 - 1) / N
///
/// (E[R] / E[sqrt R]^2 = exp(a^2/4), a: log-sd of the radius, eq. 4); zero in
/// dry contact (alpha = 1: the separation adjusts to W) and vanishing in full
/// film. The friction of one contact scatters with sd (f_s - f_l)
/// sqrt(Var(alpha)), most in the mixed regime, as in paper 002 Fig. 6.
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
///   const double f = CalcMixedFriction(theta, surface, S, s.load_n);
/// @endcode

#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "frictiond/estimators/field_error.h"

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
  /// E*, effective Hertz modulus of the pair [GPa], > 0. Default: steel on
  /// steel as paper 002's 100C6 pin on 42CD4 plate (E = 210 GPa, nu = 0.3:
  /// E* = E / (2 (1 - nu^2)) = 115.4 GPa).
  double modulus_gpa = 115.4;
};

/// Surface from roughness parameters (eqs. 2-3): Alt = R/2 and
/// SAlt = 0.35 sqrt(W^2 + SW^2), radii defaults otherwise.
/// @throws FieldError naming a non-positive or non-finite input.
AsperitySurface MakeSurfaceFromRoughness(double r_um,
                                         double w_um,
                                         double sw_um);

/// @throws FieldError naming the field, its value and the rule.
void ValidateSurface(const AsperitySurface& surface);

/// Vogel viscosity law eta(T) = A exp(B / (T + C)), T in degrees C. The
/// defaults are an ISO VG 68 mineral oil (68 cSt at 40 C, 8.7 cSt at 100 C,
/// density 0.87 g/ml, C = 95 C): A = 7.39e-5 Pa s, B = 902.5 C.
struct Lubricant {
  double vogel_a_pa_s = 7.39e-5;  ///< A [Pa s], > 0
  double vogel_b_c = 902.5;       ///< B [degrees C], > 0
  double vogel_c_c = 95.0;        ///< C [degrees C]; T + C must stay > 0
};

/// @throws FieldError naming the field, its value and the rule.
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

/// Gaussian summit integrals F_nu(lambda) = int_lambda^inf (s - lambda)^nu
/// phi(s) ds (phi the standard normal density) for the orders the model
/// uses. dF_nu/dlambda = -nu F_(nu-1); F_nu(0) = 2^((nu-1)/2)
/// Gamma((nu+1)/2) / sqrt(2 pi).
struct SummitIntegrals {
  double f_m12 = 0;  ///< F_-1/2
  double f_12 = 0;   ///< F_1/2
  double f_32 = 0;   ///< F_3/2 (Hertz load, eq. 6 elastic term)
  double f_3 = 0;    ///< F_3 (second moment of the Hertz load)
};

/// F_nu(lambda) for nu = -1/2, 1/2, 3/2, 3 by a 128-node composite
/// Gauss-Legendre rule in u (s = lambda + u^2), on the u range where the
/// integrand is within exp(-45) of its peak. All NaN for a non-finite lambda.
SummitIntegrals CalcSummitIntegrals(double lambda);

/// K = N 4/3 E* E[sqrt R] SAlt^3/2 [N]: the solid load is K F_3/2(lambda)
/// (see the file comment; eqs. 4-7).
double CalcAsperityLoadScaleN(const AsperitySurface& surface);

/// Fraction of summits above d, P(z > d) = 1/2 erfc((d - Alt)/(SAlt sqrt 2))
/// (eq. 2). NOT the load fraction: kept to compare with it (until issue 19
/// this was used as alpha).
double CalcTouchingFraction(const AsperitySurface& surface, double film_um);

/// Separation d_dry [um] (from the mean line) at which the summits alone
/// carry load_n elastically: K F_3/2((d_dry - Alt)/SAlt) = load_n. May be
/// negative (summits pressed below the mean line). NaN if load_n <= 0.
double CalcDrySeparationUm(const AsperitySurface& surface, double load_n);

/// Solid-contact LOAD fraction alpha in [0, 1] for film thickness d [um]
/// (d_film of the film law, >= 0) under the normal load load_n [N] > 0:
/// min(1, K F_3/2(lambda) / W) with lambda = (d_film + min(0, d_dry) -
/// Alt) / SAlt (see the file comment). Optional J_alpha_d = dalpha/dd_film
/// [1/um] (0 where alpha = 1). NaN for load_n <= 0.
double CalcSolidFraction(const AsperitySurface& surface,
                         double film_um,
                         double load_n,
                         double* J_alpha_d = nullptr);

/// Mixed friction coefficient f(S, W) (eq. 1) [-] at normal load load_n
/// [N] > 0. Optional J_f_theta and J_f_s [1/um] (at fixed load). S <= 0
/// means no film (d = 0): dry contact, alpha = 1 and f = f_s.
double CalcMixedFriction(const MixedFrictionTheta& theta,
                         const AsperitySurface& surface,
                         double sommerfeld_um,
                         double load_n,
                         MixedFrictionThetaRow* J_f_theta = nullptr,
                         double* J_f_s = nullptr);

/// Standard deviation of f between contacts from the finite number of
/// summits with lognormal radii at load load_n (see the file comment) [-].
double CalcMixedFrictionDispersion(const MixedFrictionTheta& theta,
                                   const AsperitySurface& surface,
                                   double sommerfeld_um,
                                   double load_n);

/// Friction of one simulated contact under load_n: draws round(N) summit
/// altitudes (eq. 2) and radii (eqs. 4-5) from `rng`, sums the Hertz loads
/// 4/3 E* sqrt(R) (z - d)^3/2 of the summits above the separation d (the
/// literal sum of eq. 6's elastic terms) and returns alpha_sample f_s +
/// (1 - alpha_sample) f_l, alpha_sample = min(1, sum / load_n). Checks the
/// mean and dispersion formulas; simulators use it.
double SampleContactFriction(const MixedFrictionTheta& theta,
                             const AsperitySurface& surface,
                             double sommerfeld_um,
                             double load_n,
                             std::mt19937_64* rng);

/// Fast evaluation of f at a joint state for a fixed model (the hot path of
/// a robot's control loop and of the mixed_friction_eval benchmark). For a
/// fixed theta and a load W <= K F_3/2(-Alt/SAlt) (d_dry >= 0), f depends
/// on the state through u = ln S and W only:
///
///     ln S = ln A + B / (T + C) + ln V - ln p + const    (Vogel, no exp)
///     alpha = min(1, G(u) / W),  G(u) = K F_3/2(lambda(d(u)))   [N]
///
/// so G(u) is tabulated once on a uniform grid in u with its exact slope
/// (cubic Hermite); below the grid G is its d -> 0 limit, above it G < 1e-30
/// K. Heavier loads (d_dry < 0) use lambda = lambda_dry(W) + d(u) / SAlt
/// with lambda_dry tabulated in ln W (up to e^16 times the capacity; beyond,
/// the direct CalcMixedFriction path) and F_3/2 tabulated in lambda on
/// [-8, 12], its asymptotic series below -8 (relative error < 1e-13) and 0
/// above 12. Interpolation error in f is below 1e-9 (tested). Copyable; not
/// thread-hostile (read-only after build).
class MixedFrictionTable {
 public:
  /// Builds the table (about 50 us).
  /// @throws FieldError for invalid theta, surface, lubricant or
  /// contact (naming the field).
  MixedFrictionTable(const MixedFrictionTheta& theta,
                     const AsperitySurface& surface,
                     const Lubricant& lubricant,
                     const JointContact& contact);

  /// f at S [um], S > 0, and load [N] > 0.
  double EvalSommerfeld(double sommerfeld_um, double load_n) const;
  /// f at a state: speed [mm/s] > 0, load [N] > 0, temperature [C] inside
  /// the lubricant's Vogel range (NaN otherwise).
  double Eval(double v_mm_s, double load_n, double temp_c) const;

 private:
  double EvalLog(double u, double load_n) const;
  MixedFrictionTheta theta_;
  AsperitySurface surface_;
  double log_a_ = 0, b_ = 0, c_ = 0, log_const_ = 0;
  double u_min_ = 0, u_max_ = 0, inv_du_ = 0, du_ = 0;
  double g_low_ = 0, g_high_ = 0;
  double HeavyLoad(double u, double load_n) const;
  double w_table_max_ = 0;               // loads above: the heavy-load tables
  std::vector<double> g_, slope_;        // G [N] and dG/du at the nodes
  double k_n_ = 0, log_k_ = 0;           // K [N] and ln K
  double y_lo_ = 0, y_hi_ = 0, dy_ = 0;  // ln(W/K) grid of lambda_dry
  std::vector<double> lam_dry_, lam_dry_slope_;
  std::vector<double> f32_, f32_slope_;  // F_3/2 on lambda in [-8, 12]
};

// ---------------------------------------------------------------- wear

/// Archard wear generalised to mixed lubrication (paper 002 Section 5.4):
/// only the load carried by the solid summits wears, so the wear volume
/// rate per sliding distance is
///
///     dV/ds = K(S) W / H,    K(S) = k_solid alpha(S, W)
///
/// (k_solid: dry Archard coefficient, H: hardness). Wear removes summit
/// altitude: the worn height h = V / A_nominal lowers Alt, which thickens
/// the effective film margin (d - Alt) and lowers friction (running-in).
struct WearParams {
  double k_solid = 1e-6;       ///< dimensionless dry Archard coefficient
  double hardness_mpa = 2000;  ///< H [MPa] (N/mm^2), > 0
};

/// Wear coefficient K(S, W) = k_solid alpha(S, W) [-] (alpha the load
/// fraction: only the solid load wears).
double CalcWearCoefficient(const MixedFrictionTheta& theta,
                           const AsperitySurface& surface,
                           const WearParams& wear,
                           double sommerfeld_um,
                           double load_n);

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
/// @throws FieldError for non-positive distance, points < 2 or
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
