#include "frictiond/storage/store.h"

#include <cstdio>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

namespace frictiond {
namespace {

// The suite is parametrised by back end URL factory so a second back end
// (PostgreSQL) runs the same tests unchanged.
class StoreTest : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("frictiond_store_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    url_ = GetParam() == "sqlite-file" ? (dir_ / "lib.db").string()
                                       : std::string(":memory:");
    store_ = OpenStore(url_);
  }
  void TearDown() override {
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  ModelRecord Model(const std::string& material, const std::string& json) {
    ModelRecord m;
    m.material = material;
    m.reason = "test";
    m.json = json;
    return m;
  }
  std::filesystem::path dir_;
  std::string url_;
  std::unique_ptr<Store> store_;
};

TEST_P(StoreTest, MaterialsCrud) {
  Material m{"rubber-1", "Rubber", "soft", {"elastomer", "grey"}, "", ""};
  EXPECT_TRUE(store_->PutMaterial(m));
  m.name = "Rubber v2";
  EXPECT_FALSE(store_->PutMaterial(m));
  auto got = store_->GetMaterial("rubber-1");
  ASSERT_TRUE(got);
  EXPECT_EQ(got->name, "Rubber v2");
  EXPECT_EQ(got->tags, (std::vector<std::string>{"elastomer", "grey"}));
  EXPECT_FALSE(got->created_at.empty());
  EXPECT_EQ(store_->ListMaterials().size(), 1u);
  EXPECT_TRUE(store_->DeleteMaterial("rubber-1"));
  EXPECT_FALSE(store_->DeleteMaterial("rubber-1"));
  EXPECT_FALSE(store_->GetMaterial("rubber-1"));
}

TEST_P(StoreTest, SqlMetacharactersAreData) {
  Material m{"x",
             "Robert'); DROP TABLE materials;--",
             "\"quoted\" ; --",
             {"a'b"},
             "",
             ""};
  store_->PutMaterial(m);
  auto got = store_->GetMaterial("x");
  ASSERT_TRUE(got);
  EXPECT_EQ(got->name, m.name);
  EXPECT_EQ(got->tags[0], "a'b");
  EXPECT_EQ(store_->ListMaterials().size(), 1u);
}

TEST_P(StoreTest, RobotsAreCreatedThenReplaced) {
  EXPECT_FALSE(store_->GetRobot("arm-1").has_value());
  EXPECT_TRUE(
      store_->PutRobot(RobotRecord{"arm-1", R"({"joints":[]})", "", ""}));
  EXPECT_FALSE(store_->PutRobot(RobotRecord{"arm-1", R"({"v":2})", "", ""}));
  const auto r = store_->GetRobot("arm-1");
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->json, R"({"v":2})");
  EXPECT_FALSE(r->created_at.empty());
}

TEST_P(StoreTest, DefaultFingertipExists) {
  ASSERT_TRUE(store_->GetFingertip("default"));
  EXPECT_TRUE(store_->PutFingertip(
      Fingertip{"silicone-17mm", "Dragon Skin 30", "", ""}));
  EXPECT_EQ(store_->ListFingertips().size(), 2u);
}

TEST_P(StoreTest, UploadsAppendVersionsNeverOverwrite) {
  StrokeRecord s;
  s.material = "felt";
  s.robot = "arm-7";
  s.samples = 3;
  s.csv = "t_s,fn_n,ft_n,v_mm_s\n0,1,1,0\n";
  const UploadCommit c1 = store_->CommitUpload(s, Model("felt", "{\"v\":1}"));
  EXPECT_TRUE(c1.material_created);
  EXPECT_EQ(c1.version, 1);
  const UploadCommit c2 = store_->CommitUpload(s, Model("felt", "{\"v\":2}"));
  EXPECT_FALSE(c2.material_created);
  EXPECT_EQ(c2.version, 2);
  EXPECT_EQ(store_->AddModelVersion(Model("felt", "{\"v\":3}")), 3);
  EXPECT_EQ(store_->GetLatestModel("felt", "default")->json, "{\"v\":3}");
  EXPECT_EQ(store_->GetModel("felt", "default", 1)->json, "{\"v\":1}");
  EXPECT_EQ(store_->GetModel("felt", "default", 2)->stroke_id, c2.stroke_id);
  EXPECT_EQ(store_->ListModels("felt", "default").size(), 3u);
  const auto strokes = store_->ListStrokes("felt", "default");
  ASSERT_EQ(strokes.size(), 2u);
  EXPECT_EQ(strokes[0].robot, "arm-7");
  EXPECT_TRUE(strokes[0].csv.empty());
  EXPECT_EQ(store_->GetStroke(c1.stroke_id)->csv, s.csv);
  // Other fingertips are separate pairs.
  StrokeRecord s2 = s;
  s2.fingertip = "tip-b";
  ModelRecord m2 = Model("felt", "{}");
  m2.fingertip = "tip-b";
  EXPECT_EQ(store_->CommitUpload(s2, m2).version, 1);
  EXPECT_TRUE(store_->GetFingertip("tip-b"));
  // Delete cascades.
  EXPECT_TRUE(store_->DeleteMaterial("felt"));
  EXPECT_FALSE(store_->GetLatestModel("felt", "default"));
  EXPECT_FALSE(store_->GetStroke(c1.stroke_id));
}

TEST_P(StoreTest, IdentificationJobsOpenOncePerPair) {
  IdentificationJob j;
  j.material = "unknown-cloth";
  j.plan_json = "{}";
  j.requested_by = "robot-1";
  const auto a = store_->RequestIdentification(j);
  const auto b = store_->RequestIdentification(j);
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.state, "requested");
  EXPECT_EQ(store_->ListJobs(true).size(), 1u);
  StrokeRecord s;
  s.material = "unknown-cloth";
  s.csv = "x";
  ModelRecord m;
  m.material = "unknown-cloth";
  m.json = "{}";
  store_->CommitUpload(s, m);
  EXPECT_EQ(store_->GetJob(a.id)->state, "fitted");
  EXPECT_TRUE(store_->ListJobs(true).empty());
  EXPECT_EQ(store_->ListJobs(false).size(), 1u);
  EXPECT_TRUE(store_->UpdateJob(a.id, "failed", "why"));
  EXPECT_FALSE(store_->UpdateJob(999, "failed", "why"));
}

