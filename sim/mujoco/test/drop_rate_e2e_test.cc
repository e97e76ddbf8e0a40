// Validation by drop rates, end to end (issue 21 item 3, docs/mujoco.md):
// strokes simulated from a known stochastic truth per fingertip are
// uploaded through the service core (FrictionLibrary::IngestStrokes on a
// SQLite store); the served models (decoded from the JSON the service
// serves) give the pinch's grip force for a hold (PinchHoldRisk, the
// service's hold risk extended to two contacts); the truths, live in
// MuJoCo through FrictionAdapter, decide whether the box drops. Over
// seeded episodes the drop frequency must be within a factor of 1.5 of the
// requested risk, and with the truth's own grip force inside the 99 %
// binomial interval of it. A drop of the hold is a slip that started in
// the hold and fell 5 mm by the end of a grace after it (Outcome).
//
// The truths are wider than the estimator's assumptions: eps has a
// per-stroke offset and an AR(1) part (eps_time.h's latent process), and
// fingertip b's eps is skewed (a long lower tail), not normal.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <unistd.h>

#include "frictiond/estimators/grip_force.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/mujoco/friction_adapter.h"
#include "frictiond/mujoco/pinch_grip.h"
#include "frictiond/proto/model_json.h"
#include "frictiond/server/library.h"
#include "frictiond/testing/stroke_simulator.h"

#include "pinch_scene.h"

