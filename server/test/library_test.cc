#include "frictiond/server/library.h"

#include <gtest/gtest.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/server/http_server.h"
#include "frictiond/server/query_parameters.h"
#include "frictiond/server/routes.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;

std::string SimulatedCsv(std::uint64_t seed, int strokes = 8) {
  testing::SimulationSpec spec;
  spec.strokes = strokes;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

class LibraryTest : public ::testing::Test {
 protected:
  LibraryTest() : lib_(OpenStore(":memory:")) {
    RegisterCoreRoutes(http_, lib_);
    InstallQueryCheck(http_);  // as the daemon does
  }
  HttpResponse Get(const std::string& path,
                   std::multimap<std::string, std::string> query = {}) {
    HttpRequest r;
    r.method = "GET";
    r.path = path;
    r.query = std::move(query);
    return http_.Dispatch(r);
  }
  FrictionLibrary lib_;
  HttpServer http_;
};

TEST_F(LibraryTest, RefitAddsVersionsAndCacheServesNewest) {
  const IngestResult a = lib_.IngestStrokes("felt", SimulatedCsv(1), {});
  EXPECT_EQ(a.version, 1);
  EXPECT_TRUE(a.material_created);
  ASSERT_TRUE(lib_.FindModel("felt", "default"));
  const IngestResult b = lib_.IngestStrokes("felt", SimulatedCsv(2), {});
  EXPECT_EQ(b.version, 2);
  EXPECT_EQ(lib_.FindModel("felt", "default")->set.version, 2);
  // The refit uses both uploads: more slipping samples than either alone.
  EXPECT_GT(b.model->set.stochastic->samples_slip,
            a.model->set.stochastic->samples_slip);
  EXPECT_EQ(lib_.FindModelVersion("felt", "default", 1)->set.version, 1);
  const json served = json::parse(Get("/v1/materials/felt/model").body);
  EXPECT_EQ(served["version"], 2);
  EXPECT_EQ(served["material"], "felt");
  EXPECT_TRUE(served["stochastic"]["coefficients"].contains("fn_n"));
}

// A gripper's wide Fn range is a valid upload: eq. (2)'s windows coarsen
// (slip_likelihood.h) instead of the upload being refused with a 400 that
// named no field (found by an outside attack run at 0.5-250 N).
TEST_F(LibraryTest, WideFnRangeUploadIsStored) {
  testing::SimulationSpec spec;
  spec.strokes = 40;
  spec.fn_min_n = 0.5;
  spec.fn_max_n = 250.0;
  const IngestResult r = lib_.IngestStrokes(
      "gripper", FormatStrokeCsv(testing::SimulateStrokes(spec, 3)), {});
  EXPECT_EQ(r.version, 1);
  ASSERT_TRUE(lib_.FindModel("gripper", "default"));
}

TEST_F(LibraryTest, LabellingOfAnUploadIsReusedByLaterUploads) {
  IngestOptions o;
  SlipLabelOptions l;
  l.peak_mm_s = 12.0;
  l.floor_mm_s = 6.0;
  o.labelling = l;
  lib_.IngestStrokes("felt", SimulatedCsv(3), o);
  const IngestResult r = lib_.IngestStrokes("felt", SimulatedCsv(4), {});
  EXPECT_DOUBLE_EQ(r.model->set.stochastic->labelling.peak_mm_s, 12.0);
  EXPECT_DOUBLE_EQ(r.model->set.stochastic->labelling.floor_mm_s, 6.0);
}

TEST_F(LibraryTest, NoSlipIsUnprocessableAndStoresNothing) {
  const std::string csv =
      "t_s,fn_n,ft_n,v_mm_s\n0,1,0.2,0\n0.01,1,0.3,0\n0.02,1,0.4,0.5\n";
  try {
    lib_.IngestStrokes("glass", csv, {});
    FAIL() << "accepted a stroke without slip";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kFailedPrecondition);
    EXPECT_NE(std::string(e.what()).find("slipping samples"), std::string::npos)
        << e.what();
    EXPECT_EQ(e.field(), "v_mm_s");  // slip is labelled from the speed
  }
  EXPECT_FALSE(lib_.store().GetMaterial("glass"));
  EXPECT_TRUE(lib_.store().ListStrokes("glass", "default").empty());
}

