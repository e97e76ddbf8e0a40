#include "frictiond/estimators/joint_friction.h"

#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/diagnosis.h"
#include "frictiond/estimators/joint_identification.h"

#include "jacobian_tester.h"

namespace frictiond {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// The truth of the joint tests: paper 002's range (0.1 mixed, 0.004 full
// film), a 0.5 um film at S = 0.01 um, hydrodynamic-like exponent 0.6.
MixedFrictionTheta Truth() {
  return MakeMixedFrictionTheta(0.1, 0.004, 0.5, 0.6);
}

std::string ThrowMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no throw)";
}

// Joint operating states: speeds 5..2000 mm/s (log-uniform), loads
// 20..200 N, temperatures 20..80 C. Fixed seed.
struct States {
  std::vector<double> v, load, temp;
};
States MakeStates(int n, unsigned seed, double t_lo = 20, double t_hi = 80) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  States s;
  for (int i = 0; i < n; ++i) {
    s.v.push_back(5.0 * std::pow(400.0, u(rng)));
    s.load.push_back(20.0 + 180.0 * u(rng));
    s.temp.push_back(t_lo + (t_hi - t_lo) * u(rng));
  }
  return s;
}

// Reference F_nu(lambda) by a rule independent of CalcSummitIntegrals: t =
// e^x, F_nu = int e^((nu+1) x) phi(lambda + e^x) dx, trapezoid in x (smooth,
// decaying at both ends, so the trapezoid converges exponentially).
double ReferenceF(double nu, double lambda) {
  const double x_hi = std::log(std::max(0.0, -lambda) + 12.0);
  const double x_lo = -90.0 / (nu + 1.0);
  const double h = 0.002;
  long double sum = 0;
  for (double x = x_lo; x <= x_hi; x += h) {
    const double t = std::exp(x);
    const double s = lambda + t;
    sum += std::exp((nu + 1) * x - 0.5 * s * s);
  }
  return static_cast<double>(sum * h) * 0.3989422804014327;
}

TEST(SummitIntegrals, MatchAnIndependentQuadratureAndClosedForms) {
  double worst = 0, worst_lambda = 0;
  for (double lambda = -60; lambda <= 30; lambda += 0.37) {
    const SummitIntegrals f = CalcSummitIntegrals(lambda);
    const double got[4] = {f.f_m12, f.f_12, f.f_32, f.f_3};
    const double nu[4] = {-0.5, 0.5, 1.5, 3.0};
    for (int k = 0; k < 4; ++k) {
      const double ref = ReferenceF(nu[k], lambda);
      if (ref < 1e-280) continue;  // below double range: nothing to compare
      const double rel = std::abs(got[k] - ref) / ref;
      if (rel > worst) {
        worst = rel;
        worst_lambda = lambda;
      }
    }
  }
  EXPECT_LT(worst, 1e-12) << "at lambda = " << worst_lambda;
  // F_nu(0) = 2^((nu-1)/2) Gamma((nu+1)/2) / sqrt(2 pi).
  const SummitIntegrals f0 = CalcSummitIntegrals(0.0);
  auto at0 = [](double nu) {
    return std::pow(2.0, 0.5 * (nu - 1)) * std::tgamma(0.5 * (nu + 1)) /
           std::sqrt(2 * M_PI);
  };
  EXPECT_NEAR(f0.f_m12, at0(-0.5), 1e-14 * at0(-0.5));
  EXPECT_NEAR(f0.f_12, at0(0.5), 1e-14 * at0(0.5));
  EXPECT_NEAR(f0.f_32, at0(1.5), 1e-14 * at0(1.5));
  EXPECT_NEAR(f0.f_3, at0(3.0), 1e-14 * at0(3.0));
  // Integer order in closed form: F_0 = Q, F_1 = phi - l Q,
  // F_2 = F_0 - l F_1, F_3 = 2 F_1 - l F_2; half orders by the recursion
  // F_3/2 = 1/2 F_-1/2 - l F_1/2 (integration by parts).
  for (double l = -20; l <= 3; l += 0.5) {
    const SummitIntegrals f = CalcSummitIntegrals(l);
    const double q = 0.5 * std::erfc(l / std::sqrt(2.0));
    const double phi = std::exp(-0.5 * l * l) / std::sqrt(2 * M_PI);
    const double f1 = phi - l * q, f2 = q - l * f1, f3 = 2 * f1 - l * f2;
    EXPECT_NEAR(f.f_3, f3, 1e-12 * f3) << l;
    EXPECT_NEAR(f.f_32, 0.5 * f.f_m12 - l * f.f_12, 1e-12 * f.f_32) << l;
  }
  EXPECT_TRUE(std::isnan(CalcSummitIntegrals(NAN).f_32));
}

