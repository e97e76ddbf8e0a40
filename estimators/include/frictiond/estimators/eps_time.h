#pragma once
/// @file
/// Time correlation of eps (the residual of paper 000 eq. (1)) and the
/// first-passage probability a held grasp needs.
///
/// Paper 000 treats eps as a draw per instant. In every measured stroke eps
/// is correlated in time, so "P(slip)" of a grasp held for 3 s differs a lot
/// from P(slip) at one instant. frictiond describes eps by its marginal
/// distribution F (the empirical quantiles stored with the model, with an
/// exponential lower tail below the 0.001 quantile) and a Gaussian copula:
///
///   eps_t = F^-1(Phi(z_t)),
///   z_t   = sqrt(f) * A + sqrt(1 - f) * w_t,   A ~ N(0, 1) once per episode,
///   w_t   = phi * w_{t-1} + sqrt(1 - phi^2) * e_t,   e_t ~ N(0, 1) i.i.d.,
///
/// sampled every dt_s. f (offset_fraction) is the share of the latent
/// variance that stays constant within an episode (a stroke's, or a grasp's,
/// offset: "across episodes"), phi the AR(1) coefficient per sample of the
/// rest ("within episodes"). Both are identified by the method of moments
/// from the lag-0, -1 and -2 autocovariances of the standardised residuals
/// (standing in for the latent z: equal for Gaussian eps), pooled over
/// consecutive slipping samples of each episode:
///   g0 = 1, g1 = f + (1 - f) phi, g2 = f + (1 - f) phi^2
///   => phi = (g1 - g2) / (g0 - g1),  1 - f = (g0 - g1) / (1 - phi).
///
/// A grasp held for hold_s seconds is one new episode of n = 1 + round(hold_s
/// / dt_s) samples; it slips when eps_t < u at any of them, so
///   P(slip during hold) = 1 - Int phi_N(a) S_n((c - sqrt(f) a)/sqrt(1 - f)) da
/// with c = Phi^-1(F(u)) (F: the stored quantiles, the tail below) and S_n(b) =
/// P(w_0..w_{n-1} >= b) the survival of the stationary AR(1), computed exactly
/// up to quadrature error by iterating its transition kernel on a grid
/// (Nystroem) and extrapolating geometrically once the quasi-stationary decay
/// rate has converged (CalcAr1Survival).
///
/// Departures from the paper (which has none of this): the risk is per hold,
/// not per instant; the time step of "any time" is the sampling interval of
/// the identified data (a slip shorter than one sample is not seen by the
/// data either).
///
/// For simulators (e.g. a MuJoCo plug-in): draw A once per grasp and w_t as
/// above at dt_s, map through Phi and CalcEpsQuantileExtended.
///
/// Offset plus within-episode process (EpsOffsetModel, issue 19). The
/// Gaussian copula above has no tail dependence: with a heavy-tailed
/// per-episode offset it treats an extreme offset as a passing excursion
/// and counts too many independent chances in a hold (served holds slipped
/// at 0.022 for a requested 0.05 over 5 s with Student-t(4) offsets and
/// shocks). When the model carries EpsTimeModel::offset, the offset and the
/// within-episode part keep their OWN (empirical, heavy-tailed allowed)
/// distributions:
///
///   Y_t = a + u_t,  a ~ G once per episode,
///   u_t = phi u_{t-1} + e_t,  e_t ~ E i.i.d.  (a linear AR(1); H: its
///         stationary law; without stored E: u_t = H^-1(Phi(w_t)), w_t the
///         copula's unit AR(1)),
///   eps_t = F^-1(K(Y_t)),  K the CDF of Y_t (G convolved with H).
///
/// The last map keeps F (the stored eps quantiles, their tail) as the
/// marginal, so one instant is unchanged; the decomposition only sets how
/// an instant's risk grows over a hold. A slip at eps level e is Y_t < y
/// with y = K^-1(F(e)), and (paper 000 eq. (1) with its eps per instant,
/// extended to a hold; section IV-A's risk read as the hold's)
///   P(slip during n samples) = 1 - E_a[ S_n(y - a) ],
/// S_n(b) = P(u_0..u_{n-1} >= b): with E, the first passage of the linear
/// AR(1) as a Markov chain on cells of u (transition probabilities from
/// E's CDF, started from H), iterated to its quasi-stationary decay rate
/// and tabulated in b; without E, CalcAr1Survival at Phi^-1(H(b)). E_a is
/// Simpson over a = G^-1(Phi(s)) in the normal score s (851 nodes).
///
/// Identification (FitEpsTimeModel), per episode k of n_k samples with
/// mean m_k and c_k = Var(mean of n_k AR(1) samples) / var_u:
///  - var_u = sum (r - m_k)^2 / sum n_k (1 - c_k),  var_a = mean (m_k -
///    mean)^2 - mean(c_k) var_u (method of moments on the variances);
///  - G: the quantiles of m_k over episodes whose mean is mostly offset
///    (rho_k = var_a / (var_a + c_k var_u) >= 0.5), the noise taken out
///    level by level: q_a(p) - med = sign(d) sqrt(d^2 - z_p^2 noise), d =
///    q_m(p) - med, z_p = Phi^-1(p), noise = mean c_k var_u (exact for
///    Gaussian a; in a heavy tail the noise barely moves the quantiles and
///    they are barely shrunk); the GPD tail below 0.001 from the variance-
///    matched means med + (m_k - med) sqrt(rho_k);
///  - E: the quantiles of (r_t - m_k) - phi (r_{t-1} - m_k) (the episode
///    mean removes a; (1 - phi) mean(u) is left, small), with a GPD tail;
///  - H: the stationary law of u_t = phi u_{t-1} + e_t (the chain iterated
///    from N(0, var_u) until phi^t < 1e-3), the GPD tail shape of the
///    deviations (r - m_k) / sqrt(v_t) (v_t: their variance factor).
/// Not identified (offset.valid = false, holds on the copula above) with
/// f = 0 or 1, var_a <= 0, fewer than 100 usable episodes or fewer than
/// 1000 deviations. Limits: G needs many episodes (its 0.001 quantile is
/// the 1-in-1000 episode); phi is one coefficient for the whole process.
/// A departure from the paper (which has one eps per instant) and from the
/// copula above (kept for models without the decomposition).