// Large uploads are processed at most max_large_uploads at once (memory);
// one beyond is 503 naming the body before it is parsed, and stores
// nothing; small uploads never wait for them. The slot is given back.
TEST(LibraryLargeUploadTest, BeyondTheLimitIs503AndStoresNothing) {
  const std::string small = SimulatedCsv(1, 2);
  const std::string large = SimulatedCsv(2, 8);
  LibraryOptions o;
  o.large_upload_bytes = small.size();
  ASSERT_GT(large.size(), o.large_upload_bytes);
  o.max_large_uploads = 0;  // every large upload is one too many
  FrictionLibrary none(OpenStore(":memory:"), o);
  try {
    none.IngestStrokes("felt", large, {});
    FAIL() << "a large upload beyond the limit was accepted";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kUnavailable);
    EXPECT_EQ(e.field(), "body");
  }
  EXPECT_FALSE(none.store().GetMaterial("felt"));
  EXPECT_EQ(none.IngestStrokes("felt", small, {}).version, 1);
  o.max_large_uploads = 1;
  FrictionLibrary one(OpenStore(":memory:"), o);
  for (int version = 1; version <= 2; ++version)  // the slot comes back
    EXPECT_EQ(one.IngestStrokes("felt", large, {}).version, version);
}

// Forces within the CSV rule (finite, > 0) but so large that eq. (1)'s
// sums of squares overflow: refused naming the column that overflows, not
// a fixed field (an outside attack with Fn ~ 1e200 N got "v_mm_s").
TEST_F(LibraryTest, ForcesTooLargeToFitNameTheirColumnAndStoreNothing) {
  struct Case {
    double fn_scale, ft_scale;
    const char* field;
  };
  for (const Case& c : {Case{1e200, 1e200, "fn_n"}, Case{1.0, 1e200, "ft_n"}}) {
    testing::SimulationSpec spec;
    spec.strokes = 6;
    StrokeData d = testing::SimulateStrokes(spec, 7);
    for (double& x : d.fn_n) x *= c.fn_scale;
    for (double& x : d.ft_n) x *= c.ft_scale;
    try {
      lib_.IngestStrokes("steel", FormatStrokeCsv(d), {});
      ADD_FAILURE() << "fitted forces scaled by " << c.fn_scale << ", "
                    << c.ft_scale;
    } catch (const RequestError& e) {
      EXPECT_EQ(e.code(), StatusCode::kFailedPrecondition);
      EXPECT_EQ(e.field(), c.field) << e.what();
      EXPECT_NE(std::string(e.what()).find("too large"), std::string::npos)
          << e.what();
    }
    EXPECT_FALSE(lib_.store().GetMaterial("steel"));
  }
}

TEST_F(LibraryTest, AnUploadsAuditEntryIsStoredWithItAndOnlyThen) {
  IngestOptions o;
  o.fingertip = "tip-a";
  o.audit = AuditEntry{};
  o.audit->actor = "lcm:r1";
  o.audit->action = "LCM stroke_chunk_v2";
  o.audit->material = "felt";
  o.audit->detail = R"({"status":201,"job":7})";
  const IngestResult r = lib_.IngestStrokes("felt", SimulatedCsv(9), o);
  auto log = lib_.store().ListAudit(0, 100, "felt");
  ASSERT_EQ(log.size(), 1u);
  const json d = json::parse(log[0].detail);
  EXPECT_EQ(d["job"], 7);  // the caller's detail, completed
  EXPECT_EQ(d["fingertip"], "tip-a");
  EXPECT_EQ(d["samples"], r.samples);
  EXPECT_EQ(d["fit_status"], r.fit_status);
  EXPECT_EQ(d["stroke_id"], r.stroke_id);
  EXPECT_EQ(d["version"], r.version);
  EXPECT_EQ(d["material_created"], true);
  // A refused upload (a negative normal force) logs nothing.
  EXPECT_THROW(
      lib_.IngestStrokes("felt", "t_s,fn_n,ft_n,v_mm_s\n0,-2,1,0\n", o),
      RequestError);
  EXPECT_EQ(lib_.store().ListAudit(0, 100, "felt").size(), 1u);
}

TEST_F(LibraryTest, BadCsvNamesLineAndFieldAndStoresNothing) {
  try {
    lib_.IngestStrokes(
        "felt", "t_s,fn_n,ft_n,v_mm_s\n0,1,1,0\n0.1,-2,1,0\n", {});
    FAIL();
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(e.field(), "fn_n");
    EXPECT_EQ(e.extra()["line"], 3);
  }
  EXPECT_TRUE(lib_.ListMaterials().empty());
}