TEST(MixedFriction, SolidFractionIsTheHertzLoadFractionOfEq6) {
  // alpha against a brute-force double integral of eq. 6's elastic term
  // over p(z, R) = p1(z) p2(R) (eq. 7), summing N 4/3 E* sqrt(R) (z-d)^3/2
  // on a grid in z and ln R* (no factorisation, no F_3/2 used).
  AsperitySurface s;
  s.alt_um = 0.4;
  s.salt_um = 0.2;
  s.radius_log_sd = 0.7;
  s.radius_log_mean = 0.3;
  for (double d : {0.2, 0.4, 0.7}) {
    const double load = 60.0;
    long double w = 0;
    const int nz = 4000, nr = 400;
    const double z_hi = s.alt_um + 12 * s.salt_um;
    const double hz = (z_hi - d) / nz;
    const double hr = 16.0 * s.radius_log_sd / nr;
    for (int i = 0; i <= nz; ++i) {
      const double z = d + hz * i;
      const double wz = (i == 0 || i == nz) ? 0.5 : 1.0;
      const double p1 =
          std::exp(-0.5 * std::pow((z - s.alt_um) / s.salt_um, 2)) /
          (s.salt_um * std::sqrt(2 * M_PI));  // eq. 2 [1/um]
      const double delta_mm = (z - d) * 1e-3;
      for (int j = 0; j <= nr; ++j) {
        const double x = s.radius_log_mean - 8 * s.radius_log_sd + hr * j;
        const double wr = (j == 0 || j == nr) ? 0.5 : 1.0;
        const double p2 =  // eq. 4 in x = ln R*
            std::exp(-0.5 *
                     std::pow((x - s.radius_log_mean) / s.radius_log_sd, 2)) /
            (s.radius_log_sd * std::sqrt(2 * M_PI));
        const double r_mm = s.srad_um * std::exp(x) * 1e-3;  // eq. 5
        w += wz * wr * p1 * p2 * (4.0 / 3.0) * s.modulus_gpa * 1e3 *
             std::sqrt(r_mm) * std::pow(delta_mm, 1.5);
      }
    }
    const double w_solid = static_cast<double>(w) * hz * hr * s.summits;
    const double alpha = CalcSolidFraction(s, d, load);
    ASSERT_LT(w_solid, load) << d;  // mixed regime: not clipped
    // The trapezoid in z meets the (z-d)^3/2 endpoint: error ~ hz^2.5.
    EXPECT_NEAR(alpha, w_solid / load, 1e-5 * alpha) << "d = " << d;
    // Not the fraction of summits touching (the pre-issue-19 alpha).
    EXPECT_GT(std::abs(alpha - CalcTouchingFraction(s, d)), 0.05) << d;
  }
}

TEST(MixedFriction, SolidFractionLimitsDryAndFullFilm) {
  const AsperitySurface s;  // K = 17.2 N, Hertz capacity at d = 0: 110 N
  const double k = CalcAsperityLoadScaleN(s);
  EXPECT_NEAR(k,
              400 * 4.0 / 3 * 115.4e3 * std::sqrt(0.02) * std::exp(0.08) *
                  std::pow(0.15e-3, 1.5),
              1e-9 * k);
  for (double load : {5.0, 50.0, 500.0, 5000.0}) {
    // No film: dry, alpha = 1, at every load (d_dry > 0 or < 0).
    EXPECT_EQ(CalcSolidFraction(s, 0.0, load), 1.0) << load;
    const double d_dry = CalcDrySeparationUm(s, load);
    const double lambda = (d_dry - s.alt_um) / s.salt_um;
    EXPECT_NEAR(k * CalcSummitIntegrals(lambda).f_32, load, 1e-10 * load);
    EXPECT_EQ(d_dry<0, load> 110) << load << " d_dry " << d_dry;
    double previous = 1.0;
    const double start = std::max(0.0, d_dry) + 1e-3;
    for (double d = start; d < 3.0; d += 0.01) {
      double J = 0;
      const double a = CalcSolidFraction(s, d, load, &J);
      ASSERT_GE(a, 0.0);
      ASSERT_LE(a, previous) << "load " << load << " d " << d;
      ASSERT_LE(J, 0.0);
      previous = a;
    }
    // Full film: Alt + 12 SAlt above the datum carries nothing.
    EXPECT_LT(CalcSolidFraction(
                  s, std::max(0.0, -d_dry) + s.alt_um + 12 * s.salt_um, load),
              1e-25)
        << load;
  }
  // Below the dry separation the summits carry the whole load.
  EXPECT_EQ(CalcSolidFraction(s, 0.5 * CalcDrySeparationUm(s, 50.0), 50.0),
            1.0);
  // At one film thickness a heavier load leaves a smaller share to the
  // summits (their Hertz load is fixed by d; the fluid takes the rest).
  EXPECT_GT(CalcSolidFraction(s, 0.45, 20.0),
            2 * CalcSolidFraction(s, 0.45, 80.0));
  EXPECT_TRUE(std::isnan(CalcSolidFraction(s, 0.45, 0.0)));
}

