#include "frictiond/proto/model_json.h"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

StochasticFrictionModel WithTimeModel() {
  StochasticFrictionModel m;
  RegressionModel& r = m.mu;
  r.terms = {Term::Intercept()};
  r.beta = Eigen::VectorXd::Constant(1, 0.5);
  r.std_err = Eigen::VectorXd::Constant(1, 0.01);
  r.P_beta = Eigen::MatrixXd::Constant(1, 1, 1e-4);
  r.sigma_eps = 0.05;
  r.samples = 1200;
  for (double p : EpsQuantileLevels()) r.eps_quantiles.push_back(p - 0.5);
  m.mu_fn_only = r;
  EpsTimeModel& t = m.eps_time;
  t.valid = true;
  t.dt_s = 0.01;
  t.phi = 0.9;
  t.corr_time_s = -0.01 / std::log(0.9);
  t.offset_fraction = 0.4;
  t.episodes = 12;
  t.samples = 1200;
  t.effective_samples = 250.5;
  t.min_instant_risk = 1 / 250.5;
  t.tail_xi = 0.2;
  t.tail_scale = 0.03;
  return m;
}

TEST(ModelJson, EpsTimeRoundTrips) {
  const StochasticFrictionModel m = WithTimeModel();
  const StochasticFrictionModel back =
      StochasticModelFromJson(StochasticModelToJson(m));
  const EpsTimeModel& a = m.eps_time;
  const EpsTimeModel& b = back.eps_time;
  EXPECT_TRUE(b.valid);
  EXPECT_EQ(b.dt_s, a.dt_s);
  EXPECT_EQ(b.phi, a.phi);
  EXPECT_EQ(b.corr_time_s, a.corr_time_s);
  EXPECT_EQ(b.offset_fraction, a.offset_fraction);
  EXPECT_EQ(b.episodes, a.episodes);
  EXPECT_EQ(b.samples, a.samples);
  EXPECT_EQ(b.effective_samples, a.effective_samples);
  EXPECT_EQ(b.min_instant_risk, a.min_instant_risk);
  EXPECT_EQ(b.tail_xi, a.tail_xi);
  EXPECT_EQ(b.tail_scale, a.tail_scale);
}

TEST(ModelJson, HostileEpsTimeLeavesItInvalid) {
  // Out-of-range values from a stored or uploaded model must not reach the
  // quadrature: the time model becomes invalid (hold_s > 0 is refused).
  for (const char* key :
       {"phi", "dt_s", "offset_fraction", "min_instant_risk"}) {
    nlohmann::json j = StochasticModelToJson(WithTimeModel());
    j["eps_time"][key] = -1.0;
    const StochasticFrictionModel m = StochasticModelFromJson(j);
    EXPECT_FALSE(m.eps_time.valid) << key;
    EXPECT_FALSE(m.eps_time.why.empty()) << key;
  }
  nlohmann::json j = StochasticModelToJson(WithTimeModel());
  j["eps_time"]["valid"] = "yes";  // not a boolean: not valid, no throw
  EXPECT_FALSE(StochasticModelFromJson(j).eps_time.valid);
  j = StochasticModelToJson(WithTimeModel());
  j["eps_time"]["tail_xi"] = 5.0;  // out of range: exponential tail instead
  const StochasticFrictionModel m = StochasticModelFromJson(j);
  EXPECT_TRUE(m.eps_time.valid);
  EXPECT_EQ(m.eps_time.tail_scale, 0.0);
  // A model stored before eps_time existed: no time model.
  j.erase("eps_time");
  EXPECT_FALSE(StochasticModelFromJson(j).eps_time.valid);
}

StochasticFrictionModel WithOffsetDecomposition() {
  StochasticFrictionModel m = WithTimeModel();
  EpsOffsetModel& o = m.eps_time.offset;
  o.valid = true;
  for (double p : EpsQuantileLevels()) {
    o.offset_quantiles.push_back(0.04 * (p - 0.5));
    o.within_quantiles.push_back(0.02 * (p - 0.5));
  }
  o.offset_tail_xi = 0.3;
  o.offset_tail_scale = 0.02;
  o.within_tail_xi = -0.1;
  o.within_tail_scale = 0.004;
  for (double p : EpsQuantileLevels())
    o.innovation_quantiles.push_back(0.005 * (p - 0.5));
  o.innovation_tail_xi = 0.25;
  o.innovation_tail_scale = 0.001;
  o.episodes_used = 11;
  return m;
}