namespace frictiond::mujoco {
namespace {

// The scene of drop_rate_test.cc (pinch_scene.h): two soft fingertips (x
// slides, motors = grip force) pinch a 0.4 kg box on a vertical and a
// horizontal (y) slide; elliptic cone, impratio 10 and noslip iterations so
// friction, not soft-contact creep, decides slip.

constexpr double kSlipM = 20e-6;   // box lower than this: slipped
constexpr double kRateHz = 100.0;  // stroke sampling (eps_time.dt_s)

// A truth: eq. (1) with eps = F^-1(Phi(z)), z = sqrt(f) A + sqrt(1 - f) w
// (A per stroke / grasp, w an AR(1) per 10 ms sample).
StochasticFrictionModel Truth(double b0,
                              double b1,
                              double b2,
                              double sigma,
                              const std::vector<double>& quantiles,
                              double phi,
                              double offset_fraction) {
  StochasticFrictionModel t;
  for (RegressionModel* r : {&t.mu, &t.mu_fn_only}) {
    r->terms = {
        Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
    r->beta = Eigen::Vector3d(b0, b1, b2);
    r->sigma_eps = sigma;
    r->samples = 1000000;
    r->eps_quantiles = quantiles;
  }
  t.mu_fn_only.terms = {Term::Intercept(), Term::Linear("fn_n")};
  t.mu_fn_only.beta = Eigen::Vector2d(b0, b2);
  t.mu_coulomb = b0 + 2.5 * b2;  // mean mu at rest, Fn 2.5 N
  t.eps_time.valid = true;
  t.eps_time.dt_s = 1.0 / kRateHz;
  t.eps_time.phi = phi;
  t.eps_time.offset_fraction = offset_fraction;
  t.eps_time.min_instant_risk = 1e-6;
  return t;
}

// Fingertip a: mu = 0.8 - 0.003 v - 0.01 Fn + eps, eps ~ N(0, 0.1);
// half of eps's variance per stroke, phi 0.95 per 10 ms.
StochasticFrictionModel TruthA() {
  std::vector<double> q;
  RegressionModel n;
  n.sigma_eps = 0.1;
  for (double p : EpsQuantileLevels()) q.push_back(CalcEpsQuantile(n, p));
  return Truth(0.8, -0.02, -0.01, 0.1, q, 0.95, 0.5);
}

// Fingertip b, a different rubber: mu = 0.6 - 0.002 v - 0.005 Fn + eps,
// eps = 0.07 (1 - E), E ~ Exp(1) (skewed, long lower tail); 30 % of the
// latent variance per stroke, phi 0.9 per 10 ms.
StochasticFrictionModel TruthB() {
  std::vector<double> q;
  for (double p : EpsQuantileLevels()) q.push_back(0.07 * (1.0 + std::log(p)));
  return Truth(0.6, -0.01, -0.005, 0.07, q, 0.9, 0.3);
}

// eps = F^-1(Phi(z)) of a truth (the adapter's map).
double TruthEps(const StochasticFrictionModel& t, double z) {
  const double p =
      std::clamp(0.5 * std::erfc(-z / std::sqrt(2.0)), 1e-15, 1.0 - 1e-15);
  return CalcEpsQuantileExtended(t.mu, p, t.eps_time);
}

// Strokes of a truth (testing/stroke_simulator.h's rest + half-sine
// strokes, 0.5 to 4.5 N, 15 to 80 mm/s, at 100 Hz) with the truth's eps
// added to every sliding sample: a new offset A and a stationary w per
// stroke. Unlabelled, as a robot uploads them (the daemon labels slip).
StrokeData TruthStrokes(const StochasticFrictionModel& t,
                        int strokes,
                        std::uint64_t seed) {
  frictiond::testing::SimulationSpec spec;
  spec.b0 = t.mu.beta(0);
  spec.b1 = t.mu.beta(1);
  spec.b2 = t.mu.beta(2);
  spec.sigma_eps = 0.0;
  spec.strokes = strokes;
  spec.rate_hz = kRateHz;
  spec.v_min_mm_s = 11.0;
  spec.v_max_mm_s = 20.0;
  spec.write_labels = true;  // to find the strokes; dropped below
  StrokeData d = frictiond::testing::SimulateStrokes(spec, seed);
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double f = t.eps_time.offset_fraction, phi = t.eps_time.phi;
  double offset = 0.0, w = 0.0;
  int stroke = -1;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (d.stroke[i] != stroke) {
      stroke = d.stroke[i];
      offset = normal(rng);
      w = normal(rng);
    }
    if (!(d.v_mm_s[i] > 0)) continue;  // the stroke's rest
    w = phi * w + std::sqrt(1.0 - phi * phi) * normal(rng);
    const double eps =
        TruthEps(t, std::sqrt(f) * offset + std::sqrt(1.0 - f) * w);
    d.ft_n[i] = std::max(0.0, d.ft_n[i] + eps * d.fn_n[i]);
  }
  d.slip.clear();
  d.stroke.clear();
  return d;
}

// One episode's outcome. The hold fails when a slip starts in it
// (CalcGripForce's hold risk: eps below the slip level at some sample of
// the hold); the box then needs time to fall, so the episode runs kGraceS
// past the hold.
struct Outcome {
  /// eps_a + eps_b below the slip level at one of the hold's 1 + hold_s /
  /// dt_s looks (the event the hold risk counts; episodes with a level).
  bool crossed = false;
  bool slipped = false;          ///< lower than kSlipM within the hold
  bool dropped_in_hold = false;  ///< lower than kDropM within the hold
  /// Lower than kDropM by hold + grace, in a sliding run (box speed above
  /// kSlideSpeed throughout) that began within the hold: a drop of the hold.
  bool dropped = false;
  bool dropped_late = false;  ///< dropped in a run that began in the grace
  double fall_s = 0.0;        ///< start of the dropping run to kDropM [s]
};

struct Scene {
  Scene() {
    const std::string path = ::testing::TempDir() + "/pinch_e2e_" +
                             std::to_string(::getpid()) + ".xml";
    std::ofstream(path) << kPinchScene;
    char err[1000] = "";
    m = mj_loadXML(path.c_str(), nullptr, err, sizeof(err));
    std::remove(path.c_str());
    if (!m) ADD_FAILURE() << err;
    d = mj_makeData(m);
    box_body = mj_name2id(m, mjOBJ_BODY, "box");
    box_z = m->jnt_qposadr[mj_name2id(m, mjOBJ_JOINT, "bz")];
  }
  ~Scene() {
    mj_deleteData(d);
    mj_deleteModel(m);
  }
  double Load() const { return m->body_mass[box_body] * 9.81; }