TEST(MixedFriction, ReproducesTheStribeckRangeOfPaper002) {
  const AsperitySurface surface;
  const MixedFrictionTheta theta = Truth();
  for (double load : {20.0, 100.0, 200.0}) {
    double previous = 1.0;
    double sd_max = 0;
    for (double log_s = -6; log_s <= 1; log_s += 0.05) {
      const double s = std::pow(10.0, log_s);
      const double f = CalcMixedFriction(theta, surface, s, load);
      EXPECT_LE(f, previous + 1e-15) << "not monotone at S = " << s;
      previous = f;
      sd_max = std::max(sd_max,
                        CalcMixedFrictionDispersion(theta, surface, s, load));
    }
    // Mixed regime ~0.1 at small S, full film ~0.004 at large S (Sec. 5.1);
    // dry (f = f_s exactly) with no film.
    EXPECT_NEAR(CalcMixedFriction(theta, surface, 1e-6, load), 0.1, 1e-3);
    EXPECT_NEAR(CalcMixedFriction(theta, surface, 10.0, load), 0.004, 1e-5);
    EXPECT_EQ(CalcMixedFriction(theta, surface, 0.0, load), 0.1);
    // Dispersion: none at either end, some in the mixed regime.
    EXPECT_GT(sd_max, 1e-4) << load;
    EXPECT_EQ(CalcMixedFrictionDispersion(theta, surface, 0.0, load), 0.0);
    EXPECT_LT(CalcMixedFrictionDispersion(theta, surface, 10.0, load), 1e-9);
  }
}

TEST(MixedFriction, JacobiansMatchCentralDifferences) {
  const AsperitySurface surface;
  for (double load : {30.0, 150.0}) {
    for (double s : {3e-4, 1e-3, 4e-3, 1e-2}) {
      MixedFrictionThetaRow J;
      double J_s = 0;
      CalcMixedFriction(Truth(), surface, s, load, &J, &J_s);
      auto f_theta = [&](const VectorXd& x) {
        return VectorXd::Constant(
            1, CalcMixedFriction(MixedFrictionTheta(x), surface, s, load));
      };
      EXPECT_TRUE(internal::CheckJacobian<double>(
          f_theta, VectorXd(Truth()), MatrixXd(J)))
          << "S = " << s << " load " << load;
      auto f_s = [&](const VectorXd& x) {
        return VectorXd::Constant(
            1, CalcMixedFriction(Truth(), surface, x[0], load));
      };
      EXPECT_TRUE(internal::CheckJacobian<double>(f_s,
                                                  VectorXd::Constant(1, s),
                                                  MatrixXd::Constant(1, 1, J_s),
                                                  1e-6 * s,
                                                  1e-6))
          << "S = " << s << " load " << load;
    }
  }
  const JointConfig config;
  VectorXd sv(5);
  sv << 0.02, 0.09, 40.0, 1.5, 1e-5;
  VectorXd lg(4);
  lg << 0.09, 0.02, 40.0, 1e-5;
  for (auto [kind, theta] :
       {std::make_pair(JointModelKind::kStribeckViscous, sv),
        std::make_pair(JointModelKind::kLuGreSteadyState, lg)}) {
    Eigen::RowVectorXd J;
    PredictJointFriction(kind, theta, config, 30.0, 100.0, 0.05, &J);
    auto f = [&, kind = kind](const VectorXd& x) {
      return VectorXd::Constant(
          1, PredictJointFriction(kind, x, config, 30.0, 100.0, 0.05));
    };
    EXPECT_TRUE(internal::CheckJacobian<double>(f, theta, MatrixXd(J)))
        << ToString(kind);
  }
}

