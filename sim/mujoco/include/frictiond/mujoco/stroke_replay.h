#pragma once
/// @file
/// A measured stroke replayed in MuJoCo (issue 21 item 4, docs/mujoco.md):
/// a fingertip is pressed onto a flat surface with the recorded normal
/// force and dragged along it like the recorded stage, and the simulated
/// tangential force is compared with the measured one.
///
/// Scene (MakeStrokeMjcf): a sphere fingertip (radius 8 mm, 50 g) on two
/// slide joints, z pressed down by a motor with ctrl = Fn(t) and x pulled
/// by a `position` actuator (the stage's drive, stiffness
/// drive_stiffness_n_m, critically damped through the joint) to the
/// recorded stage position (covariate `position_mm`, relative to its first
/// value), both linearly interpolated in time; gravity off; elliptic cone,
/// impratio 10, noslip 30; contact friction from FrictionAdapter (the mode
/// of the options) on the tagged fingertip. The drive spring lets the
/// fingertip stick and preslide at reversals as the rig's flexure does.
///
/// Output per recorded sample: the simulated contact normal force and
/// tangential force magnitude (mj_contactForce), at the sample's time.

#include <cstdint>
#include <string>
#include <vector>

#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/estimators/stroke_data.h"
#include "frictiond/mujoco/friction_adapter.h"

namespace frictiond::mujoco {

/// Options of ReplayStroke.
struct StrokeReplayOptions {
  AdapterOptions adapter;              ///< friction mode, seed, clamps
  double timestep_s = 0.001;           ///< MuJoCo step [s], > 0
  double drive_stiffness_n_m = 4.2e4;  ///< stage-to-fingertip spring [N/m]
};

/// One replay.
struct StrokeReplay {
  std::vector<double> t_s;   ///< the recorded sample times replayed
  std::vector<double> fn_n;  ///< simulated normal force [N]
  std::vector<double> ft_n;  ///< simulated tangential force magnitude [N]
};

/// The scene (file comment); joints "x", "z", geom "tip".
std::string MakeStrokeMjcf(const StrokeReplayOptions& options);

/// Replays samples [begin, end) of `data` (which needs the covariate
/// `position_mm`) with the friction `model`.
/// @throws std::invalid_argument for a missing position_mm, an empty or
/// out-of-range sample range or invalid options (naming the field).
StrokeReplay ReplayStroke(const StrokeData& data,
                          std::size_t begin,
                          std::size_t end,
                          const StochasticFrictionModel& model,
                          const StrokeReplayOptions& options = {});

}  // namespace frictiond::mujoco