TEST(ModelJson, OffsetDecompositionRoundTripsAndIsOptional) {
  // Absent (as in every model stored before it): not valid, the time model
  // itself still valid (holds use the Gaussian copula).
  EXPECT_FALSE(StochasticModelToJson(WithTimeModel())["eps_time"].contains(
      "offset_decomposition"));
  const StochasticFrictionModel old =
      StochasticModelFromJson(StochasticModelToJson(WithTimeModel()));
  EXPECT_TRUE(old.eps_time.valid);
  EXPECT_FALSE(old.eps_time.offset.valid);
  const StochasticFrictionModel m = WithOffsetDecomposition();
  const StochasticFrictionModel back =
      StochasticModelFromJson(StochasticModelToJson(m));
  const EpsOffsetModel& a = m.eps_time.offset;
  const EpsOffsetModel& b = back.eps_time.offset;
  EXPECT_TRUE(back.eps_time.valid);
  EXPECT_TRUE(b.valid);
  EXPECT_EQ(b.offset_quantiles, a.offset_quantiles);
  EXPECT_EQ(b.within_quantiles, a.within_quantiles);
  EXPECT_EQ(b.offset_tail_xi, a.offset_tail_xi);
  EXPECT_EQ(b.offset_tail_scale, a.offset_tail_scale);
  EXPECT_EQ(b.within_tail_xi, a.within_tail_xi);
  EXPECT_EQ(b.within_tail_scale, a.within_tail_scale);
  EXPECT_EQ(b.innovation_quantiles, a.innovation_quantiles);
  EXPECT_EQ(b.innovation_tail_xi, a.innovation_tail_xi);
  EXPECT_EQ(b.innovation_tail_scale, a.innovation_tail_scale);
  EXPECT_EQ(b.episodes_used, a.episodes_used);
  // Without innovations (optional inside the decomposition): u_t is the
  // Gaussian copula AR(1).
  nlohmann::json j = StochasticModelToJson(m);
  j["eps_time"]["offset_decomposition"].erase("innovation_quantiles");
  const StochasticFrictionModel copula = StochasticModelFromJson(j);
  EXPECT_TRUE(copula.eps_time.offset.valid);
  EXPECT_TRUE(copula.eps_time.offset.innovation_quantiles.empty());
}

TEST(ModelJson, HostileOffsetDecompositionLeavesTimeModelInvalid) {
  const nlohmann::json good = StochasticModelToJson(WithOffsetDecomposition());
  std::vector<nlohmann::json> bad(7, good);
  auto& o0 = bad[0]["eps_time"]["offset_decomposition"];
  o0["offset_quantiles"].erase(0);  // one level short
  auto& o1 = bad[1]["eps_time"]["offset_decomposition"];
  o1["within_quantiles"][5] = 1.0;  // decreasing afterwards
  auto& o2 = bad[2]["eps_time"]["offset_decomposition"];
  o2["offset_quantiles"][3] = "x";  // not a number
  auto& o3 = bad[3]["eps_time"]["offset_decomposition"];
  o3["within_tail_xi"] = 3.0;  // out of range
  auto& o4 = bad[4]["eps_time"]["offset_decomposition"];
  o4["offset_tail_scale"] = -1.0;
  bad[5]["eps_time"]["offset_decomposition"] = "not an object";
  auto& o6 = bad[6]["eps_time"]["offset_decomposition"];
  o6["innovation_quantiles"][0] = 1e300;  // decreasing afterwards
  for (std::size_t k = 0; k < bad.size(); ++k) {
    const StochasticFrictionModel m = StochasticModelFromJson(bad[k]);
    EXPECT_FALSE(m.eps_time.valid) << k;
    EXPECT_FALSE(m.eps_time.offset.valid) << k;
    EXPECT_NE(m.eps_time.why.find("offset_decomposition"), std::string::npos)
        << k << ": " << m.eps_time.why;
  }
}

TEST(ModelJson, EpsScaleRoundTripsAndIsAbsentByDefault) {
  StochasticFrictionModel m = WithTimeModel();
  EXPECT_FALSE(StochasticModelToJson(m).contains("eps_scale"));
  EXPECT_FALSE(StochasticModelFromJson(StochasticModelToJson(m)).eps_scale);
  EpsScaleModel s;
  s.input = "fn_n";
  s.log_sigma_intercept = -4.1;
  s.log_sigma_slope = 0.35;
  s.x_min = 0.6;
  s.x_max = 4.4;
  s.sigma_ref = 0.031;
  m.eps_scale = s;
  const StochasticFrictionModel back =
      StochasticModelFromJson(StochasticModelToJson(m));
  ASSERT_TRUE(back.eps_scale.has_value());
  EXPECT_EQ(back.eps_scale->input, "fn_n");
  EXPECT_EQ(back.eps_scale->log_sigma_intercept, s.log_sigma_intercept);
  EXPECT_EQ(back.eps_scale->log_sigma_slope, s.log_sigma_slope);
  EXPECT_EQ(back.eps_scale->x_min, s.x_min);
  EXPECT_EQ(back.eps_scale->x_max, s.x_max);
  EXPECT_EQ(back.eps_scale->sigma_ref, s.sigma_ref);
}

TEST(ModelJson, HostileEpsScaleIsRefusedNamingTheField) {
  StochasticFrictionModel m = WithTimeModel();
  m.eps_scale = EpsScaleModel{"fn_n", -4.0, 0.3, 0.5, 4.0, 0.03};
  const nlohmann::json good = StochasticModelToJson(m);
  const std::vector<std::pair<std::string, nlohmann::json>> bad = {
      {"sigma_ref", -1.0},
      {"sigma_ref", 0.0},
      {"x_min", 10.0},  // above x_max
      {"log_sigma_slope", 1e300},
      {"log_sigma_slope", "big"},
      {"input", "fn_n; drop"},
      {"input", 3},
  };
  for (const auto& [key, value] : bad) {
    nlohmann::json j = good;
    j["eps_scale"][key] = value;
    try {
      StochasticModelFromJson(j);
      ADD_FAILURE() << key << " = " << value.dump() << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("eps_scale"), std::string::npos)
          << e.what();
    }
  }
  nlohmann::json j = good;
  j["eps_scale"] = "yes";
  EXPECT_THROW(StochasticModelFromJson(j), std::invalid_argument);
  j["eps_scale"] = {{"input", "fn_n"}};  // missing numbers
  EXPECT_THROW(StochasticModelFromJson(j), std::invalid_argument);
}

}  // namespace
}  // namespace frictiond