  // One episode, both fingers at fn_n; adapter == nullptr: plain mj_step.
  // The hold of kHoldS is followed by kGraceS under the same load, so that
  // a slip that started in the hold can fall kDropM (Outcome).
  // slip_level: the level of eps_a + eps_b below which the pinch slips at
  // rest (L / Fn - mean mu_a - mean mu_b of the live models), for
  // Outcome::crossed; NaN: not checked.
  Outcome Episode(FrictionAdapter* adapter,
                  std::uint64_t seed,
                  double fn_n,
                  double slip_level = std::nan("")) {
    mj_resetData(m, d);
    if (adapter) adapter->Reset(seed);
    d->ctrl[0] = fn_n;
    d->ctrl[1] = fn_n;
    const double h = m->opt.timestep;
    const int settle = static_cast<int>(std::lround(kSettleS / h));
    const int hold = static_cast<int>(std::lround(kHoldS / h));
    const int grace = static_cast<int>(std::lround(kGraceS / h));
    Outcome out;
    int slide_start = -1;  // first hold step of the current sliding run
    for (int i = 0; i < settle + hold + grace; ++i) {
      m->opt.gravity[2] = i < settle ? 0.0 : -9.81;
      if (adapter)
        adapter->Step(m, d);
      else
        mj_step(m, d);
      if (i < settle) continue;
      const int k = i - settle;  // step k of the hold covers [k h, (k + 1) h]
      const double z = d->qpos[box_z];
      if (std::fabs(d->qvel[box_z]) > kSlideSpeed) {
        if (slide_start < 0) slide_start = k;
      } else {
        slide_start = -1;
      }
      if (k < hold && z < -kSlipM) out.slipped = true;
      if (adapter && k <= hold && !std::isnan(slip_level)) {
        double eps = 0.0;  // the eps of this step (the step at hold_s too)
        for (const auto& [pair, ep] : adapter->episodes()) eps += ep.eps;
        if (eps < slip_level) out.crossed = true;
      }
      if (z < -kDropM) {
        out.dropped_in_hold = k < hold;
        // The sliding run that dropped the box began in the hold: the
        // step that starts at hold_s is the hold's last look (1 + hold_s /
        // dt_s looks, as the hold risk counts them).
        out.dropped = slide_start >= 0 && slide_start <= hold;
        out.dropped_late = !out.dropped;
        out.fall_s = slide_start >= 0 ? (k + 1 - slide_start) * h : 0.0;
        break;
      }
    }
    return out;
  }