TEST_P(StoreTest, ReopenKeepsDataAndSchema) {
  if (GetParam() != "sqlite-file")
    GTEST_SKIP() << "in-memory database does not persist";
  store_->PutMaterial(Material{"a", "A", "", {}, "", ""});
  const int schema = store_->SchemaVersion();
  EXPECT_GE(schema, 1);
  store_.reset();
  store_ = OpenStore(url_);
  EXPECT_EQ(store_->SchemaVersion(), schema);
  EXPECT_TRUE(store_->GetMaterial("a"));
  EXPECT_EQ(store_->CheckIntegrity(), "");
}

TEST_P(StoreTest, TokensFoundByHashAndRevokedOnce) {
  TokenRecord a{
      "tok_000000000001", "ops", "operator", std::string(64, 'a'), "", ""};
  TokenRecord b{
      "tok_000000000002", "arm", "robot", std::string(64, 'b'), "", ""};
  EXPECT_TRUE(store_->AddToken(a));
  EXPECT_TRUE(store_->AddToken(b));
  EXPECT_FALSE(store_->AddToken(a));  // same id
  const auto found = store_->FindTokenByHash(std::string(64, 'b'));
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->id, "tok_000000000002");
  EXPECT_EQ(found->name, "arm");
  EXPECT_EQ(found->role, "robot");
  EXPECT_FALSE(found->created_at.empty());
  EXPECT_TRUE(found->revoked_at.empty());
  EXPECT_FALSE(store_->FindTokenByHash(std::string(64, 'c')).has_value());
  const auto all = store_->ListTokens();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, a.id);
  EXPECT_EQ(all[1].id, b.id);
  EXPECT_TRUE(store_->RevokeToken(b.id));
  EXPECT_FALSE(store_->RevokeToken(b.id));
  EXPECT_FALSE(store_->RevokeToken("tok_unknown"));
  const auto revoked = store_->FindTokenByHash(std::string(64, 'b'));
  ASSERT_TRUE(revoked.has_value());
  EXPECT_FALSE(revoked->revoked_at.empty());
  EXPECT_TRUE(store_->FindTokenByHash(a.hash)->revoked_at.empty());
}

TEST_P(StoreTest, AuditAppendsAndPagesByMaterial) {
  std::vector<std::int64_t> ids;
  for (int i = 0; i < 5; ++i) {
    AuditEntry e;
    e.actor = "tok_" + std::to_string(i);
    e.role = "operator";
    e.remote = "127.0.0.1";
    e.action = "PUT /v1/materials/{id}";
    e.material = i % 2 == 0 ? "even" : "odd";
    e.detail = R"({"i":)" + std::to_string(i) + "}";
    ids.push_back(store_->AppendAudit(e));
  }
  for (std::size_t i = 1; i < ids.size(); ++i) EXPECT_GT(ids[i], ids[i - 1]);
  const auto all = store_->ListAudit(0, 100, "");
  ASSERT_EQ(all.size(), 5u);
  EXPECT_EQ(all[0].actor, "tok_0");
  EXPECT_EQ(all[0].remote, "127.0.0.1");
  EXPECT_EQ(all[0].action, "PUT /v1/materials/{id}");
  EXPECT_EQ(all[4].detail, R"({"i":4})");
  EXPECT_FALSE(all[0].at.empty());
  const auto page = store_->ListAudit(ids[1], 2, "");
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].id, ids[2]);
  EXPECT_EQ(page[1].id, ids[3]);
  const auto even = store_->ListAudit(0, 100, "even");
  ASSERT_EQ(even.size(), 3u);
  for (const auto& e : even) EXPECT_EQ(e.material, "even");
  EXPECT_TRUE(store_->ListAudit(ids[4], 100, "").empty());
  // Audit outlives the material it names.
  store_->PutMaterial(Material{"even", "E", "", {}, "", ""});
  store_->DeleteMaterial("even");
  EXPECT_EQ(store_->ListAudit(0, 100, "even").size(), 3u);
}

TEST(OpenStore, RejectsUnsupportedUrl) {
  EXPECT_THROW(OpenStore("postgresql://localhost/x"), std::invalid_argument);
  EXPECT_THROW(OpenStore(""), std::invalid_argument);
  EXPECT_THROW(OpenStore("/nonexistent-dir/x/y.db"), std::runtime_error);
}

INSTANTIATE_TEST_SUITE_P(Backends,
                         StoreTest,
                         ::testing::Values("sqlite-file", "sqlite-memory"));

}  // namespace
}  // namespace frictiond