TEST(MixedFriction, SampledContactsMatchTheDispersionFormula) {
  // 3000 contacts of 400 Hertz summits each (seed 11), mixed regime.
  const AsperitySurface surface;
  const MixedFrictionTheta theta = Truth();
  const double load = 60.0;
  const double s = 5e-3;
  const double alpha =
      CalcSolidFraction(surface, CalcFilmThicknessUm(theta, s), load);
  ASSERT_GT(alpha, 0.2);
  ASSERT_LT(alpha, 0.6);
  std::mt19937_64 rng(11);
  const int n = 3000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const double f = SampleContactFriction(theta, surface, s, load, &rng);
    sum += f;
    sum2 += f * f;
  }
  const double mean = sum / n;
  const double sd = std::sqrt(sum2 / n - mean * mean);
  const double f = CalcMixedFriction(theta, surface, s, load);
  const double sd_model = CalcMixedFrictionDispersion(theta, surface, s, load);
  std::cout << "alpha " << alpha << " f " << f << " sampled " << mean
            << " sd model " << sd_model << " sampled " << sd << "\n";
  ASSERT_GT(sd_model, 1e-3);
  EXPECT_NEAR(mean, f, 4 * sd_model / std::sqrt(n));
  // sd of a sample sd ~ sd / sqrt(2n) (1.3 %) plus the second-order terms
  // of the ratio W_solid / W (heavy-tailed Hertz loads); allow 8 %.
  EXPECT_NEAR(sd, sd_model, 0.08 * sd_model);
  // Without radius scatter (a = 0) the dispersion is smaller.
  AsperitySurface equal = surface;
  equal.radius_log_sd = 0;
  EXPECT_LT(CalcMixedFrictionDispersion(theta, equal, s, load), sd_model);
}

