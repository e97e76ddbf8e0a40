// FrictionAdapter basics: eq. (1) per mode, tagging from a model JSON,
// refusals naming the field.
#include "frictiond/mujoco/friction_adapter.h"

#include <stdexcept>

#include <gtest/gtest.h>

namespace frictiond::mujoco {
namespace {

ModelSet Felt() {
  return ModelSetFromJson(nlohmann::json::parse(R"({"material":"felt",
    "version":1,"stochastic":{"coefficients":{"intercept":0.9,"v_mm_s":-0.004,
    "fn_n":-0.06},"sigma_eps":0.05,"r2":0.6,"samples":1000,
    "mu_coulomb":0.8}})"));
}

TEST(FrictionAdapter, ModesFollowEquationOne) {
  const ModelSet felt = Felt();
  ASSERT_TRUE(felt.stochastic);
  const StochasticFrictionModel& m = *felt.stochastic;
  AdapterOptions o;
  FrictionAdapter stochastic(o);
  // eq. (1): 0.9 - 0.004 * 10 - 0.06 * 2 + 0.03
  EXPECT_NEAR(stochastic.CalcMu(m, 2.0, 10.0, 0.03), 0.77, 1e-12);
  o.mode = FrictionMode::kMean;
  EXPECT_NEAR(FrictionAdapter(o).CalcMu(m, 2.0, 10.0, 0.03), 0.74, 1e-12);
  o.mode = FrictionMode::kCoulomb;
  EXPECT_NEAR(
      FrictionAdapter(o).CalcMu(m, 2.0, 10.0, 0.03), m.mu_coulomb, 1e-12);
  // Clamped: a huge slip speed would make mu negative.
  EXPECT_EQ(stochastic.CalcMu(m, 2.0, 1e6, 0.0), 1e-3);
}

TEST(FrictionAdapter, ClampsToTheFittedInputsWhenAsked) {
  ModelSet felt = Felt();
  StochasticFrictionModel& m = *felt.stochastic;
  m.inputs["v_mm_s"] = {20.0, 5.0, 80.0};
  m.inputs["fn_n"] = {2.0, 0.5, 4.5};
  AdapterOptions o;
  o.mode = FrictionMode::kMean;
  // Extrapolated: 0.9 - 0.004 * 0 - 0.06 * 10.
  EXPECT_NEAR(FrictionAdapter(o).CalcMu(m, 10.0, 0.0, 0.0), 0.3, 1e-12);
  o.clamp_to_fitted_inputs = true;
  // Clamped to v = 5, Fn = 4.5: 0.9 - 0.02 - 0.27.
  EXPECT_NEAR(FrictionAdapter(o).CalcMu(m, 10.0, 0.0, 0.0), 0.61, 1e-12);
  // Inside the range nothing changes.
  EXPECT_NEAR(FrictionAdapter(o).CalcMu(m, 2.0, 10.0, 0.0), 0.74, 1e-12);
}

TEST(FrictionAdapter, RefusesBadInput) {
  AdapterOptions o;
  o.mu_max = 0.0;
  EXPECT_THROW(FrictionAdapter{o}, std::invalid_argument);
  o = {};
  o.episode_gap_s = -1;
  EXPECT_THROW(FrictionAdapter{o}, std::invalid_argument);
  FrictionAdapter a{AdapterOptions{}};
  EXPECT_THROW(a.TagGeom(-1, *Felt().stochastic), std::invalid_argument);
  StochasticFrictionModel no_intercept;
  EXPECT_THROW(a.TagGeom(0, no_intercept), std::invalid_argument);
  EXPECT_THROW(a.TagGeom(nullptr, "tip", *Felt().stochastic),
               std::invalid_argument);
  ModelSet empty;
  empty.material = "x";
  EXPECT_THROW(a.TagGeom(nullptr, "tip", empty), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond::mujoco
