#include "frictiond/mujoco/friction_adapter.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "frictiond/estimators/grip_force.h"
#include "frictiond/proto/lugre_json.h"

namespace frictiond::mujoco {
namespace {

double Coefficient(const RegressionModel& m, const char* term) {
  const int k = m.FindTerm(term);
  return k >= 0 && k < m.beta.size() ? m.beta(k) : 0.0;
}

std::pair<int, int> PairKey(int g1, int g2) {
  return g1 < g2 ? std::make_pair(g1, g2) : std::make_pair(g2, g1);
}

// Velocity of geom g at world point p (m/s): linear + angular x (p - xpos).
void PointVelocity(const mjModel* m,
                   const mjData* d,
                   int g,
                   const mjtNum p[3],
                   mjtNum out[3]) {
  mjtNum v[6];  // [angular, linear] in the world frame at geom_xpos
  mj_objectVelocity(m, d, mjOBJ_GEOM, g, v, 0);
  const mjtNum* c = d->geom_xpos + 3 * g;
  const mjtNum r[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  out[0] = v[3] + v[1] * r[2] - v[2] * r[1];
  out[1] = v[4] + v[2] * r[0] - v[0] * r[2];
  out[2] = v[5] + v[0] * r[1] - v[1] * r[0];
}

// eps = F^-1(Phi(z)) (eps_time.h) exactly, for the table below.
double EpsAtLatent(const StochasticFrictionModel& model, double z) {
  const double p =
      std::clamp(0.5 * std::erfc(-z / std::sqrt(2.0)), 1e-15, 1.0 - 1e-15);
  return CalcEpsQuantileExtended(model.mu, p, model.eps_time);
}

constexpr double kLatentMax = 8.0;  // table over z in [-8, 8]
constexpr int kLatentPoints = 4097;

// z_t = sqrt(f) A + sqrt(1 - f) w_t, then eps = F^-1(Phi(z_t)) by linear
// interpolation in the table (grid 0.004 in z; F^-1(Phi(.)) is smooth).
double EpsFromLatent(const StochasticFrictionModel& model,
                     const std::vector<double>& table,
                     double offset_z,
                     double ar_z) {
  const double f = std::clamp(model.eps_time.offset_fraction, 0.0, 1.0);
  const double z = std::sqrt(f) * offset_z + std::sqrt(1.0 - f) * ar_z;
  if (table.size() != static_cast<std::size_t>(kLatentPoints))
    return EpsAtLatent(model, z);
  const double x = (std::clamp(z, -kLatentMax, kLatentMax) + kLatentMax) /
                   (2.0 * kLatentMax) * (kLatentPoints - 1);
  const int k = std::min(static_cast<int>(x), kLatentPoints - 2);
  const double w = x - k;
  return table[k] + w * (table[k + 1] - table[k]);
}

}  // namespace

FrictionAdapter::FrictionAdapter(AdapterOptions options)
    : options_(options), rng_(options.seed) {
  if (!(options_.mu_min >= 0) || !(options_.mu_max > options_.mu_min))
    throw std::invalid_argument("mu_min/mu_max: need 0 <= mu_min < mu_max");
  if (!(options_.episode_gap_s >= 0))
    throw std::invalid_argument("episode_gap_s: must be >= 0");
}

void FrictionAdapter::TagGeom(int geom, const StochasticFrictionModel& model) {
  if (geom < 0) throw std::invalid_argument("geom: negative id");
  if (model.mu.FindTerm("intercept") < 0)
    throw std::invalid_argument("model.mu: no intercept term");
  tagged_[geom] = model;
  std::vector<double>& table = latent_table_[geom];
  table.clear();
  if (model.eps_time.valid) {
    table.resize(kLatentPoints);
    for (int k = 0; k < kLatentPoints; ++k)
      table[k] = EpsAtLatent(
          model, -kLatentMax + 2.0 * kLatentMax * k / (kLatentPoints - 1));
  }
}

void FrictionAdapter::TagGeom(const mjModel* m,
                              const std::string& name,
                              const StochasticFrictionModel& model) {
  if (!m) throw std::invalid_argument("m: no MuJoCo model");
  const int id = mj_name2id(m, mjOBJ_GEOM, name.c_str());
  if (id < 0) throw std::invalid_argument("geom: no geom named '" + name + "'");
  TagGeom(id, model);
}

void FrictionAdapter::TagGeom(const mjModel* m,
                              const std::string& name,
                              const ModelSet& set) {
  if (!set.stochastic)
    throw std::invalid_argument("stochastic: model set of '" + set.material +
                                "' has no stochastic model");
  TagGeom(m, name, *set.stochastic);
}

void FrictionAdapter::TagGeomLuGre(int geom, const LuGreTheta& theta) {
  if (geom < 0) throw std::invalid_argument("geom: negative id");
  ValidateLuGreTheta(theta);
  lugre_[geom] = theta;
}

void FrictionAdapter::TagGeomLuGre(const mjModel* m,
                                   const std::string& name,
                                   const LuGreTheta& theta) {
  if (!m) throw std::invalid_argument("m: no MuJoCo model");
  const int id = mj_name2id(m, mjOBJ_GEOM, name.c_str());
  if (id < 0) throw std::invalid_argument("geom: no geom named '" + name + "'");
  TagGeomLuGre(id, theta);
}

void FrictionAdapter::TagGeomLuGre(const mjModel* m,
                                   const std::string& name,
                                   const ModelSet& set) {
  const auto it = set.other.find(kLuGreFamilyKey);
  if (it == set.other.end())
    throw std::invalid_argument("lugre: model set of '" + set.material +
                                "' has no LuGre family");
  TagGeomLuGre(m, name, LuGreFromJson(*it).theta);
}

void FrictionAdapter::Reset(std::uint64_t seed) {
  rng_.seed(seed);
  normal_.reset();
  episodes_.clear();
  if (joint_friction_) joint_friction_->Reset();
}

double FrictionAdapter::AdvanceLuGre(const LuGreTheta& theta,
                                     double h_s,
                                     ContactEpisode* ep) const {
  // Paper 001 eqs. (1)-(3) in friction-ratio form (lugre.h), v >= 0 the
  // slip speed of the previous step [mm/s], z [mm].
  const double v = std::max(ep->v_mm_s, 0.0);
  const double sigma0 = theta(LuGreIndex::kStiffness);
  const double g = CalcStribeckRatio(theta, v);  // > 0 for a valid theta
  double z_dot = 0.0;
  if (v > 0) {
    // Exact for constant v: dz/dt = v - sigma0 v z / g relaxes z to g/sigma0.
    const double z_ss = g / sigma0;
    ep->lugre_z = z_ss + (ep->lugre_z - z_ss) * std::exp(-sigma0 * v * h_s / g);
    z_dot = v - sigma0 * v * ep->lugre_z / g;
  }
  const double mu = sigma0 * ep->lugre_z + theta(LuGreIndex::kDamping) * z_dot +
                    theta(LuGreIndex::kViscous) * v;
  if (!std::isfinite(mu)) return options_.mu_min;
  return std::clamp(mu, options_.mu_min, options_.mu_max);
}

double FrictionAdapter::CalcMu(const StochasticFrictionModel& model,
                               double fn_n,
                               double v_mm_s,
                               double eps) const {
  double mu = 0.0;
  if (options_.mode == FrictionMode::kCoulomb) {
    mu = model.mu_coulomb;
  } else {
    if (options_.clamp_to_fitted_inputs) {
      auto clamp_input = [&model](const char* name, double x) {
        const auto it = model.inputs.find(name);
        if (it == model.inputs.end() || !(it->second.min <= it->second.max))
          return x;
        return std::clamp(x, it->second.min, it->second.max);
      };
      fn_n = clamp_input("fn_n", fn_n);
      v_mm_s = clamp_input("v_mm_s", v_mm_s);
    }
    // Paper 000 eq. (1): mu = b0 + b1 v + b2 Fn + eps.
    mu = Coefficient(model.mu, "intercept") +
         Coefficient(model.mu, "v_mm_s") * v_mm_s +
         Coefficient(model.mu, "fn_n") * fn_n;
    if (options_.mode == FrictionMode::kStochastic) mu += eps;
  }
  if (!std::isfinite(mu)) mu = options_.mu_min;
  return std::clamp(mu, options_.mu_min, options_.mu_max);
}

namespace {

// Tangential relative speed of contact c's geoms at its point [m/s].
double TangentialSpeed(const mjModel* m, const mjData* d, const mjContact& c) {
  mjtNum v1[3], v2[3];
  PointVelocity(m, d, c.geom1, c.pos, v1);
  PointVelocity(m, d, c.geom2, c.pos, v2);
  mjtNum rel[3] = {v2[0] - v1[0], v2[1] - v1[1], v2[2] - v1[2]};
  const mjtNum* n = c.frame;  // first row: contact normal
  const mjtNum vn = rel[0] * n[0] + rel[1] * n[1] + rel[2] * n[2];
  for (int k = 0; k < 3; ++k) rel[k] -= vn * n[k];
  return std::sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]);
}

}  // namespace

