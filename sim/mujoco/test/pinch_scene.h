#pragma once
// The two-fingertip pinch scene of the MuJoCo drop-rate tests
// (docs/mujoco.md): two soft fingertips (x slides, motors press_a/press_b =
// grip force Fn each) pinch a 0.4 kg box on a vertical (bz) and a
// horizontal (by) slide; the box's x reaction comes from the joints. The y
// slide is needed: with no y freedom the contacts' first friction rows are
// empty and MuJoCo 2.2.2's elliptic noslip leaves the box creeping at
// 0.7 mm/s with two contacts. Elliptic cone, impratio 10 and 30 noslip
// iterations remove soft-contact creep, so friction decides slip.

#include <cmath>

namespace frictiond::mujoco {

inline constexpr const char* kPinchScene = R"(
<mujoco model="pinch">
  <option timestep="0.002" integrator="Euler" cone="elliptic" impratio="10"
          noslip_iterations="30" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="finger_a" pos="-0.03 0 0">
      <joint name="ax" type="slide" axis="1 0 0" damping="2"/>
      <geom name="tip_a" type="sphere" size="0.01" mass="0.05"
            solref="0.01 1" friction="1 0.005 0.0001"/>
    </body>
    <body name="finger_b" pos="0.03 0 0">
      <joint name="bx" type="slide" axis="-1 0 0" damping="2"/>
      <geom name="tip_b" type="sphere" size="0.01" mass="0.05"
            solref="0.01 1" friction="1 0.005 0.0001"/>
    </body>
    <body name="box" pos="0 0 0">
      <joint name="bz" type="slide" axis="0 0 1"/>
      <joint name="by" type="slide" axis="0 1 0"/>
      <geom name="box" type="box" size="0.02 0.02 0.02" mass="0.4"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="press_a" joint="ax" gear="1"/>
    <motor name="press_b" joint="bx" gear="1"/>
  </actuator>
</mujoco>)";

inline constexpr double kSettleS = 0.2;  ///< gravity off, grip established [s]
inline constexpr double kHoldS = 0.5;    ///< hold time under load [s]
inline constexpr double kDropM = 0.005;  ///< box lower than this: dropped [m]
/// Run on after the hold so that a slip that started in it can fall kDropM
/// (onset to 5 mm takes at most 0.09 s in the e2e scene) [s].
inline constexpr double kGraceS = 0.2;
/// The box moves faster than this: it slides (a constant-mu hold below its
/// limit stays below 0.1 mm/s, the no-creep test) [m/s].
inline constexpr double kSlideSpeed = 1e-4;

/// Smallest k with P(X <= k) >= p for X ~ Binomial(n, r).
inline int BinomialQuantile(int n, double r, double p) {
  double cdf = 0.0;
  for (int k = 0; k <= n; ++k) {
    cdf += std::exp(std::lgamma(n + 1.0) - std::lgamma(k + 1.0) -
                    std::lgamma(n - k + 1.0) + k * std::log(r) +
                    (n - k) * std::log1p(-r));
    if (cdf >= p) return k;
  }
  return n;
}

}  // namespace frictiond::mujoco
