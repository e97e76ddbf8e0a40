// Where a validator's rejection crosses to a transport (InvalidArgumentFrom):
// the field comes from the error's type, never from its message, for every
// validator the routes call; and the canonical codes' HTTP mapping.
#include "frictiond/server/request_error.h"

#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/joint_friction.h"
#include "frictiond/estimators/joint_identification.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/actuator_json.h"
#include "frictiond/proto/joint_json.h"
#include "frictiond/proto/json_parse.h"

namespace frictiond {
namespace {

// The RequestError `f`'s rejection becomes, with "body" as the fallback.
RequestError Mapped(const std::function<void()>& f,
                    const std::string& prefix = "") {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return InvalidArgumentFrom(e, "body", prefix);
  }
  ADD_FAILURE() << "no exception";
  return RequestError(StatusCode::kInvalidArgument, "", "");
}

TEST(InvalidArgumentFrom, TakesTheTypedFieldAndKeepsTheMessage) {
  const RequestError e = Mapped(
      [] { throw FieldError("alt_um", "alt_um = nan (must be finite)"); });
  EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(e.field(), "alt_um");
  EXPECT_STREQ(e.what(), "alt_um = nan (must be finite)");
}

TEST(InvalidArgumentFrom, NeverReadsAFieldOutOfAPlainMessage) {
  // A message that starts like a field name is not taken for one.
  const RequestError e =
      Mapped([] { throw std::invalid_argument("k = 1 (must be >= 2)"); });
  EXPECT_EQ(e.field(), "body");
  EXPECT_STREQ(e.what(), "k = 1 (must be >= 2)");
  // An empty typed field falls back too.
  EXPECT_EQ(Mapped([] { throw FieldError("", "no single field"); }).field(),
            "body");
}

TEST(InvalidArgumentFrom, PrefixesFieldAndMessageOfANestedValue) {
  const RequestError e = Mapped(
      [] { throw FieldError("entries[3].position", "entries[3].position: x"); },
      "logs[1].");
  EXPECT_EQ(e.field(), "logs[1].entries[3].position");
  EXPECT_STREQ(e.what(), "logs[1].entries[3].position: x");
  EXPECT_EQ(
      Mapped([] { throw std::invalid_argument("odd"); }, "logs[0].").field(),
      "logs[0].body");
}

TEST(FieldError, PrefixedNamesTheOuterPath) {
  const FieldError e =
      FieldError("salt_um", "salt_um = 0 (must be > 0)").Prefixed("surface.");
  EXPECT_EQ(e.field(), "surface.salt_um");
  EXPECT_STREQ(e.what(), "surface.salt_um = 0 (must be > 0)");
}

TEST(FieldError, BecauseStartsTheMessageWithTheField) {
  const FieldError e = FieldError::Because("entries", "must be an array");
  EXPECT_EQ(e.field(), "entries");
  EXPECT_STREQ(e.what(), "entries: must be an array");
  EXPECT_STREQ(e.Prefixed("logs[2].").what(),
               "logs[2].entries: must be an array");
}

// Each validator a route calls names its field through the type, including
// the messages that begin with a position ("line 3: ", "sample 7: ").
TEST(InvalidArgumentFrom, EveryRouteValidatorNamesItsField) {
  AsperitySurface surface;
  surface.salt_um = 0;
  EXPECT_EQ(Mapped([&] { ValidateSurface(surface); }).field(), "salt_um");

  Lubricant lubricant;
  lubricant.vogel_b_c = -1;
  EXPECT_EQ(Mapped([&] { ValidateLubricant(lubricant); }).field(), "vogel_b_c");

  const Lubricant oil;
  const RequestError csv = Mapped([&] {
    ParseJointCsv("v_mm_s,load_n,mu,temp_c\n1,2,0.1,40\n1,-2,0.1,40\n", oil);
  });
  EXPECT_EQ(csv.field(), "load_n");
  EXPECT_EQ(std::string(csv.what()).rfind("line 3: load_n = -2", 0), 0u)
      << csv.what();
  EXPECT_EQ(Mapped([&] {
              ParseJointCsv("v_mm_s,mu,temp_c\n1,0.1,40\n", oil);
            }).field(),
            "load_n");

  JointData data;
  data.v_mm_s = {1, 2};
  data.load_n = {1, 1};
  data.eta_pa_s = {0.1, 0.1};
  data.mu = {0.1, std::nan("")};
  const RequestError sample = Mapped([&] { ValidateJointData(data); });
  EXPECT_EQ(sample.field(), "mu");
  EXPECT_EQ(std::string(sample.what()).rfind("sample 1: mu", 0), 0u);

  JointConfig config;
  WearParams wear;
  EXPECT_EQ(Mapped([&] {
              JointConfigFromJson(
                  nlohmann::json::parse(R"({"surface":{"salt_um":0}})"),
                  &config,
                  &wear);
            }).field(),
            "surface.salt_um");

  EXPECT_EQ(Mapped([] {
              RobotFromJson(nlohmann::json::parse(
                  R"({"joints":[{"type":"revolute","stiffness":-1,
                                 "sigma_tau":0.1}]})"));
            }).field(),
            "joints[0].stiffness");

  const nlohmann::json log = nlohmann::json::parse(
      R"({"mass":1,"length":0.1,"kp":10,"vin":12,"entries":[
          {"timestamp":0,"position":0,"goal_position":0,"torque_enable":true},
          {"timestamp":1,"goal_position":0,"torque_enable":true}]})");
  EXPECT_EQ(Mapped([&] { ActuatorLogFromJson(log); }, "logs[1].").field(),
            "logs[1].entries[1].position");
  // Header values are checked after parsing (ValidateActuatorLog).
  nlohmann::json no_step = log;
  no_step["entries"][1]["position"] = 0.1;
  no_step["dt"] = 0;
  EXPECT_EQ(Mapped([&] { ActuatorLogFromJson(no_step); }, "logs[0].").field(),
            "logs[0].dt");
  no_step["dt"] = 0.01;
  no_step["entries"][1]["timestamp"] = 0;
  EXPECT_EQ(Mapped([&] { ActuatorLogFromJson(no_step); }).field(),
            "entries[1].timestamp");
  EXPECT_EQ(Mapped([] { ParseJson("{", "log"); }).field(), "log");

  // The stroke CSV's error is the same type.
  const RequestError stroke = Mapped([] {
    ParseStrokeCsv("t_s,v_mm_s,fn_n,ft_n\n0,1,-1,0.5\n", StrokeCsvOptions{});
  });
  EXPECT_EQ(stroke.field(), "fn_n");
}

TEST(StatusCodes, MapToOneHttpStatusEach) {
  EXPECT_EQ(HttpStatusFor(StatusCode::kInvalidArgument), 400);
  EXPECT_EQ(HttpStatusFor(StatusCode::kNotFound), 404);
  EXPECT_EQ(HttpStatusFor(StatusCode::kResourceExhausted), 413);
  EXPECT_EQ(HttpStatusFor(StatusCode::kFailedPrecondition), 422);
  EXPECT_EQ(HttpStatusFor(StatusCode::kUnavailable), 503);
  EXPECT_STREQ(StatusCodeName(StatusCode::kInvalidArgument),
               "invalid_argument");
}

}  // namespace
}  // namespace frictiond