#include <memory>
#include <string>
#include <vector>

namespace frictiond {

/// Offset decomposition of eps (optional; stored as eps_time's
/// "offset_decomposition"; see "Offset plus within-episode process" above).
/// Quantiles at EpsQuantileLevels() (stochastic_model.h), each with a
/// generalised Pareto lower tail below the 0.001 level anchored as
/// EpsTimeModel's (tail_scale = 0: an exponential tail through the 0.001
/// and 0.01 quantiles).
struct EpsOffsetModel {
  bool valid = false;  ///< false: holds use the Gaussian copula of z_t
  /// G: the per-episode offset a (deconvolved episode means, see
  /// FitEpsTimeModel).
  std::vector<double> offset_quantiles;
  double offset_tail_xi = 0.0;
  double offset_tail_scale = 0.0;
  /// H: the within-episode part u_t (scaled deviations from the episode
  /// mean).
  std::vector<double> within_quantiles;
  double within_tail_xi = 0.0;
  double within_tail_scale = 0.0;
  /// E: innovations e_t of u_t read as a linear AR(1), u_t = phi u_{t-1} +
  /// e_t (empty: u_t is the Gaussian copula AR(1) H^-1(Phi(w_t))). With
  /// heavy-tailed e a large shock persists for ~1 / (1 - phi) samples,
  /// which the copula (no tail dependence) cannot represent.
  std::vector<double> innovation_quantiles;
  double innovation_tail_xi = 0.0;
  double innovation_tail_scale = 0.0;
  int episodes_used = 0;  ///< episodes behind G
};

/// Identified time structure of eps (stored with the model, JSON field
/// "eps_time" of the stochastic model).
struct EpsTimeModel {
  bool valid = false;  ///< false: not identified (see why); hold_s > 0 refused
  std::string why;     ///< reason when not valid
  double dt_s = 0.0;   ///< sampling interval of the identified data [s]
  double phi = 0.0;    ///< AR(1) coefficient per sample, in [0, 0.98]
  double corr_time_s = 0.0;      ///< -dt_s / ln(phi) (0 when phi = 0) [s]
  double offset_fraction = 0.0;  ///< f: latent variance constant per episode
  int episodes = 0;              ///< episodes (runs of consecutive samples)
  int samples = 0;               ///< residuals used
  /// Effectively independent samples behind the marginal's tail:
  /// sum over episodes of 1 / (f + (1 - f) (1 + phi) / ((1 - phi) n_k)).
  double effective_samples = 0.0;
  /// Smallest per-instant slip probability the data support:
  /// max(1e-6, 1 / effective_samples); below it the eps quantile would be
  /// a guess beyond every independent observation.
  double min_instant_risk = 1.0;
  /// Lower tail of eps beyond the stored quantiles: a generalised Pareto
  /// fit (probability-weighted moments, Hosking & Wallis 1987) to the
  /// residuals below their 2 % quantile, P(eps < q_0.02 - y) = 0.02 (1 +
  /// tail_xi y / tail_scale)^(-1 / tail_xi). tail_xi > 0: heavier than
  /// exponential; Gaussian eps gives about -0.1. tail_scale = 0: no fit
  /// (an exponential tail through the 0.001 and 0.01 quantiles is used).
  double tail_xi = 0.0;
  double tail_scale = 0.0;
  /// Offset plus within-episode process for holds (issue 19); when not
  /// valid (models stored before it, too few episodes) holds use the
  /// Gaussian copula of z_t above, unchanged.
  EpsOffsetModel offset;
};

/// Identifies EpsTimeModel from residuals in time order. episode[i] names
/// the episode of residuals[i]: consecutive samples of one slipping run
/// share an id (a new id wherever a sample was skipped). dt_s: the sampling
/// interval. Needs >= 2 episodes and >= 50 lag pairs; otherwise valid =
/// false with the reason. phi is capped at 0.98 (a conservative cap: a
/// smaller phi means more independent looks per hold, so more grip force).
EpsTimeModel FitEpsTimeModel(const std::vector<double>& residuals,
                             const std::vector<int>& episode,
                             double dt_s);

/// Survival S_n(b) = P(w_t >= b for t = 0..n-1) of a stationary unit AR(1)
/// with coefficient phi in [0, 0.995]. n >= 1. Exact for n = 1 and phi = 0;
/// otherwise quadrature (relative error of the complement below ~1e-4,
/// tested against closed forms and Monte Carlo).
/// @throws std::invalid_argument for n < 1 or phi outside [0, 0.995].
double CalcAr1Survival(double b, int n, double phi);

/// P(z_t < c for some t in 0..n-1) for the latent process above (one
/// episode of n samples). The probability that a hold of n samples slips
/// when the per-instant slip probability is Phi(c).
/// @throws std::invalid_argument as CalcAr1Survival, or f outside [0, 1].
double CalcHoldCrossingProbability(double c,
                                   int n,
                                   double phi,
                                   double offset_fraction);

/// The level c with CalcHoldCrossingProbability(c, n, phi, f) = risk (to
/// 1e-7 in c): the per-instant slip probability Phi(c) a hold of n samples
/// may have. Tabulates S_n once.
/// @throws std::invalid_argument as CalcHoldCrossingProbability, or risk
/// outside (0, 1).
double CalcHoldCrossingLevel(double risk,
                             int n,
                             double phi,
                             double offset_fraction);

/// The one rule for holds: P(slip at any of n samples) of a hold whose
/// per-instant slip probability is p in [0, 1]. n = 1: p. With
/// t.offset.valid the offset decomposition above, else the Gaussian copula
/// (CalcHoldCrossingProbability(Phi^-1(p), n, phi, f), as before). Used by
/// the grip force, the smallest supported risk and the slip probability of
/// a hold (grip_force.h), so every route and the client library agree.
/// @throws std::invalid_argument for p outside [0, 1], n < 1, or phi, f
/// out of range.
double CalcHoldSlipFromInstant(double p, int n, const EpsTimeModel& t);

/// The inverse: the per-instant slip probability p with
/// CalcHoldSlipFromInstant(p, n, t) = risk (n = 1: risk).
/// @throws std::invalid_argument for risk outside (0, 1), as above.
double CalcInstantRiskForHold(double risk, int n, const EpsTimeModel& t);

namespace internal {
class OffsetHold;
}  // namespace internal

/// The same rule for one model and hold length, tabulated once for both
/// directions (the two functions above build one per call; CalcGripForce
/// asks both). Keeps a copy of what it needs, so it may outlive t.
/// Move-only.
class HoldSlipRule {
 public:
  /// @throws std::invalid_argument for n < 1, or (with the decomposition)
  /// phi out of range or a malformed EpsTimeModel::offset.
  HoldSlipRule(const EpsTimeModel& t, int n);
  ~HoldSlipRule();
  HoldSlipRule(HoldSlipRule&&) noexcept;
  HoldSlipRule& operator=(HoldSlipRule&&) noexcept;
  HoldSlipRule(const HoldSlipRule&) = delete;
  HoldSlipRule& operator=(const HoldSlipRule&) = delete;

