// eps with its identified time correlation inside a contact episode
// (issue 21, eps_time.h, docs/mujoco.md): the adapter's eps process in a
// held MuJoCo contact has the model's marginal, the AR(1) + offset
// autocorrelation and the hold-crossing probability CalcGripForce uses;
// and a held box drops at the hold risk.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/eps_time.h"
#include "frictiond/estimators/grip_force.h"
#include "frictiond/mujoco/actuator_replay.h"
#include "frictiond/mujoco/friction_adapter.h"

#include "pinch_scene.h"  // BinomialQuantile

namespace frictiond::mujoco {
namespace {

// One fingertip presses a box on a vertical slide (its x reaction from the
// joint) and a y slide (without it MuJoCo 2.2.2's noslip lets the contact
// creep, docs/mujoco.md): one friction contact carries the load.
constexpr const char* kScene = R"(
<mujoco model="hold">
  <option timestep="0.002" integrator="Euler" cone="elliptic" impratio="10"
          noslip_iterations="30" gravity="0 0 0"/>
  <worldbody>
    <body name="finger" pos="-0.03 0 0">
      <joint name="fx" type="slide" axis="1 0 0" damping="2"/>
      <geom name="tip" type="sphere" size="0.01" mass="0.05"
            solref="0.01 1"/>
    </body>
    <body name="box" pos="0 0 0">
      <joint name="bz" type="slide" axis="0 0 1"/>
      <joint name="by" type="slide" axis="0 1 0"/>
      <geom name="box" type="box" size="0.02 0.02 0.02" mass="0.2"/>
    </body>
  </worldbody>
  <actuator><motor name="press" joint="fx" gear="1"/></actuator>
</mujoco>)";

constexpr double kDtS = 0.01;  // eps_time sampling interval (5 steps)
constexpr double kPhi = 0.9;
constexpr double kOffset = 0.5;
constexpr double kSlipM = 2e-5;  // box moved 20 um after settling: slipped
// kSettleS, kHoldS, kGraceS and kSlideSpeed are the pinch scene's
// (pinch_scene.h): the hold is followed by a grace under the same load; a
// slip (or drop) of the hold is one whose sliding run (box speed above 0.1
// mm/s) began within the hold (drop_rate_e2e_test's rule, docs/mujoco.md).

// mu = 0.8 - 0.002 v - 0.01 Fn + eps, eps ~ N(0, 0.1) stored as quantiles,
// with an AR(1) + offset time structure.
StochasticFrictionModel Truth() {
  StochasticFrictionModel t;
  t.mu.terms = {
      Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
  t.mu.beta = Eigen::Vector3d(0.8, -0.002, -0.01);
  t.mu.sigma_eps = 0.1;
  t.mu.samples = 100000;
  for (double p : EpsQuantileLevels())
    t.mu.eps_quantiles.push_back(CalcEpsQuantile(t.mu, p));
  t.mu_fn_only = t.mu;
  t.mu_coulomb = 0.77;
  t.eps_time.valid = true;
  t.eps_time.dt_s = kDtS;
  t.eps_time.phi = kPhi;
  t.eps_time.offset_fraction = kOffset;
  t.eps_time.min_instant_risk = 1e-4;
  return t;
}

double NormalQuantile(double p) {
  // Inverse of Phi by bisection (tests only).
  double lo = -10, hi = 10;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

struct Hold {
  Hold() : m(LoadMjcfText(kScene)), d(mj_makeData(m.get())) {
    box_z = m->jnt_qposadr[mj_name2id(m.get(), mjOBJ_JOINT, "bz")];
  }
  ~Hold() { mj_deleteData(d); }
  double Load() const {
    return m->body_mass[mj_name2id(m.get(), mjOBJ_BODY, "box")] * 9.81;
  }
  MjModelPtr m;
  mjData* d;
  int box_z = -1;
};

// The latent z_t of each episode, one value per dt_s, over the hold.
std::vector<std::vector<double>> LatentPaths(EpsTime mode, int episodes) {
  Hold h;
  const StochasticFrictionModel truth = Truth();
  AdapterOptions o;
  o.eps_time = mode;
  FrictionAdapter a(o);
  a.TagGeom(h.m.get(), "tip", truth);
  const int per_sample = static_cast<int>(std::lround(kDtS / 0.002));
  const int steps = static_cast<int>((kSettleS + kHoldS) / 0.002);
  std::vector<std::vector<double>> paths;
  for (int e = 0; e < episodes; ++e) {
    mj_resetData(h.m.get(), h.d);
    a.Reset(100 + e);
    h.d->ctrl[0] = 3.0;
    std::vector<double> z;
    for (int i = 0; i < steps; ++i) {
      a.Step(h.m.get(), h.d);
      if (i * 0.002 >= kSettleS && i % per_sample == 0) {
        EXPECT_EQ(a.episodes().size(), 1u);
        const double eps = a.episodes().begin()->second.eps;
        z.push_back(NormalQuantile(
            std::clamp(CalcEpsCdfExtended(truth.mu, eps, truth.eps_time),
                       1e-12,
                       1 - 1e-12)));
      }
    }
    paths.push_back(z);
  }
  return paths;
}

double LagCorrelation(const std::vector<std::vector<double>>& paths, int lag) {
  double sxy = 0, sxx = 0, syy = 0;
  for (const auto& z : paths) {
    for (std::size_t t = 0; t + lag < z.size(); ++t) {
      sxy += z[t] * z[t + lag];
      sxx += z[t] * z[t];
      syy += z[t + lag] * z[t + lag];
    }
  }
  return sxy / std::sqrt(sxx * syy);
}

TEST(EpsTime, AdapterRealisesTheIdentifiedTimeStructure) {
  const auto paths = LatentPaths(EpsTime::kIdentified, 1000);
  // Marginal: z ~ N(0, 1) (F^-1(Phi(z)) maps back to the stored eps).
  int below[3] = {0, 0, 0}, total = 0;
  const double levels[3] = {0.05, 0.2, 0.5};
  for (const auto& z : paths) {
    for (double v : z) {
      ++total;
      for (int k = 0; k < 3; ++k) below[k] += v < NormalQuantile(levels[k]);
    }
  }
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(static_cast<double>(below[k]) / total, levels[k], 0.03)
        << "level " << levels[k];
  // Autocorrelation at lag k samples: f + (1 - f) phi^k.
  for (int lag : {1, 5, 20}) {
    const double want = kOffset + (1 - kOffset) * std::pow(kPhi, lag);
    const double got = LagCorrelation(paths, lag);
    std::printf("lag %2d: correlation %.3f (model %.3f)\n", lag, got, want);
    EXPECT_NEAR(got, want, 0.04) << "lag " << lag;
  }
  // P(z_t < c at some sample of the hold) = the hold-crossing probability
  // CalcGripForce's hold risk is made of.
  const double c = NormalQuantile(0.02);
  const int n = static_cast<int>(paths.front().size());
  int crossed = 0;
  for (const auto& z : paths)
    crossed += *std::min_element(z.begin(), z.end()) < c;
  const double want = CalcHoldCrossingProbability(c, n, kPhi, kOffset);
  const int lo = BinomialQuantile(1000, want, 0.005);
  const int hi = BinomialQuantile(1000, want, 0.995);
  std::printf(
      "hold of %d samples: %d/1000 crossed (model %.4f, 99%% "
      "interval [%d, %d])\n",
      n,
      crossed,
      want,
      lo,
      hi);
  EXPECT_GE(crossed, lo);
  EXPECT_LE(crossed, hi);
  // Per-episode mode: one draw, constant within the episode.
  for (const auto& z : LatentPaths(EpsTime::kPerEpisode, 20))
    for (double v : z) EXPECT_NEAR(v, z.front(), 1e-6);
}

TEST(EpsTime, HeldBoxDropsAtTheHoldRisk) {
  Hold h;
  const StochasticFrictionModel truth = Truth();
  AdapterOptions ao;
  ao.current_slip_speed = true;
  FrictionAdapter a(ao);
  a.TagGeom(h.m.get(), "tip", truth);
  for (double risk : {0.05, 0.2}) {
    GripForceOptions o;
    o.hold_s = kHoldS;
    const GripForce g = CalcGripForce(truth, h.Load(), risk, o);
    ASSERT_TRUE(g.attainable) << g.why;
    const double fn_instant = CalcGripForce(truth, h.Load(), risk).fn_n;
    int drops = 0, slips = 0, drops_in_hold = 0, slips_in_hold = 0;
    const int episodes = 1000;
    for (int e = 0; e < episodes; ++e) {
      mj_resetData(h.m.get(), h.d);
      a.Reset(7000 + e);
      h.d->ctrl[0] = g.fn_n;
      const int settle = static_cast<int>(std::lround(kSettleS / 0.002));
      const int hold = static_cast<int>(std::lround(kHoldS / 0.002));
      const int grace = static_cast<int>(std::lround(kGraceS / 0.002));
      double z_hold = 0;
      bool slipped = false, slipped_in_hold = false;
      int slide_start = -1;  // first hold step of the current sliding run
      for (int i = 0; i < settle + hold + grace; ++i) {
        h.m->opt.gravity[2] = i < settle ? 0.0 : -9.81;
        a.Step(h.m.get(), h.d);
        if (i == settle - 1) z_hold = h.d->qpos[h.box_z];
        if (i < settle) continue;
        const int k = i - settle;
        if (std::fabs(h.d->qvel[h.box_z]) <= kSlideSpeed)
          slide_start = -1;
        else if (slide_start < 0)
          slide_start = k;
        const bool of_hold = slide_start >= 0 && slide_start <= hold;
        if (h.d->qpos[h.box_z] < z_hold - kSlipM) {
          slipped = slipped || of_hold;
          slipped_in_hold = slipped_in_hold || k < hold;
        }
        if (h.d->qpos[h.box_z] < -0.005) {
          drops += of_hold;
          drops_in_hold += k < hold;
          break;
        }
      }
      slips += slipped;
      slips_in_hold += slipped_in_hold;
    }
    const int lo = BinomialQuantile(episodes, risk, 0.005);
    const int hi = BinomialQuantile(episodes, risk, 0.995);
    std::printf(
        "risk %.2f: hold Fn %.3f N (one instant: %.3f N); drops %d/%d "
        "(within the hold %d), slips > 20 um %d (within the hold %d) (99%% "
        "interval [%d, %d])\n",
        risk,
        g.fn_n,
        fn_instant,
        drops,
        episodes,
        drops_in_hold,
        slips,
        slips_in_hold,
        lo,
        hi);
    // A slip (the box moved 20 um) happens at the hold risk: CalcGripForce
    // counts any sample below the threshold as a slip.
    EXPECT_GE(slips, lo) << "risk " << risk;
    EXPECT_LE(slips, hi) << "risk " << risk;
    // Not every slip drops the box: a dip of one or two 10 ms samples
    // moves it microns and friction recovers, so the hold risk is
    // conservative for drops.
    EXPECT_LE(drops, slips);
    EXPECT_GT(g.fn_n, fn_instant) << "a hold needs more force than an instant";
  }
}

}  // namespace
}  // namespace frictiond::mujoco
