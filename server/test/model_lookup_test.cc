#include "frictiond/server/model_lookup.h"

#include <stdexcept>

#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using Outcome = ModelLookup::Outcome;

class ModelLookupTest : public ::testing::Test {
 protected:
  ModelLookupTest() : lib_(OpenStore(":memory:")) {
    testing::SimulationSpec spec;
    spec.strokes = 8;
    lib_.IngestStrokes(
        "felt", FormatStrokeCsv(testing::SimulateStrokes(spec, 1)), {});
  }
  FrictionLibrary lib_;
};

// A fake recogniser: "felt-image" is felt at 0.9, anything else unknown,
// "broken" cannot be decoded.
ImageRecognition Recognize(const std::string& image) {
  if (image == "broken") throw std::invalid_argument("not a PNG or JPEG");
  ImageRecognition r;
  if (image == "felt-image") {
    r.unknown = false;
    r.candidates = {{"felt", 0.9}};
  }
  return r;
}

TEST_F(ModelLookupTest, KnownPairGivesItsModel) {
  const ModelLookup l = LookUpModel(lib_, "felt", "default", "robot-1");
  ASSERT_EQ(l.outcome, Outcome::kKnown);
  ASSERT_TRUE(l.model);
  EXPECT_EQ(l.model->set.version, 1);
  EXPECT_TRUE(lib_.store().ListJobs(false).empty());  // nothing requested
}

TEST_F(ModelLookupTest, UnknownPairRecordsAnIdentification) {
  const ModelLookup l = LookUpModel(lib_, "felt", "tip2", "robot-1");
  ASSERT_EQ(l.outcome, Outcome::kUnknown);
  EXPECT_TRUE(l.known_material);
  ASSERT_TRUE(l.identification.requested) << l.identification.reason;
  EXPECT_EQ(l.identification.plan.fingertip, "tip2");
  EXPECT_EQ(l.message,
            "material 'felt' has no friction model for fingertip 'tip2' yet: "
            "an identification was requested");
  const ModelLookup cork = LookUpModel(lib_, "cork", "default", "robot-1");
  EXPECT_FALSE(cork.known_material);
  EXPECT_EQ(cork.message,
            "unknown material 'cork': an identification was requested");
  // RequireModel (HTTP) throws the same message with the request as JSON.
  try {
    lib_.RequireModel("cork", "default", "robot-1");
    FAIL() << "no model, but RequireModel returned";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kNotFound);
    EXPECT_EQ(std::string(e.what()), cork.message);
    EXPECT_EQ(e.extra()["identification"]["job_id"],
              cork.identification.job_id);
    EXPECT_EQ(e.extra()["known_material"], false);
  }
  EXPECT_THROW(LookUpModel(lib_, "bad id", "default", "r"), RequestError);
}

TEST_F(ModelLookupTest, QueriesNeverThrowAndNameTheField) {
  const ModelLookup bad =
      LookUpModelForQuery(lib_, nullptr, "bad id", "default", "", "lcm:r");
  EXPECT_EQ(bad.outcome, Outcome::kRejected);
  EXPECT_EQ(bad.field, "material");
  const ModelLookup tip =
      LookUpModelForQuery(lib_, nullptr, "felt", "bad tip", "", "lcm:r");
  EXPECT_EQ(tip.field, "fingertip");
  const ModelLookup no_hook =
      LookUpModelForQuery(lib_, nullptr, "", "default", "felt-image", "lcm:r");
  EXPECT_EQ(no_hook.field, "image");
  const ModelLookup known = LookUpModelForQuery(
      lib_, Recognize, "", "default", "felt-image", "lcm:r");
  ASSERT_EQ(known.outcome, Outcome::kKnown) << known.message;
  EXPECT_EQ(known.material, "felt");
  EXPECT_EQ(known.recognition_score, 0.9);
  const ModelLookup broken =
      LookUpModelForQuery(lib_, Recognize, "", "default", "broken", "lcm:r");
  EXPECT_EQ(broken.field, "image");
  EXPECT_EQ(broken.message, "image: not a PNG or JPEG");
  const ModelLookup unnamed =
      LookUpModelForQuery(lib_, Recognize, "", "default", "other", "lcm:r");
  EXPECT_EQ(unnamed.field, "material");
  // An unrecognised image with the id the new material should get.
  const ModelLookup named =
      LookUpModelForQuery(lib_, Recognize, "cork", "default", "other", "lcm:r");
  ASSERT_EQ(named.outcome, Outcome::kUnknown);
  EXPECT_EQ(named.material, "cork");
  EXPECT_EQ(named.recognition_score, 0.0);
  EXPECT_TRUE(named.identification.requested);
}

}  // namespace
}  // namespace frictiond