TEST(MixedFriction, TableMatchesTheClosedForm) {
  const JointConfig c;
  const MixedFrictionTable table(Truth(), c.surface, c.lubricant, c.contact);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst = 0;
  for (int i = 0; i < 20000; ++i) {
    const double v = 0.01 * std::pow(1e6, u(rng));
    const double load = 1.0 + 999.0 * u(rng);
    const double temp = -10.0 + 120.0 * u(rng);
    const double eta = CalcViscosity(c.lubricant, temp);
    const double s = CalcSommerfeldUm(eta, v, load, c.contact);
    const double exact = CalcMixedFriction(Truth(), c.surface, s, load);
    worst = std::max(worst, std::abs(table.Eval(v, load, temp) - exact));
    worst = std::max(worst, std::abs(table.EvalSommerfeld(s, load) - exact));
  }
  // Heavy loads: lambda_dry far below -8 (asymptotic F_3/2).
  for (double load : {2e3, 1e4, 1e5, 1e7}) {
    for (double s = 1e-6; s < 10; s *= 1.7) {
      const double exact = CalcMixedFriction(Truth(), c.surface, s, load);
      worst = std::max(worst, std::abs(table.EvalSommerfeld(s, load) - exact));
    }
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_TRUE(std::isnan(table.Eval(1, 1, -200)));
  EXPECT_TRUE(std::isnan(table.EvalSommerfeld(1e-3, 0.0)));
  EXPECT_NEAR(table.EvalSommerfeld(1e-30, 50.0),
              CalcMixedFriction(Truth(), c.surface, 1e-30, 50.0),
              1e-12);
  EXPECT_NEAR(table.EvalSommerfeld(1e6, 50.0), 0.004, 1e-15);
}

TEST(MixedFriction, ViscosityFollowsTheDocumentedVogelConstants) {
  const Lubricant oil;
  // ISO VG 68: 68 cSt at 40 C, 8.7 cSt at 100 C, density ~0.87.
  EXPECT_NEAR(CalcViscosity(oil, 40.0), 68e-6 * 870, 0.02 * 68e-6 * 870);
  EXPECT_NEAR(CalcViscosity(oil, 100.0), 8.7e-6 * 870, 0.03 * 8.7e-6 * 870);
  EXPECT_TRUE(std::isnan(CalcViscosity(oil, -200.0)));
  // S = eta V / p: 0.06 Pa s, 100 mm/s, 100 N on 50 mm^2 (2 MPa) -> 3e-9 m.
  JointContact c;
  c.area_mm2 = 50;
  EXPECT_NEAR(CalcSommerfeldUm(0.06, 100.0, 100.0, c), 3e-3, 1e-12);
}

TEST(JointIdentification, RecoversTheMixedModelWithCovariance) {
  const JointConfig config;
  const States st = MakeStates(600, /*seed=*/7);
  const JointData data = SimulateJointData(
      Truth(), config, st.v, st.load, st.temp, /*noise=*/0.002, 7);
  JointFitOptions options;
  options.start = Eigen::Vector4d(0.3, 0.03, 3.0, 1.5);
  // The start is far from a solution.
  double start_ss = 0;
  for (std::size_t i = 0; i < data.size(); ++i)
    start_ss += std::pow(PredictJointFriction(JointModelKind::kMixed,
                                              options.start,
                                              config,
                                              data.v_mm_s[i],
                                              data.load_n[i],
                                              data.eta_pa_s[i]) -
                             data.mu[i],
                         2);
  const double start_rms = std::sqrt(start_ss / data.size());
  const JointFitResult r =
      FitJointModel(JointModelKind::kMixed, data, config, options);
  ASSERT_EQ(r.status, JointFitStatus::kConverged) << r.why;
  EXPECT_GT(start_rms, 5 * r.residual_rms);
  const char* names[] = {"f_s", "f_l", "d_ref_um", "n"};
  for (int i = 0; i < 4; ++i) {
    const double sd = std::sqrt(r.P_theta(i, i));
    EXPECT_NEAR(r.theta[i], Truth()[i], 4 * sd)
        << names[i] << ": expected " << Truth()[i] << ", got " << r.theta[i]
        << " +- " << sd;
    // Stated tolerance: friction coefficients within 0.001 (1 % of the
    // drop f_s - f_l), film parameters within 10 %.
    EXPECT_NEAR(r.theta[i], Truth()[i], i < 2 ? 1e-3 : 0.1 * Truth()[i])
        << names[i];
    EXPECT_GT(sd, 0) << names[i];
    std::cout << names[i] << ": true " << Truth()[i] << ", fitted "
              << r.theta[i] << " +- " << sd << "\n";
  }
}

TEST(JointIdentification, PredictionCombinesScatterAndParametersAndFloors) {
  const JointConfig config;
  JointFitResult mixed;
  mixed.kind = JointModelKind::kMixed;
  mixed.status = JointFitStatus::kConverged;
  mixed.theta = Eigen::Vector4d(Truth());
  mixed.P_theta = Eigen::Matrix4d::Zero();
  const double s = 0.5, load = 100.0;
  // Known parameters: the sd is the contact scatter alone, the mean eq. 1.
  MixedFrictionPrediction p =
      PredictMixedFriction(mixed, config.surface, s, load);
  EXPECT_EQ(p.mu, CalcMixedFriction(Truth(), config.surface, s, load));
  EXPECT_EQ(p.sigma_param, 0.0);
  EXPECT_EQ(p.sigma,
            CalcMixedFrictionDispersion(Truth(), config.surface, s, load));
  EXPECT_NEAR(p.lo95, p.mu - 1.959964 * p.sigma, 1e-15);
  EXPECT_NEAR(p.hi95, p.mu + 1.959964 * p.sigma, 1e-15);
  EXPECT_FALSE(p.floored_at_zero);
  // Uncertain parameters: sigma_param = sqrt(J P J'), here P = c I.
  mixed.P_theta = 1e-4 * Eigen::Matrix4d::Identity();
  MixedFrictionThetaRow J;
  CalcMixedFriction(Truth(), config.surface, s, load, &J);
  p = PredictMixedFriction(mixed, config.surface, s, load);
  EXPECT_NEAR(p.sigma_param, std::sqrt(1e-4 * J.squaredNorm()), 1e-15);
  EXPECT_NEAR(p.sigma, std::hypot(p.sigma_contact, p.sigma_param), 1e-15);
  // So uncertain that the Gaussian interval reaches below 0: floored, and
  // said so; the upper bound is unchanged.
  mixed.P_theta = 1.0 * Eigen::Matrix4d::Identity();
  p = PredictMixedFriction(mixed, config.surface, s, load);
  ASSERT_LT(p.mu - 1.959964 * p.sigma, 0.0);
  EXPECT_EQ(p.lo95, 0.0);
  EXPECT_TRUE(p.floored_at_zero);
  EXPECT_NEAR(p.hi95, p.mu + 1.959964 * p.sigma, 1e-12);
}

TEST(JointIdentification, CoverageOfTheCovarianceOverSeeds) {
  const JointConfig config;
  int inside = 0, total = 0;
  for (unsigned seed = 1; seed <= 8; ++seed) {
    const States st = MakeStates(300, seed);
    const JointData data =
        SimulateJointData(Truth(), config, st.v, st.load, st.temp, 0.002, seed);
    const JointFitResult r =
        FitJointModel(JointModelKind::kMixed, data, config);
    ASSERT_EQ(r.status, JointFitStatus::kConverged) << seed << ": " << r.why;
    for (int i = 0; i < 4; ++i, ++total)
      if (std::abs(r.theta[i] - Truth()[i]) <= 2 * std::sqrt(r.P_theta(i, i)))
        ++inside;
  }
  // 2-sigma intervals should hold ~95 %; 32 draws: at least 26 (p ~ 0.01).
  EXPECT_GE(inside, 26) << inside << " of " << total;
}

// A generator wider than the mixed model's assumptions, summit by summit:
// altitude and radius correlated (rho 0.3; eq. 7 assumes independence),
// summit count per contact drawn in [300, 500] (model: 400), film
// thickness off the film law by a lognormal factor (sd 5 %), and Student-t
// sensor noise with 3 degrees of freedom (scale 0.002). Seeded.
struct Widening {
  double rho = 0.3;           // altitude-radius correlation
  double film_jitter = 0.05;  // lognormal sd of d around the film law
};

JointData SimulateWiderJointData(const MixedFrictionTheta& theta,
                                 const JointConfig& config,
                                 const States& st,
                                 unsigned seed,
                                 const Widening& wide = {}) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::student_t_distribution<double> student(3.0);
  std::uniform_int_distribution<int> count(300, 500);
  const AsperitySurface& surf = config.surface;
  const double rho = wide.rho, e_star = surf.modulus_gpa * 1e3;
  JointData d;
  d.v_mm_s = st.v;
  d.load_n = st.load;
  d.temp_c = st.temp;
  for (std::size_t i = 0; i < st.v.size(); ++i) {
    const double eta = CalcViscosity(config.lubricant, st.temp[i]);
    const double s = CalcSommerfeldUm(eta, st.v[i], st.load[i], config.contact);
    double film = CalcFilmThicknessUm(theta, s) *
                  std::exp(wide.film_jitter * normal(rng));
    film += std::min(0.0, CalcDrySeparationUm(surf, st.load[i]));
    const int n = count(rng);
    double w = 0;
    for (int k = 0; k < n; ++k) {
      const double xz = normal(rng);
      const double xr = rho * xz + std::sqrt(1 - rho * rho) * normal(rng);
      const double z = surf.alt_um + surf.salt_um * xz;
      if (z <= film) continue;
      const double r_mm =
          surf.srad_um * 1e-3 *
          std::exp(surf.radius_log_mean + surf.radius_log_sd * xr);
      const double delta_mm = (z - film) * 1e-3;
      w +=
          4.0 / 3.0 * e_star * std::sqrt(r_mm) * delta_mm * std::sqrt(delta_mm);
    }
    const double alpha = std::min(1.0, w / st.load[i]);
    d.eta_pa_s.push_back(eta);
    d.mu.push_back(alpha * theta[0] + (1 - alpha) * theta[1] +
                   0.002 * student(rng));
  }
  return d;
}

