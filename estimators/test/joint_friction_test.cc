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

TEST(MixedFriction, ReproducesTheStribeckRangeOfPaper002) {
  const AsperitySurface surface;
  const MixedFrictionTheta theta = Truth();
  double previous = 1.0;
  double sd_max = 0, s_at_sd_max = 0;
  for (double log_s = -6; log_s <= 1; log_s += 0.05) {
    const double s = std::pow(10.0, log_s);
    const double f = CalcMixedFriction(theta, surface, s);
    EXPECT_LE(f, previous + 1e-15) << "not monotone at S = " << s;
    previous = f;
    const double sd = CalcMixedFrictionDispersion(theta, surface, s);
    if (sd > sd_max) {
      sd_max = sd;
      s_at_sd_max = s;
    }
  }
  // Mixed regime ~0.1 at small S, full film ~0.004 at large S (Sec. 5.1).
  EXPECT_NEAR(CalcMixedFriction(theta, surface, 1e-6), 0.1, 1e-3);
  EXPECT_NEAR(CalcMixedFriction(theta, surface, 10.0), 0.004, 1e-5);
  EXPECT_NEAR(CalcMixedFriction(theta, surface, 0.0), 0.1, 1e-3);
  // Dispersion: none at either end, largest in the mixed regime where
  // d = Alt (alpha = 1/2), i.e. at S = S_ref for d_ref = Alt.
  EXPECT_LT(CalcMixedFrictionDispersion(theta, surface, 1e-6), 0.1 * sd_max);
  EXPECT_LT(CalcMixedFrictionDispersion(theta, surface, 10.0), 1e-6);
  EXPECT_NEAR(std::log10(s_at_sd_max), std::log10(kSommerfeldRefUm), 0.06);
  const double expected_sd =
      0.096 * std::sqrt(0.25 * std::exp(0.16) / surface.summits);
  EXPECT_NEAR(sd_max, expected_sd, 1e-3 * expected_sd);
}

TEST(MixedFriction, SolidFractionIsTheGaussianTail) {
  AsperitySurface s;
  s.alt_um = 0.4;
  s.salt_um = 0.2;
  EXPECT_NEAR(CalcSolidFraction(s, 0.4), 0.5, 1e-15);
  EXPECT_NEAR(CalcSolidFraction(s, 0.4 + 0.2 * 1.959963985), 0.025, 1e-9);
  EXPECT_NEAR(CalcSolidFraction(s, 0.4 - 0.2), 0.841344746, 1e-9);
}

TEST(MixedFriction, JacobiansMatchCentralDifferences) {
  const AsperitySurface surface;
  for (double s : {2e-3, 1e-2, 4e-2}) {
    MixedFrictionThetaRow J;
    double J_s = 0;
    CalcMixedFriction(Truth(), surface, s, &J, &J_s);
    auto f_theta = [&](const VectorXd& x) {
      return VectorXd::Constant(
          1, CalcMixedFriction(MixedFrictionTheta(x), surface, s));
    };
    EXPECT_TRUE(internal::CheckJacobian<double>(
        f_theta, VectorXd(Truth()), MatrixXd(J)))
        << "S = " << s;
    auto f_s = [&](const VectorXd& x) {
      return VectorXd::Constant(1, CalcMixedFriction(Truth(), surface, x[0]));
    };
    EXPECT_TRUE(internal::CheckJacobian<double>(f_s,
                                                VectorXd::Constant(1, s),
                                                MatrixXd::Constant(1, 1, J_s),
                                                1e-6,
                                                1e-6))
        << "S = " << s;
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
  // 3000 contacts of 400 summits each (seed 11) at alpha ~ 0.3.
  const AsperitySurface surface;
  const MixedFrictionTheta theta = Truth();
  const double s = 0.02;
  std::mt19937_64 rng(11);
  const int n = 3000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < n; ++i) {
    const double f = SampleContactFriction(theta, surface, s, &rng);
    sum += f;
    sum2 += f * f;
  }
  const double mean = sum / n;
  const double sd = std::sqrt(sum2 / n - mean * mean);
  const double f = CalcMixedFriction(theta, surface, s);
  const double sd_model = CalcMixedFrictionDispersion(theta, surface, s);
  ASSERT_GT(sd_model, 1e-3);
  EXPECT_NEAR(mean, f, 4 * sd_model / std::sqrt(n));
  // sd of a sample sd ~ sd / sqrt(2n) = 1.3 %; allow 6 %.
  EXPECT_NEAR(sd, sd_model, 0.06 * sd_model);
  // Without radius scatter (a = 0) the dispersion is binomial.
  AsperitySurface equal = surface;
  equal.radius_log_sd = 0;
  EXPECT_LT(CalcMixedFrictionDispersion(theta, equal, s), sd_model);
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
    const double exact = CalcMixedFriction(Truth(), c.surface, s);
    worst = std::max(worst, std::abs(table.Eval(v, load, temp) - exact));
    worst = std::max(worst, std::abs(table.EvalSommerfeld(s) - exact));
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_TRUE(std::isnan(table.Eval(1, 1, -200)));
  EXPECT_NEAR(table.EvalSommerfeld(1e-30),
              CalcMixedFriction(Truth(), c.surface, 1e-30),
              1e-12);
  EXPECT_NEAR(table.EvalSommerfeld(1e6), 0.004, 1e-15);
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
  const JointFitResult at_start =
      FitJointModel(JointModelKind::kMixed, data, config, [&] {
        JointFitOptions o = options;
        o.max_iterations = 1;
        return o;
      }());
  const JointFitResult r =
      FitJointModel(JointModelKind::kMixed, data, config, options);
  ASSERT_EQ(r.status, JointFitStatus::kConverged) << r.why;
  EXPECT_GT(at_start.residual_rms, 5 * r.residual_rms);
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
    const double k = CalcWearCoefficient(Truth(), surface, wear, s);
    EXPECT_LE(k, previous) << s;
    previous = k;
  }
  EXPECT_NEAR(CalcWearCoefficient(Truth(), surface, wear, 1e-6), 1e-6, 1e-9);
  EXPECT_LT(CalcWearCoefficient(Truth(), surface, wear, 10.0), 1e-12);
  JointContact contact;
  // 100 N on 50 mm^2, 1 km of sliding in the mixed regime.
  const auto run =
      PredictWearDrift(Truth(), surface, wear, contact, 0.01, 100.0, 1e6, 11);
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
                  Truth(), surface, wear, contact, 0.01, 100.0, -1, 3);
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
  const double s_um = 0.004, load_n = 100, v_mm_s = 100;
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