// An empty path segment (e.g. a %2F the HTTP layer decoded before
// routing) matches no route: "/v1/materials/%2F/model" was served as the
// lookup of material "model" and recorded an identification request.
TEST_F(LibraryTest, EmptyPathSegmentMatchesNoRoute) {
  EXPECT_EQ(Get("/v1/materials///model").status, 404);
  EXPECT_EQ(Get("/v1/materials//model").status, 400);  // empty id
  EXPECT_TRUE(lib_.store().ListJobs(false).empty());
  EXPECT_EQ(Get("/v1/fingertips").status, 200);
  EXPECT_EQ(Get("/v1/fingertips/").status, 404);  // as before
}

TEST_F(LibraryTest, UnknownMaterialRecordsOneIdentificationRequest) {
  const HttpResponse r1 = Get("/v1/materials/canvas/model");
  const HttpResponse r2 =
      Get("/v1/materials/canvas/predict", {{"fn_n", "1"}, {"v_mm_s", "10"}});
  EXPECT_EQ(r1.status, 404);
  EXPECT_EQ(r2.status, 404);
  const json j = json::parse(r1.body);
  EXPECT_TRUE(j["identification"]["requested"].get<bool>());
  EXPECT_EQ(j["identification"]["stroke"]["fn_n"].size(), 2u);
  EXPECT_EQ(json::parse(r2.body)["identification"]["job_id"],
            j["identification"]["job_id"]);
  EXPECT_EQ(lib_.store().ListJobs(true).size(), 1u);
  // The requested stroke arrives: the job is fitted.
  lib_.IngestStrokes("canvas", SimulatedCsv(5), {});
  EXPECT_TRUE(lib_.store().ListJobs(true).empty());
  EXPECT_EQ(Get("/v1/materials/canvas/model").status, 200);
}

TEST_F(LibraryTest, FamilyFittersAndListenersRun) {
  int notified = 0;
  lib_.AddModelListener(
      [&](const CachedModel& m) { notified += m.set.version; });
  lib_.AddFamilyFitter("demo",
                       [](const StrokeData& all,
                          const StrokeData& upload,
                          const CachedModel* previous,
                          std::string* note) -> json {
                         *note = "saw " + std::to_string(upload.size());
                         return json{{"samples", all.size()},
                                     {"had_previous", previous != nullptr}};
                       });
  lib_.IngestStrokes("felt", SimulatedCsv(6, 3), {});
  const IngestResult r = lib_.IngestStrokes("felt", SimulatedCsv(7, 3), {});
  EXPECT_EQ(notified, 1 + 2);
  EXPECT_TRUE(r.model->set.other["demo"]["had_previous"].get<bool>());
  EXPECT_NE(r.fit_note.find("demo: saw"), std::string::npos) << r.fit_note;
}

// Robots and reference images are written through the library, which
// checks what the store cannot: ids inside a robot's friction references,
// the material an image belongs to.
TEST_F(LibraryTest, PutRobotAndAddReferenceImageCheckTheirReferences) {
  nlohmann::json arm = nlohmann::json::parse(R"({
    "joints": [{"type": "revolute", "a_mm": 400, "stiffness": 20000,
                "friction": {"material": "steel-oil", "joint": "j1"}}],
    "q_home": [0]})");
  EXPECT_TRUE(lib_.PutRobot("arm1", RobotFromJson(arm)));
  EXPECT_FALSE(lib_.PutRobot("arm1", RobotFromJson(arm)));
  arm["joints"][0]["friction"]["joint"] = "no spaces";
  try {
    lib_.PutRobot("arm2", RobotFromJson(arm));
    ADD_FAILURE() << "invalid joint id accepted";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(e.field(), "joints[0].friction.joint");
  }
  EXPECT_FALSE(lib_.store().GetRobot("arm2"));

  ImageRecord image;
  image.material = "felt";
  image.mime = "image/png";
  image.features = std::string(16, '\0');
  try {
    lib_.AddReferenceImage(image);
    ADD_FAILURE() << "image of an unknown material accepted";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.code(), StatusCode::kNotFound);
    EXPECT_EQ(e.field(), "id");
  }
  lib_.PutMaterial("felt", MaterialUpdate{});
  EXPECT_GT(lib_.AddReferenceImage(image), 0);
}