TEST(JointIdentification, RecoversFromAWiderGenerator) {
  // Three generators, 6 seeds each, 400 samples, the estimator's nominal
  // config. Stated tolerance: friction coefficients within 0.005 (f_s comes
  // out about 0.002 low: alpha = min(1, sum / W) with a random summit count
  // sits below its mean near the dry limit, Jensen), d_ref
  // within 10 %, n within 10 % when altitude and radius are independent
  // (eq. 7 holds) and within 20 % when they are correlated (rho 0.3 biases
  // n upwards by about 0.05 on average: taller summits are blunter and carry
  // more load, which the fit reads as a steeper film law).
  const JointConfig config;
  const char* names[] = {"f_s", "f_l", "d_ref_um", "n"};
  for (const Widening w :
       {Widening{0.0, 0.0}, Widening{0.0, 0.05}, Widening{0.3, 0.05}}) {
    int inside = 0, total = 0;
    double bias[4] = {0, 0, 0, 0};
    for (unsigned seed = 31; seed < 37; ++seed) {
      const States st = MakeStates(400, seed);
      const JointData data =
          SimulateWiderJointData(Truth(), config, st, seed, w);
      const JointFitResult r =
          FitJointModel(JointModelKind::kMixed, data, config);
      ASSERT_EQ(r.status, JointFitStatus::kConverged) << seed << ": " << r.why;
      for (int i = 0; i < 4; ++i, ++total) {
        const double sd = std::sqrt(r.P_theta(i, i));
        if (std::abs(r.theta[i] - Truth()[i]) <= 2 * sd) ++inside;
        bias[i] += (r.theta[i] - Truth()[i]) / 6;
        const double tol = i < 2   ? 5e-3
                           : i < 3 ? 0.1 * Truth()[i]
                                   : (w.rho > 0 ? 0.2 : 0.1) * Truth()[i];
        EXPECT_NEAR(r.theta[i], Truth()[i], tol)
            << "rho " << w.rho << " jitter " << w.film_jitter << " seed "
            << seed << " " << names[i] << " +- " << sd;
      }
    }
    // Reported, not asserted at 95 %: the robust covariance does not see
    // the misspecification bias.
    std::cout << "rho " << w.rho << " film jitter " << w.film_jitter
              << ": mean error f_s " << bias[0] << ", f_l " << bias[1]
              << ", d_ref " << bias[2] << ", n " << bias[3] << "; " << inside
              << " of " << total << " inside 2 sd\n";
  }
}

