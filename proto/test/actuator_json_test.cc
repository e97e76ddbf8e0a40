#include "frictiond/proto/actuator_json.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

const char* kGood =
    R"({"mass": 0.49, "length": 0.1, "kp": 400, "vin": 7.4, "dt": 0.005,
        "trajectory": "sin_sin", "entries": [
        {"timestamp": 0.0, "position": 0.1, "speed": 0.0, "goal_position": 0.2,
         "torque_enable": true, "temp": 30},
        {"timestamp": 0.005, "position": 0.11, "speed": 2.0, "goal_position": 0.2,
         "torque_enable": false, "temp": 31}]})";

std::string Refusal(const std::string& text) {
  try {
    ParseActuatorLog(text);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(ActuatorJsonTest, ParsesALog) {
  const ActuatorLog log = ParseActuatorLog(kGood, "x");
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(log.trajectory, "sin_sin");
  EXPECT_DOUBLE_EQ(log.q_rad[1], 0.11);
  EXPECT_EQ(log.torque_enable[1], 0);
  EXPECT_DOUBLE_EQ(log.dt_s, 0.005);
}

TEST(ActuatorJsonTest, RefusesBadLogsNamingTheField) {
  std::string s = kGood;
  EXPECT_EQ(Refusal(""), "log: empty");
  EXPECT_NE(Refusal("{").find("invalid JSON"), std::string::npos);
  EXPECT_NE(Refusal(R"({"mass": 1})").find("length: missing"),
            std::string::npos);
  std::string no_pos = s;
  no_pos.replace(no_pos.find("\"position\": 0.11"), 16, "\"positio\": 0.11");
  EXPECT_NE(Refusal(no_pos).find("entries[1].position: missing"),
            std::string::npos)
      << Refusal(no_pos);
  std::string back = s;
  back.replace(back.find("0.005, \"position\""), 5, "0.000");
  EXPECT_NE(Refusal(back).find("entries[1].timestamp"), std::string::npos)
      << Refusal(back);
  std::string empty =
      R"({"mass": 0.49, "length": 0.1, "kp": 400, "vin": 7.4, "entries": []})";
  EXPECT_EQ(Refusal(empty), "entries: empty");
  std::string neg = s;
  neg.replace(neg.find("\"kp\": 400"), 9, "\"kp\": -40");
  EXPECT_NE(Refusal(neg).find("kp = -40"), std::string::npos) << Refusal(neg);
  std::string deep(100, '[');
  EXPECT_NE(Refusal(deep), "accepted");
}

TEST(ActuatorJsonTest, ModelRoundTripAndBamParams) {
  ActuatorModel m = MakeDefaultActuatorModel(ActuatorFrictionLaw::kBamM6);
  m.kt = 0.31;
  const ActuatorModel back = ActuatorModelFromJson(ActuatorModelToJson(m));
  EXPECT_EQ(back.law, ActuatorFrictionLaw::kBamM6);
  EXPECT_DOUBLE_EQ(back.kt, 0.31);
  const ActuatorModel bam = ParseBamParams(
      R"({"kt": 0.32, "R": 4.7, "armature": 0.0016, "q_offset": 0.018,
          "friction_base": 0.007, "friction_viscous": 0.01, "model": "m1"})");
  EXPECT_EQ(bam.law, ActuatorFrictionLaw::kCoulombViscous);
  EXPECT_DOUBLE_EQ(bam.friction.friction_base, 0.007);
  EXPECT_THROW(ParseBamParams(R"({"model": "m9"})"), std::invalid_argument);
  const std::string mjcf = ExportActuatorMjcf(bam, "shoulder");
  EXPECT_NE(mjcf.find("frictionloss=\"0.007\""), std::string::npos) << mjcf;
  EXPECT_NE(mjcf.find("armature=\"0.0016\""), std::string::npos) << mjcf;
}

}  // namespace
}  // namespace frictiond