TEST_F(LibraryTest, PutMaterialTakesTypedFieldsAndKeepsUnsetOnes) {
  MaterialUpdate u;
  u.name = "Felt pad";
  u.tags = std::vector<std::string>{"soft", "textile"};
  EXPECT_TRUE(lib_.PutMaterial("felt", u));
  MaterialUpdate d;
  d.description = "grey\nwool";  // free text may break lines
  EXPECT_FALSE(lib_.PutMaterial("felt", d));
  const Material m = lib_.GetMaterial("felt");
  EXPECT_EQ(m.name, "Felt pad");
  EXPECT_EQ(m.description, "grey\nwool");
  EXPECT_EQ(m.tags, (std::vector<std::string>{"soft", "textile"}));
  // Refused values name the field and store nothing.
  auto refused = [&](const MaterialUpdate& bad, const std::string& field) {
    try {
      lib_.PutMaterial("rubber", bad);
      ADD_FAILURE() << field << " accepted";
    } catch (const RequestError& e) {
      EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
      EXPECT_EQ(e.field(), field);
    }
    EXPECT_THROW(lib_.GetMaterial("rubber"), RequestError);
  };
  MaterialUpdate bad;
  bad.name = std::string("a\x01b");
  refused(bad, "name");
  bad = {};
  bad.name = std::string(201, 'n');
  refused(bad, "name");
  bad = {};
  bad.description = std::string("\xC3");
  refused(bad, "description");
  bad = {};
  bad.tags = std::vector<std::string>(65, "t");
  refused(bad, "tags");
  bad = {};
  bad.tags = std::vector<std::string>{std::string(65, 't')};
  refused(bad, "tags");
  bad = {};
  bad.description = std::string("x\a\0y", 4);  // control characters
  refused(bad, "description");
}

// A fingertip's text follows a material's rules: a name without control
// characters, a description that may break lines but holds no other
// control character (an outside attack stored NUL, ESC and BEL here).
TEST_F(LibraryTest, PutFingertipRefusesControlCharacters) {
  Fingertip ok;
  ok.id = "pad";
  ok.name = "Silicone pad";
  ok.description = "shore 30A\r\nmoulded";
  EXPECT_TRUE(lib_.PutFingertip(ok));
  auto refused = [&](Fingertip bad, const std::string& field) {
    bad.id = "pad2";
    try {
      lib_.PutFingertip(bad);
      ADD_FAILURE() << field << " accepted";
    } catch (const RequestError& e) {
      EXPECT_EQ(e.code(), StatusCode::kInvalidArgument);
      EXPECT_EQ(e.field(), field);
    }
  };
  Fingertip bad;
  bad.name = std::string("a\0b\x1b[31mRED", 12);
  refused(bad, "name");
  bad = {};
  bad.name = "a\nb";
  refused(bad, "name");
  bad = {};
  bad.description = std::string("x\a\0y", 4);
  refused(bad, "description");
  bad = {};
  bad.description = std::string("\xC3");
  refused(bad, "description");
  EXPECT_FALSE(lib_.store().GetFingertip("pad2").has_value());
}

TEST_F(LibraryTest, QueryValidationNamesTheParameter) {
  lib_.IngestStrokes("felt", SimulatedCsv(8), {});
  auto detail = [&](std::multimap<std::string, std::string> q,
                    const std::string& route) {
    const HttpResponse r = Get("/v1/materials/felt/" + route, std::move(q));
    EXPECT_EQ(r.status, 400) << r.body;
    return json::parse(r.body)["detail"].get<std::string>();
  };
  EXPECT_NE(detail({{"fn_n", "abc"}, {"v_mm_s", "1"}}, "predict").find("fn_n"),
            std::string::npos);
  EXPECT_NE(detail({{"fn_n", "1"}}, "predict").find("v_mm_s is required"),
            std::string::npos);
  EXPECT_NE(
      detail({{"fn_n", "-1"}, {"v_mm_s", "1"}}, "predict").find("must be > 0"),
      std::string::npos);
  EXPECT_NE(detail({{"load_n", "1"}, {"risk", "2"}}, "grip-force").find("risk"),
            std::string::npos);
  EXPECT_NE(
      detail({{"fn_n", "1"}, {"v_mm_s", "1"}, {"temp_c", "20"}}, "predict")
          .find("not an input"),
      std::string::npos);
  const HttpResponse bad_id = Get("/v1/materials/a;drop/model");
  EXPECT_EQ(bad_id.status, 400);
  EXPECT_EQ(json::parse(bad_id.body)["field"], "id");
}

}  // namespace
}  // namespace frictiond