  /// CalcHoldSlipFromInstant(p, n, t).
  double SlipFromInstant(double p) const;
  /// CalcInstantRiskForHold(risk, n, t).
  double InstantRiskFor(double risk) const;
  /// n: samples of the hold.
  int samples() const { return n_; }

 private:
  int n_ = 1;
  double phi_ = 0.0, offset_fraction_ = 0.0;          // the copula's (no impl_)
  std::unique_ptr<const internal::OffsetHold> impl_;  // the decomposition
};

/// For simulators of the offset decomposition: G^-1(p), H^-1(p), E^-1(p)
/// (the stored quantiles with their lower tails) and K(y) = P(a + u_t <
/// y). Per episode draw a = CalcOffsetQuantile(t, U) and u_0 =
/// CalcWithinQuantile(t, U'), then u_t = phi u_{t-1} +
/// CalcInnovationQuantile(t, U_t) (with stored innovations; without them
/// u_t = CalcWithinQuantile(t, Phi(w_t)), w_t the unit AR(1)), and eps_t =
/// CalcEpsQuantileExtended(mu, CalcOffsetSumCdf(t, a + u_t), t). K costs
/// 851 terms: tabulate it for hot loops. The copula sampling above is
/// unchanged.
/// @throws std::invalid_argument when t.offset is not valid (or, for
/// CalcInnovationQuantile, has no innovations).
double CalcOffsetQuantile(const EpsTimeModel& t, double p);
double CalcWithinQuantile(const EpsTimeModel& t, double p);
double CalcInnovationQuantile(const EpsTimeModel& t, double p);
double CalcOffsetSumCdf(const EpsTimeModel& t, double y);

}  // namespace frictiond
