// A measured stroke replayed in MuJoCo (issue 21 item 4, docs/mujoco.md):
// the reciprocating tribometer trace of data/microtribo_recip (5 N, about
// 0.26 mm/s, PROVENANCE.md). The served model is identified from the first
// half of the constant-load phase (FitStochasticModel, the daemon's fit,
// with the labelling the data needs); the second half is replayed with the
// exported constant, the mean model and the stochastic model, and the
// simulated Ft/Fn is compared with the measured one, sample by sample.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/mujoco/stroke_replay.h"

namespace frictiond::mujoco {
namespace {

constexpr double kTrainFromS = 8.0, kSplitS = 108.0, kReplayToS = 208.0;
constexpr double kSlidingMmS = 0.1;  // clearly sliding (the data's floor
                                     // is 0.02 mm/s, quantisation-noisy)
// Steady sliding: the stage has moved this long in one direction (the
// reversal's presliding ramp takes 0.3 to 0.5 s, PROVENANCE.md).
constexpr double kSteadyAfterS = 0.6;

StrokeData Load() {
  const char* root = std::getenv("FRICTIOND_SOURCE_DIR");
  if (!root) throw std::runtime_error("FRICTIOND_SOURCE_DIR is not set");
  std::ifstream in(std::string(root) +
                   "/data/microtribo_recip/test_data_2.strokes.csv");
  std::stringstream s;
  s << in.rdbuf();
  return ParseStrokeCsv(s.str());
}

std::size_t IndexAt(const StrokeData& d, double t_s) {
  return static_cast<std::size_t>(
      std::lower_bound(d.t_s.begin(), d.t_s.end(), t_s) - d.t_s.begin());
}

StrokeData Slice(const StrokeData& d, std::size_t b, std::size_t e) {
  StrokeData out;
  out.t_s.assign(d.t_s.begin() + b, d.t_s.begin() + e);
  out.fn_n.assign(d.fn_n.begin() + b, d.fn_n.begin() + e);
  out.ft_n.assign(d.ft_n.begin() + b, d.ft_n.begin() + e);
  out.v_mm_s.assign(d.v_mm_s.begin() + b, d.v_mm_s.begin() + e);
  out.covariate_names = d.covariate_names;
  for (const std::vector<double>& c : d.covariates)
    out.covariates.emplace_back(c.begin() + b, c.begin() + e);
  return out;
}

// The served model: eq. (1) fitted on the training half.
StochasticFrictionModel Served(const StrokeData& train) {
  StochasticFitOptions o;
  o.labelling.peak_mm_s = 0.1;  // as the paper-000 report of this data
  o.labelling.floor_mm_s = 0.02;
  o.labelling.median_window_s = 0.05;
  const StochasticFit fit = FitStochasticModel(train, o);
  if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial)
    throw std::runtime_error("fit: " + fit.why);
  return fit.model;
}

struct Errors {
  double rms_all = 0;       // RMS(mu_sim - mu_meas), every replayed sample
  double rms_sliding = 0;   // the same over sliding samples
  double bias_sliding = 0;  // mean(mu_sim - mu_meas) over sliding samples
  double sd_sim = 0;        // SD of mu_sim over sliding samples
  double sd_meas = 0;       // SD of mu_meas over sliding samples
  double bias_steady = 0;   // mean(mu_sim - mu_meas), steady sliding
  double rms_steady = 0;    // RMS(mu_sim - mu_meas), steady sliding
  double sd_steady_sim = 0, sd_steady_meas = 0;  // SDs over steady sliding
  double mean_steady_sim = 0, mean_steady_meas = 0;
};

Errors Compare(const StrokeData& d, std::size_t b, const StrokeReplay& r) {
  Errors e;
  double s_all = 0, s_sl = 0, bias = 0, m_sim = 0, m_meas = 0, q_sim = 0,
         q_meas = 0;
  std::size_t n_sl = 0;
  const std::vector<double>& dir = d.covariates[*d.FindCovariate("dir_sign")];
  double moving_since = d.t_s[b], sum_st = 0, sq_st = 0;
  std::vector<double> st_sim, st_meas;
  for (std::size_t k = 0; k < r.t_s.size(); ++k) {
    const double meas = d.mu(b + k);
    const double sim = r.fn_n[k] > 0 ? r.ft_n[k] / r.fn_n[k] : 0.0;
    s_all += (sim - meas) * (sim - meas);
    if (dir[b + k] == 0 || (k > 0 && dir[b + k] != dir[b + k - 1]))
      moving_since = d.t_s[b + k];
    if (dir[b + k] != 0 && d.v_mm_s[b + k] > kSlidingMmS &&
        d.t_s[b + k] - moving_since >= kSteadyAfterS) {
      sum_st += sim - meas;
      sq_st += (sim - meas) * (sim - meas);
      st_sim.push_back(sim);
      st_meas.push_back(meas);
    }
    if (d.v_mm_s[b + k] > kSlidingMmS) {
      ++n_sl;
      s_sl += (sim - meas) * (sim - meas);
      bias += sim - meas;
      m_sim += sim;
      m_meas += meas;
      q_sim += sim * sim;
      q_meas += meas * meas;
    }
  }
  e.rms_all = std::sqrt(s_all / r.t_s.size());
  e.rms_sliding = std::sqrt(s_sl / n_sl);
  e.bias_sliding = bias / n_sl;
  m_sim /= n_sl;
  m_meas /= n_sl;
  e.sd_sim = std::sqrt(std::max(0.0, q_sim / n_sl - m_sim * m_sim));
  e.sd_meas = std::sqrt(std::max(0.0, q_meas / n_sl - m_meas * m_meas));
  const double n_st = static_cast<double>(st_sim.size());
  e.bias_steady = sum_st / n_st;
  e.rms_steady = std::sqrt(sq_st / n_st);
  for (std::size_t i = 0; i < st_sim.size(); ++i) {
    e.mean_steady_sim += st_sim[i] / n_st;
    e.mean_steady_meas += st_meas[i] / n_st;
  }
  auto sd = [n_st](const std::vector<double>& x) {
    double m = 0, q = 0;
    for (double v : x) m += v;
    m /= n_st;
    for (double v : x) q += (v - m) * (v - m);
    return std::sqrt(q / n_st);
  };
  e.sd_steady_sim = sd(st_sim);
  e.sd_steady_meas = sd(st_meas);
  return e;
}

void Print(const char* name, const Errors& e) {
  std::printf(
      "%-28s RMS all %.4f, RMS sliding %.4f, bias sliding %+.4f, SD "
      "sliding sim %.4f vs measured %.4f; steady: bias %+.4f RMS %.4f SD "
      "sim %.4f vs measured %.4f\n",
      name,
      e.rms_all,
      e.rms_sliding,
      e.bias_sliding,
      e.sd_sim,
      e.sd_meas,
      e.bias_steady,
      e.rms_steady,
      e.sd_steady_sim,
      e.sd_steady_meas);
}

TEST(StrokeReplay, MeasuredStrokeWithConstantMeanAndStochasticModels) {
  const StrokeData data = Load();
  const std::size_t t0 = IndexAt(data, kTrainFromS);
  const std::size_t split = IndexAt(data, kSplitS);
  const std::size_t end = IndexAt(data, kReplayToS);
  const StochasticFrictionModel served = Served(Slice(data, t0, split));
  std::printf(
      "served model: mu = %.4f + %.4f v + %.4f Fn, sigma_eps %.4f, "
      "mu_coulomb %.4f; eps_time valid %d phi %.3f f %.3f dt %.4f\n",
      served.mu.beta(0),
      served.mu.beta.size() > 1 ? served.mu.beta(1) : 0.0,
      served.mu.beta.size() > 2 ? served.mu.beta(2) : 0.0,
      served.mu.sigma_eps,
      served.mu_coulomb,
      served.eps_time.valid,
      served.eps_time.phi,
      served.eps_time.offset_fraction,
      served.eps_time.dt_s);

  StrokeReplayOptions o;
  o.adapter.mode = FrictionMode::kCoulomb;
  const Errors coulomb =
      Compare(data, split, ReplayStroke(data, split, end, served, o));
  Print("exported constant", coulomb);
  o.adapter.mode = FrictionMode::kMean;
  const Errors mean_extrapolated =
      Compare(data, split, ReplayStroke(data, split, end, served, o));
  Print("mean model, extrapolated", mean_extrapolated);
  o.adapter.clamp_to_fitted_inputs = true;
  const Errors mean =
      Compare(data, split, ReplayStroke(data, split, end, served, o));
  Print("mean model, clamped inputs", mean);
  o.adapter.mode = FrictionMode::kStochastic;
  for (std::uint64_t seed : {1, 2, 3}) {
    o.adapter.seed = seed;
    const Errors st =
        Compare(data, split, ReplayStroke(data, split, end, served, o));
    Print(("stochastic, clamped, seed " + std::to_string(seed)).c_str(), st);
  }
  // A constant at the training half's steady sliding level (what a
  // well-chosen Coulomb constant can do): separates the simulator's own
  // error (drive spring, presliding) from the served model's.
  StochasticFrictionModel level = served;
  {
    StrokeReplay none;  // only the measured side of Compare is used
    none.t_s.assign(data.t_s.begin() + t0, data.t_s.begin() + split);
    none.fn_n.assign(none.t_s.size(), 1.0);
    none.ft_n.assign(none.t_s.size(), 0.0);
    level.mu_coulomb = Compare(data, t0, none).mean_steady_meas;
  }
  o = {};
  o.adapter.mode = FrictionMode::kCoulomb;
  const Errors oracle =
      Compare(data, split, ReplayStroke(data, split, end, level, o));
  std::printf("training steady level %.4f\n", level.mu_coulomb);
  Print("constant at training level", oracle);

  // The simulator realises a constant exactly while sliding: the error of
  // the exported constant is the model's (mu_coulomb averages the
  // presliding samples labelled slip), not the simulator's.
  EXPECT_NEAR(coulomb.mean_steady_sim, served.mu_coulomb, 0.005);
  EXPECT_LT(coulomb.sd_steady_sim, 0.005);
  // With the right level, the replay reproduces the held-out trace,
  // reversals (presliding through the drive spring) included.
  EXPECT_LT(std::fabs(oracle.bias_steady), 0.03);
  EXPECT_LT(oracle.rms_all, 0.1);
}

TEST(StrokeReplay, RefusesBadInput) {
  StrokeData d;
  d.t_s = {0, 0.01};
  d.fn_n = {1, 1};
  d.ft_n = {0.5, 0.5};
  d.v_mm_s = {0, 0};
  StochasticFrictionModel m;
  m.mu.terms = {Term::Intercept()};
  m.mu.beta = Eigen::VectorXd::Constant(1, 0.5);
  EXPECT_THROW(ReplayStroke(d, 0, 2, m), std::invalid_argument);
  d.covariate_names = {"position_mm"};
  d.covariates = {{0.0, 0.001}};
  EXPECT_THROW(ReplayStroke(d, 1, 1, m), std::invalid_argument);
  EXPECT_THROW(ReplayStroke(d, 0, 3, m), std::invalid_argument);
  StrokeReplayOptions o;
  o.timestep_s = 0;
  EXPECT_THROW(ReplayStroke(d, 0, 2, m, o), std::invalid_argument);
  const StrokeReplay r = ReplayStroke(d, 0, 2, m);
  ASSERT_EQ(r.ft_n.size(), 2u);
  EXPECT_NEAR(r.fn_n[1], 1.0, 0.05);
}

}  // namespace
}  // namespace frictiond::mujoco