TEST(JointIdentification, TemperatureEntersThroughSommerfeld) {
  // Train at 20-40 C, test at 60-80 C, speeds and loads as before: only the
  // mixed model sees that hot oil thins the film (lower eta -> lower S).
  const JointConfig config;
  const States cold = MakeStates(300, 21, 20, 40);
  const States hot = MakeStates(300, 22, 60, 80);
  States all = cold;
  all.v.insert(all.v.end(), hot.v.begin(), hot.v.end());
  all.load.insert(all.load.end(), hot.load.begin(), hot.load.end());
  all.temp.insert(all.temp.end(), hot.temp.begin(), hot.temp.end());
  const JointData data =
      SimulateJointData(Truth(), config, all.v, all.load, all.temp, 0.002, 21);
  std::vector<int> fold(data.size(), 0);
  for (std::size_t i = cold.v.size(); i < data.size(); ++i) fold[i] = 1;
  // Fold 1 (hot) held out when fitting fold 0 and vice versa.
  const std::vector<JointModelScore> s =
      CompareJointModels(data, config, 2, fold);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].kind, JointModelKind::kMixed);
  EXPECT_EQ(s[0].folds_fitted, 2);
  for (const JointModelScore& m : s)
    std::cout << ToString(m.kind) << ": held-out RMSE " << m.heldout_rmse
              << "\n";
  for (int i = 1; i < 3; ++i) {
    EXPECT_LT(2 * s[0].heldout_rmse, s[i].heldout_rmse)
        << "mixed " << s[0].heldout_rmse << " vs " << ToString(s[i].kind) << " "
        << s[i].heldout_rmse;
  }
  // Mixed model error near the noise + contact scatter level.
  EXPECT_LT(s[0].heldout_rmse, 0.008);
}

TEST(JointIdentification, NullCaseFindsNoStribeckDrop) {
  // Constant friction 0.05 +- 0.002: nothing planted, the fit must not claim
  // a significant drop f_s - f_l.
  const JointConfig config;
  const States st = MakeStates(300, 5);
  const JointData data =
      SimulateJointData(MakeMixedFrictionTheta(0.05, 0.05, 0.5, 0.6),
                        config,
                        st.v,
                        st.load,
                        st.temp,
                        0.002,
                        5);
  const JointFitResult r = FitJointModel(JointModelKind::kMixed, data, config);
  // d_ref and n are not identified without a drop, so the fit may stop at
  // the iteration limit or report rank deficiency; whatever it returns, a
  // drop must not be significant.
  if (r.status != JointFitStatus::kNotObservable) {
    const double drop = r.theta[0] - r.theta[1];
    const double var = r.P_theta(0, 0) + r.P_theta(1, 1) - 2 * r.P_theta(0, 1);
    EXPECT_LT(drop, 3 * std::sqrt(std::max(var, 0.0)) + 0.002)
        << "drop " << drop << " sd " << std::sqrt(var);
  } else {
    EXPECT_EQ(r.status, JointFitStatus::kNotObservable) << r.why;
  }
}

TEST(JointIdentification, RejectsBadDataNamingTheField) {
  JointData d;
  d.v_mm_s = {1, 2};
  d.load_n = {10, -1};
  d.eta_pa_s = {0.05, 0.05};
  d.mu = {0.1, 0.1};
  EXPECT_EQ(ThrowMessage([&] { ValidateJointData(d); }),
            "sample 1: load_n = -1 (must be > 0 and finite)");
  d.load_n = {10, 10};
  d.mu = {0.1};
  EXPECT_EQ(ThrowMessage([&] { ValidateJointData(d); }),
            "v_mm_s has 2 samples, mu has 1");
  EXPECT_EQ(ThrowMessage([] { MakeSurfaceFromRoughness(-1, 1, 1); }),
            "r_um = -1 (must be > 0)");
  AsperitySurface s;
  s.salt_um = 0;
  EXPECT_EQ(ThrowMessage([&] { ValidateSurface(s); }),
            "salt_um = 0 (must be > 0)");
}