void FrictionAdapter::MeasurePairs(const mjModel* m, const mjData* d) {
  // Forces and velocities of the contacts of the step just taken (efc_force
  // belongs to d->contact until the next collision).
  for (auto& [key, ep] : episodes_) {
    ep.fn_n = 0.0;
    ep.v_mm_s = 0.0;
    ep.seen = false;
  }
  for (int i = 0; i < d->ncon; ++i) {
    const mjContact& c = d->contact[i];
    auto it = episodes_.find(PairKey(c.geom1, c.geom2));
    if (it == episodes_.end()) continue;
    mjtNum f[6];
    mj_contactForce(m, d, i, f);
    ContactEpisode& ep = it->second;
    ep.fn_n += std::max<mjtNum>(f[0], 0.0);
    if (!options_.current_slip_speed)
      ep.v_mm_s =
          std::max(ep.v_mm_s, 1000.0 * TangentialSpeed(m, d, c));  // mm/s
    ep.seen = true;
  }
}

void FrictionAdapter::MeasureSlipSpeeds(const mjModel* m, const mjData* d) {
  for (int i = 0; i < d->ncon; ++i) {
    const mjContact& c = d->contact[i];
    auto it = episodes_.find(PairKey(c.geom1, c.geom2));
    if (it == episodes_.end()) continue;
    it->second.v_mm_s =
        std::max(it->second.v_mm_s, 1000.0 * TangentialSpeed(m, d, c));
  }
}

