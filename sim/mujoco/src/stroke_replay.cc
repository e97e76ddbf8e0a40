#include "frictiond/mujoco/stroke_replay.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "frictiond/mujoco/actuator_replay.h"

namespace frictiond::mujoco {
namespace {

constexpr double kTipMassKg = 0.05;
constexpr double kTipRadiusM = 0.008;
constexpr double kSettleS = 0.2;  // normal force established before replay

std::string Num(double x) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", x);
  return buf;
}

struct DataDeleter {
  void operator()(mjData* d) const { mj_deleteData(d); }
};

}  // namespace

std::string MakeStrokeMjcf(const StrokeReplayOptions& o) {
  const double k = o.drive_stiffness_n_m;
  const double c = 2.0 * std::sqrt(k * kTipMassKg);  // critical damping
  return R"(<mujoco model="stroke_replay">
  <option timestep=")" +
         Num(o.timestep_s) +
         R"(" integrator="Euler" cone="elliptic" impratio="10"
          noslip_iterations="30" gravity="0 0 0"/>
  <worldbody>
    <geom name="surface" type="plane" size="0.1 0.1 0.01"/>
    <body name="finger" pos="0 0 )" +
         Num(kTipRadiusM) + R"(">
      <joint name="x" type="slide" axis="1 0 0" damping=")" +
         Num(c) + R"("/>
      <joint name="y" type="slide" axis="0 1 0" damping=")" +
         Num(c) + R"("/>
      <joint name="z" type="slide" axis="0 0 -1" damping="5"/>
      <geom name="tip" type="sphere" size=")" +
         Num(kTipRadiusM) + R"(" mass=")" + Num(kTipMassKg) +
         R"(" solref="0.01 1"/>
    </body>
  </worldbody>
  <actuator>
    <position name="drive" joint="x" kp=")" +
         Num(k) + R"("/>
    <motor name="press" joint="z" gear="1"/>
  </actuator>
</mujoco>)";
}

StrokeReplay ReplayStroke(const StrokeData& data,
                          std::size_t begin,
                          std::size_t end,
                          const StochasticFrictionModel& model,
                          const StrokeReplayOptions& options) {
  const auto pos = data.FindCovariate("position_mm");
  if (!pos)
    throw std::invalid_argument(
        "position_mm: the stroke has no stage position column");
  if (!(begin < end) || end > data.size())
    throw std::invalid_argument("range: [" + std::to_string(begin) + ", " +
                                std::to_string(end) +
                                ") (must be non-empty "
                                "and within the " +
                                std::to_string(data.size()) + " samples)");
  if (!(options.timestep_s > 0) || !(options.timestep_s <= 0.01))
    throw std::invalid_argument("timestep_s: must be in (0, 0.01]");
  if (!(options.drive_stiffness_n_m > 0) ||
      !std::isfinite(options.drive_stiffness_n_m))
    throw std::invalid_argument("drive_stiffness_n_m: must be finite and > 0");
  const std::vector<double>& x_mm = data.covariates[*pos];

  MjModelPtr m = LoadMjcfText(MakeStrokeMjcf(options));
  std::unique_ptr<mjData, DataDeleter> d(mj_makeData(m.get()));
  FrictionAdapter adapter(options.adapter);
  adapter.TagGeom(m.get(), "tip", model);
  const int tip = mj_name2id(m.get(), mjOBJ_GEOM, "tip");

  const double t0 = data.t_s[begin];
  const double x0 = x_mm[begin];
  // Recorded stage position [m, relative] and Fn at time t (linear).
  std::size_t at = begin;
  auto interpolate = [&](double t, double* x_m, double* fn) {
    while (at + 1 < end && data.t_s[at + 1] <= t) ++at;
    const std::size_t nx = std::min(at + 1, end - 1);
    const double span = data.t_s[nx] - data.t_s[at];
    const double w =
        span > 0 ? std::clamp((t - data.t_s[at]) / span, 0.0, 1.0) : 0.0;
    *x_m = 1e-3 * (x_mm[at] + w * (x_mm[nx] - x_mm[at]) - x0);
    *fn = data.fn_n[at] + w * (data.fn_n[nx] - data.fn_n[at]);
  };

  // Settle: pressed with the first Fn, the drive at the start position.
  d->ctrl[0] = 0.0;
  d->ctrl[1] = data.fn_n[begin];
  const int settle = static_cast<int>(kSettleS / options.timestep_s);
  for (int i = 0; i < settle; ++i) adapter.Step(m.get(), d.get());

  StrokeReplay out;
  out.t_s.reserve(end - begin);
  out.fn_n.reserve(end - begin);
  out.ft_n.reserve(end - begin);
  double sim_t = 0.0;  // replay time (t - t0)
  for (std::size_t k = begin; k < end; ++k) {
    while (sim_t < data.t_s[k] - t0 - 0.5 * options.timestep_s) {
      double x_m = 0, fn = 0;
      interpolate(t0 + sim_t, &x_m, &fn);
      d->ctrl[0] = x_m;
      d->ctrl[1] = fn;
      adapter.Step(m.get(), d.get());
      sim_t += options.timestep_s;
    }
    double fn = 0, ft = 0;
    for (int i = 0; i < d->ncon; ++i) {
      const mjContact& c = d->contact[i];
      if (c.geom1 != tip && c.geom2 != tip) continue;
      mjtNum f[6];
      mj_contactForce(m.get(), d.get(), i, f);
      fn += f[0];
      ft += std::hypot(f[1], f[2]);
    }
    out.t_s.push_back(data.t_s[k]);
    out.fn_n.push_back(fn);
    out.ft_n.push_back(ft);
  }
  return out;
}

}  // namespace frictiond::mujoco