TEST(JointWear, WearCoefficientFallsWithSommerfeldAndFrictionDrifts) {
  const AsperitySurface surface;
  const WearParams wear;
  double previous = 1.0;
  for (double s : {1e-5, 1e-3, 1e-2, 3e-2, 1.0}) {
    const double k = CalcWearCoefficient(Truth(), surface, wear, s, 100.0);
    EXPECT_LE(k, previous) << s;
    previous = k;
  }
  EXPECT_NEAR(
      CalcWearCoefficient(Truth(), surface, wear, 1e-6, 100.0), 1e-6, 1e-9);
  EXPECT_LT(CalcWearCoefficient(Truth(), surface, wear, 10.0, 100.0), 1e-12);
  JointContact contact;
  // 50 N on 50 mm^2, 1 km of sliding in the mixed regime (alpha 0.87).
  const auto run =
      PredictWearDrift(Truth(), surface, wear, contact, 0.003, 50.0, 1e6, 11);
  ASSERT_EQ(run.size(), 11u);
  EXPECT_EQ(run.front().worn_um, 0.0);
  for (std::size_t i = 1; i < run.size(); ++i) {
    EXPECT_GT(run[i].worn_um, run[i - 1].worn_um) << i;
    EXPECT_LT(run[i].friction, run[i - 1].friction) << i;
  }
  // Running-in lowers friction by a visible amount.
  EXPECT_LT(run.back().friction, run.front().friction - 0.01);
  // No solid contact (thick film): no wear, no drift.
  const auto film =
      PredictWearDrift(Truth(), surface, wear, contact, 10.0, 100.0, 1e9, 3);
  EXPECT_LT(film.back().worn_um, 1e-9);
  EXPECT_EQ(ThrowMessage([&] {
              PredictWearDrift(
                  Truth(), surface, wear, contact, 0.003, 50.0, -1, 3);
            }),
            "distance_mm = -1 (must be > 0)");
}

// Joint data in stroke form (fn_n = joint load, ft_n = mu * load) whose
// friction drifts with sliding distance by mixed-lubrication wear, with
// random dwells between strokes so that elapsed time and distance differ:
// the diagnosis must name distance_mm (issue 9 item 3). Seed 17.
TEST(JointWear, DiagnosisNamesSlidingDistanceOnJointData) {
  const AsperitySurface surface;
  WearParams wear;
  wear.k_solid = 5e-5;
  const JointContact contact;
  const double s_um = 0.003, load_n = 50, v_mm_s = 100;
  constexpr int kStrokes = 40, kPerStroke = 60;
  const double stroke_mm = v_mm_s * (kPerStroke - 1) * 0.02;
  const auto drift = PredictWearDrift(
      Truth(), surface, wear, contact, s_um, load_n, kStrokes * stroke_mm, 401);
  ASSERT_GT(drift.front().friction - drift.back().friction, 0.02);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> noise(0.0, 0.003);
  std::uniform_real_distribution<double> dwell(0.5, 60.0);
  StrokeData d;
  double t = 0, dist = 0;
  const double step = drift[1].distance_mm;
  for (int k = 0; k < kStrokes; ++k) {
    for (int i = 0; i < kPerStroke; ++i) {
      const std::size_t j = std::min<std::size_t>(
          static_cast<std::size_t>(dist / step), drift.size() - 2);
      const double w = dist / step - static_cast<double>(j);
      const double mu =
          (1 - w) * drift[j].friction + w * drift[j + 1].friction + noise(rng);
      d.t_s.push_back(t);
      d.fn_n.push_back(load_n);
      d.ft_n.push_back(mu * load_n);
      d.v_mm_s.push_back(v_mm_s);
      d.slip.push_back(1);
      d.stroke.push_back(k);
      t += 0.02;
      if (i + 1 < kPerStroke) dist += v_mm_s * 0.02;
    }
    t += dwell(rng);  // unrecorded rest: a time gap, no distance
  }
  DiagnosisOptions options;
  const DiagnosisResult r =
      Diagnose(PrepareDiagnosisData(d, options.labelling), options);
  ASSERT_FALSE(r.findings.empty()) << r.why;
  EXPECT_EQ(r.findings.front().cause, "distance_mm")
      << r.findings.front().cause << ": " << r.findings.front().effect;
  std::cout << "diagnosis: " << r.findings.front().cause << ", gain "
            << r.findings.front().cv_mae_gain_pct << " %, "
            << r.findings.front().effect << "\n";
  // Null case: the same joint without wear; distance must not be named.
  StrokeData flat = d;
  for (std::size_t i = 0; i < flat.size(); ++i)
    flat.ft_n[i] = (drift.front().friction + noise(rng)) * load_n;
  const DiagnosisResult r0 =
      Diagnose(PrepareDiagnosisData(flat, options.labelling), options);
  for (const Finding& f : r0.findings)
    EXPECT_NE(f.cause, "distance_mm") << f.effect;
}

}  // namespace
}  // namespace frictiond