  mjModel* m = nullptr;
  mjData* d = nullptr;
  int box_body = -1;
  int box_z = -1;
};

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
      .count();
}

// The served model set of a pair, as a client decodes it.
StochasticFrictionModel Served(FrictionLibrary& lib,
                               const std::string& fingertip) {
  const auto cached = lib.FindModel("box_surface", fingertip);
  if (!cached) throw std::runtime_error("no model for " + fingertip);
  const ModelSet set =
      ModelSetFromJson(nlohmann::json::parse(cached->json_text));
  if (!set.stochastic) throw std::runtime_error("no stochastic model");
  return *set.stochastic;
}

void PrintModel(const char* name, const StochasticFrictionModel& s) {
  std::printf(
      "%s: b0 %.4f b1 %.5f b2 %.5f sigma %.4f q(0.01) %.4f q(0.05) %.4f "
      "eps_time valid %d dt %.4f phi %.3f f %.3f min_instant_risk %.2g "
      "mu_coulomb %.3f\n",
      name,
      s.mu.beta(s.mu.FindTerm("intercept")),
      s.mu.FindTerm("v_mm_s") >= 0 ? s.mu.beta(s.mu.FindTerm("v_mm_s")) : 0.0,
      s.mu.FindTerm("fn_n") >= 0 ? s.mu.beta(s.mu.FindTerm("fn_n")) : 0.0,
      s.mu.sigma_eps,
      CalcEpsQuantile(s.mu, 0.01),
      CalcEpsQuantile(s.mu, 0.05),
      s.eps_time.valid,
      s.eps_time.dt_s,
      s.eps_time.phi,
      s.eps_time.offset_fraction,
      s.eps_time.min_instant_risk,
      s.mu_coulomb);
}

TEST(DropRateEndToEnd, IdentifiedModelDropsNearTheRequestedRisk) {
  const StochasticFrictionModel truth_a = TruthA(), truth_b = TruthB();
  const int strokes = std::getenv("FRICTIOND_E2E_STROKES")
                          ? std::atoi(std::getenv("FRICTIOND_E2E_STROKES"))
                          : 1000;
  const std::uint64_t stroke_seed =
      std::getenv("FRICTIOND_E2E_SEED")
          ? std::strtoull(std::getenv("FRICTIOND_E2E_SEED"), nullptr, 10)
          : 1;
  // Upload 4 batches per fingertip through the service core.
  auto t0 = std::chrono::steady_clock::now();
  FrictionLibrary lib(OpenStore(":memory:"));
  for (int batch = 0; batch < 4; ++batch) {
    for (const char* tip : {"tip_a", "tip_b"}) {
      const StochasticFrictionModel& t = tip[4] == 'a' ? truth_a : truth_b;
      const StrokeData d =
          TruthStrokes(t, strokes / 4, 100 * stroke_seed + 10 * batch + tip[4]);
      IngestOptions io;
      io.fingertip = tip;
      const IngestResult r =
          lib.IngestStrokes("box_surface", FormatStrokeCsv(d), io);
      ASSERT_TRUE(r.model) << tip;
      std::printf("upload %d %s: %zu samples, fit %s %s\n",
                  batch,
                  tip,
                  r.samples,
                  r.fit_status.c_str(),
                  r.fit_note.c_str());
    }
  }
  const double identify_s = Seconds(t0);
  const StochasticFrictionModel served_a = Served(lib, "tip_a");
  const StochasticFrictionModel served_b = Served(lib, "tip_b");
  PrintModel("truth a ", truth_a);
  PrintModel("served a", served_a);
  PrintModel("truth b ", truth_b);
  PrintModel("served b", served_b);

  Scene s;
  const double load = s.Load();
  PinchHoldOptions ho;
  ho.hold_s = kHoldS;
  t0 = std::chrono::steady_clock::now();
  const PinchHoldRisk risk_truth(truth_a, truth_b, load, ho);
  const PinchHoldRisk risk_served(served_a, served_b, load, ho);
  const double risk_s = Seconds(t0);

  // The truths live: slip speed from the current state (a velocity-
  // weakening slip runs away without the previous step's lag).
  AdapterOptions lo;
  lo.current_slip_speed = true;
  FrictionAdapter live(lo);
  live.TagGeom(s.m, "tip_a", truth_a);
  live.TagGeom(s.m, "tip_b", truth_b);
  // Coulomb with the served mean mu (mu_coulomb, what frictiond exports as
  // a constant).
  AdapterOptions co = lo;
  co.mode = FrictionMode::kCoulomb;
  FrictionAdapter coulomb(co);
  coulomb.TagGeom(s.m, "tip_a", served_a);
  coulomb.TagGeom(s.m, "tip_b", served_b);

  // FRICTIOND_DROP_RATE_CSV=path: more risks, rows for
  // docs/mujoco_drop_rate.py.
  const char* csv_path = std::getenv("FRICTIOND_DROP_RATE_CSV");
  std::ofstream csv;
  if (csv_path) {
    csv.open(csv_path);
    csv << "risk,episodes_truth,fn_truth,drops_truth,drops_truth_in_hold,"
           "late_truth,episodes,fn_served,p_served,drops_served,"
           "drops_served_in_hold,late_served,slips_served,coulomb_episodes,"
           "drops_coulomb,drops_default,crossings_truth,crossings_served\n";
  }
  // FRICTIOND_E2E_EPISODE_SEED: first episode seed (the test uses 1000;
  // scene choices were made on others).
  const std::uint64_t episode_seed =
      std::getenv("FRICTIOND_E2E_EPISODE_SEED")
          ? std::strtoull(
                std::getenv("FRICTIOND_E2E_EPISODE_SEED"), nullptr, 10)
          : 1000;
  const std::vector<double> risks =
      csv_path ? std::vector<double>{0.01, 0.02, 0.05, 0.1, 0.2, 0.3}
               : std::vector<double>{0.01, 0.05, 0.2};
  // The truths' slip level of eps_a + eps_b at rest (pinch_grip.h).
  const auto slip_level = [&](double fn_n) {
    return load / fn_n - (truth_a.mu.beta(0) + truth_b.mu.beta(0)) -
           (truth_a.mu.beta(2) + truth_b.mu.beta(2)) * fn_n;
  };
  t0 = std::chrono::steady_clock::now();
  double fall_max_s = 0.0;
  for (double risk : risks) {
    // 3,000 episodes with the served model: at r = 0.01 a factor of 1.5 is
    // then 2.8 binomial standard deviations (1.6 with 1,000). The truth's
    // own grip force gets 1,000 (4,000 for the plot: at r <= 0.02 1,000
    // episodes see 10 to 20 drops, and the plot should show the physics,
    // not one seed range's luck).
    const int episodes = 3000;
    const int episodes_truth = csv_path ? 4000 : 1000;
    const PinchGripForce gt = risk_truth.GripForce(risk);
    const PinchGripForce gs = risk_served.GripForce(risk);
    ASSERT_TRUE(gt.attainable && gs.attainable);
    // The service's one-contact answer per finger (half the load each).
    GripForceOptions hold;
    hold.hold_s = kHoldS;
    const GripForce sa = CalcGripForce(served_a, 0.5 * load, risk, hold);
    const GripForce sb = CalcGripForce(served_b, 0.5 * load, risk, hold);
    int drops_truth = 0, hold_truth = 0, late_truth = 0, crossed_truth = 0;
    int drops_served = 0, hold_served = 0, late_served = 0, slips_served = 0,
        crossed_served = 0;
    for (int e = 0; e < std::max(episodes, episodes_truth); ++e) {
      if (e < episodes_truth) {
        const Outcome o =
            s.Episode(&live, episode_seed + e, gt.fn_n, slip_level(gt.fn_n));
        crossed_truth += o.crossed;
        drops_truth += o.dropped;
        hold_truth += o.dropped_in_hold;
        late_truth += o.dropped_late;
        if (o.dropped) fall_max_s = std::max(fall_max_s, o.fall_s);
      }
      if (e >= episodes) continue;
      const Outcome o =
          s.Episode(&live, episode_seed + e, gs.fn_n, slip_level(gs.fn_n));
      crossed_served += o.crossed;
      drops_served += o.dropped;
      hold_served += o.dropped_in_hold;
      late_served += o.dropped_late;
      slips_served += o.slipped;
      if (o.dropped) fall_max_s = std::max(fall_max_s, o.fall_s);
    }
    constexpr int kCompare = 50;
    int drops_coulomb = 0, drops_default = 0;
    for (int e = 0; e < kCompare; ++e) {
      drops_coulomb += s.Episode(&coulomb, e, gs.fn_n).dropped;
      drops_default += s.Episode(nullptr, e, gs.fn_n).dropped;
    }
    const double rate = static_cast<double>(drops_served) / episodes;
    const int lo_truth = BinomialQuantile(episodes_truth, risk, 0.005);
    const int hi_truth = BinomialQuantile(episodes_truth, risk, 0.995);
    std::printf(
        "risk %.2f: truth's model Fn %.3f N crossings %d, drops %d/%d (%.2f "
        "x r; 99%% interval [%d, %d]; in the hold %d, began in the grace "
        "%d); served model Fn %.3f N (its true P(slip) %.4f) crossings %d, "
        "drops %d/%d (%.4f, %.2f x r; in the hold %d, began in the grace "
        "%d), slips (20 um) %d; "
        "service one-contact per finger (L/2) a: %s %.3f N, b: %s %.3f N; "
        "Coulomb served mean mu %d/%d; MuJoCo default %d/%d\n",
        risk,
        gt.fn_n,
        crossed_truth,
        drops_truth,
        episodes_truth,
        drops_truth / (risk * episodes_truth),
        lo_truth,
        hi_truth,
        hold_truth,
        late_truth,
        gs.fn_n,
        risk_truth.SlipProbability(gs.fn_n),
        crossed_served,
        drops_served,
        episodes,
        rate,
        rate / risk,
        hold_served,
        late_served,
        slips_served,
        sa.attainable ? "ok" : sa.why.c_str(),
        sa.fn_n,
        sb.attainable ? "ok" : sb.why.c_str(),
        sb.fn_n,
        drops_coulomb,
        kCompare,
        drops_default,
        kCompare);
    if (csv_path)
      csv << risk << ',' << episodes_truth << ',' << gt.fn_n << ','
          << drops_truth << ',' << hold_truth << ',' << late_truth << ','
          << episodes << ',' << gs.fn_n << ','
          << risk_truth.SlipProbability(gs.fn_n) << ',' << drops_served << ','
          << hold_served << ',' << late_served << ',' << slips_served << ','
          << kCompare << ',' << drops_coulomb << ',' << drops_default << ','
          << crossed_truth << ',' << crossed_served << '\n';
    // End to end: within a factor of 1.5 of the requested risk.
    EXPECT_GE(rate, risk / 1.5) << "risk " << risk;
    EXPECT_LE(rate, risk * 1.5) << "risk " << risk;
    // The truth's own grip force: drops of the hold inside the 99 %
    // binomial interval of r.
    EXPECT_GE(drops_truth, lo_truth) << "risk " << risk;
    EXPECT_LE(drops_truth, hi_truth) << "risk " << risk;
    // The event the hold risk counts, eps below the slip level at a look.
    EXPECT_GE(crossed_truth, lo_truth) << "risk " << risk;
    EXPECT_LE(crossed_truth, hi_truth) << "risk " << risk;
    EXPECT_TRUE(drops_coulomb == 0 || drops_coulomb == kCompare);
    EXPECT_EQ(drops_default, 0);
  }
  // The grace is long enough for every drop of the hold to fall.
  EXPECT_LT(fall_max_s, 0.75 * kGraceS);
  std::printf(
      "identify %.1f s, hold risk %.1f s, episodes %.1f s; longest fall of "
      "a drop %.3f s\n",
      identify_s,
      risk_s,
      Seconds(t0),
      fall_max_s);
}

}  // namespace
}  // namespace frictiond::mujoco