void FrictionAdapter::SetContactFriction(const mjModel* m, mjData* d) {
  std::map<std::pair<int, int>, ContactEpisode> next;
  for (int i = 0; i < d->ncon; ++i) {
    mjContact& c = d->contact[i];
    auto l = lugre_.find(c.geom1);
    if (l == lugre_.end()) l = lugre_.find(c.geom2);
    if (l != lugre_.end()) {
      const auto key = PairKey(c.geom1, c.geom2);
      auto n = next.find(key);
      if (n == next.end()) {
        auto old = episodes_.find(key);
        ContactEpisode ep;  // a new episode: z = 0
        if (old != episodes_.end() &&
            d->time - old->second.last_s <= options_.episode_gap_s)
          ep = old->second;
        ep.last_s = d->time;
        ep.mu = AdvanceLuGre(l->second, m->opt.timestep, &ep);
        n = next.emplace(key, ep).first;
      }
      c.friction[0] = n->second.mu;
      c.friction[1] = n->second.mu;
      continue;
    }
    auto t = tagged_.find(c.geom1);
    if (t == tagged_.end()) t = tagged_.find(c.geom2);
    if (t == tagged_.end()) continue;
    const auto key = PairKey(c.geom1, c.geom2);
    auto n = next.find(key);
    if (n == next.end()) {
      auto old = episodes_.find(key);
      ContactEpisode ep;
      const StochasticFrictionModel& model = t->second;
      const EpsTimeModel& et = model.eps_time;
      const bool ar1 = options_.eps_time == EpsTime::kIdentified && et.valid &&
                       et.dt_s > 0 && et.offset_fraction < 1.0;
      if (old != episodes_.end() &&
          d->time - old->second.last_s <= options_.episode_gap_s) {
        ep = old->second;  // the episode goes on: keep its offset
        if (ar1 && d->time >= ep.next_ar_s) {
          // Advance w by the k elapsed dt_s steps of the AR(1) at once
          // (eps_time.h): w <- phi^k w + sqrt(1 - phi^2k) e, exact.
          const double k = std::floor((d->time - ep.next_ar_s) / et.dt_s) + 1.0;
          const double phi = std::clamp(et.phi, 0.0, 0.999);
          const double phi_k = k == 1.0 ? phi : std::pow(phi, k);
          ep.ar_z =
              phi_k * ep.ar_z + std::sqrt(1.0 - phi_k * phi_k) * normal_(rng_);
          ep.next_ar_s += k * et.dt_s;
          ep.eps = EpsFromLatent(
              model, latent_table_[t->first], ep.offset_z, ep.ar_z);
        }
      } else if (ar1) {
        // A new episode: offset A and a stationary w_0.
        ep.offset_z = normal_(rng_);
        ep.ar_z = normal_(rng_);
        ep.next_ar_s = d->time + et.dt_s;
        ep.eps =
            EpsFromLatent(model, latent_table_[t->first], ep.offset_z, ep.ar_z);
      } else {
        // A new episode, eps held for it: inverse transform of a uniform
        // draw through the stored quantiles (CalcEpsQuantile).
        std::uniform_real_distribution<double> u(0.0, 1.0);
        ep.eps = CalcEpsQuantile(model.mu, u(rng_));
      }
      ep.last_s = d->time;
      ep.mu = CalcMu(model, ep.fn_n, ep.v_mm_s, ep.eps);
      n = next.emplace(key, ep).first;
    }
    c.friction[0] = n->second.mu;
    c.friction[1] = n->second.mu;
  }
  // Pairs out of contact for less than the gap keep their episode.
  for (auto& [key, ep] : episodes_) {
    if (!next.count(key) && d->time - ep.last_s <= options_.episode_gap_s) {
      ep.fn_n = 0.0;
      ep.v_mm_s = 0.0;
      next.emplace(key, ep);
    }
  }
  episodes_.swap(next);
}

void FrictionAdapter::Step(const mjModel* m, mjData* d) {
  if (m->opt.integrator != mjINT_EULER)
    throw std::invalid_argument(
        "opt.integrator: the adapter supports the Euler integrator only");
  MeasurePairs(m, d);
  mj_checkPos(m, d);
  mj_checkVel(m, d);
  // mj_fwdPosition of MuJoCo 2.2.2, with friction set between collision
  // and constraint construction.
  mj_kinematics(m, d);
  mj_comPos(m, d);
  mj_camlight(m, d);
  mj_tendon(m, d);
  mj_crb(m, d);
  mj_factorM(m, d);
  mj_collision(m, d);
  if (options_.current_slip_speed && !episodes_.empty()) {
    // The velocities of the current state (cvel is otherwise the previous
    // step's until mj_fwdVelocity recomputes it, identically, below).
    mj_comVel(m, d);
    MeasureSlipSpeeds(m, d);
  }
  SetContactFriction(m, d);
  mj_makeConstraint(m, d);
  mj_transmission(m, d);
  mj_projectConstraint(m, d);
  // The rest of mj_forward (mj_forwardSkip(m, d, mjSTAGE_POS, 0) written
  // out, with the joint friction between actuation and acceleration), then
  // mj_step's Euler integration.
  mj_sensorPos(m, d);
  if (m->opt.enableflags & mjENBL_ENERGY) mj_energyPos(m, d);
  mj_fwdVelocity(m, d);
  mj_sensorVel(m, d);
  if (m->opt.enableflags & mjENBL_ENERGY) mj_energyVel(m, d);
  if (mjcb_control) mjcb_control(m, d);
  mj_fwdActuation(m, d);
  if (joint_friction_) joint_friction_->Apply(m, d);
  mj_fwdAcceleration(m, d);
  mj_fwdConstraint(m, d);
  mj_sensorAcc(m, d);
  mj_checkAcc(m, d);
  mj_Euler(m, d);
}

}  // namespace frictiond::mujoco
