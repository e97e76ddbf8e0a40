// Cross-module test of `friction diagnose` (CONTRACT.md, "Model diagnosis"):
// runs the built binary on planted-effect CSV files and checks the JSON shape
// and that the planted cause is named first.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/testing/lugre_strokes.h"
#include "frictiond/testing/planted_effects.h"

namespace frictiond {
namespace {

namespace fs = std::filesystem;
using testing::GeneratePlantedStrokes;
using testing::PlantedEffect;
using testing::PlantedSpec;

struct CliRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

std::string FrictionBinary() {
  const char* dir = std::getenv("FRICTIOND_BIN_DIR");
  return std::string(dir ? dir : "build/bin") + "/friction";
}

std::string ReadAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

class DiagnoseCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("diagnose_cli_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path Write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  fs::path WritePlanted(const std::string& name,
                        PlantedEffect effect,
                        std::uint64_t seed) {
    PlantedSpec spec;
    spec.effect = effect;
    spec.strokes = 60;
    return Write(name, FormatStrokeCsv(GeneratePlantedStrokes(spec, seed)));
  }
  CliRun Friction(const std::string& args) {
    CliRun r;
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = FrictionBinary() + " " + args + " >" +
                            out.string() + " 2>" + err.string();
    const int status = std::system(cmd.c_str());
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = ReadAll(out);
    r.err = ReadAll(err);
    return r;
  }
  fs::path dir_;
};

void ExpectContractShape(const nlohmann::json& j) {
  ASSERT_TRUE(j.is_object());
  ASSERT_TRUE(j.contains("baseline"));
  EXPECT_TRUE(j["baseline"]["model"].is_string());
  EXPECT_TRUE(j["baseline"]["cv_mae"].is_number());
  ASSERT_TRUE(j["findings"].is_array());
  for (const auto& f : j["findings"]) {
    EXPECT_TRUE(f["cause"].is_string());
    const std::string kind = f["kind"];
    // Issue 18 adds the kinds "interaction" and "spread".
    EXPECT_TRUE(kind == "covariate" || kind == "form" || kind == "regime" ||
                kind == "interaction" || kind == "spread")
        << kind;
    EXPECT_TRUE(f["selection_bias_pct"].is_number());
    EXPECT_TRUE(f["alternatives"].is_array());
    EXPECT_TRUE(f["p_value"].is_number());
    EXPECT_TRUE(f["cv_mae_gain_pct"].is_number());
    EXPECT_TRUE(f["effect"].is_string());
  }
  ASSERT_TRUE(j.contains("extended"));
  EXPECT_TRUE(j["extended"]["model"].is_string());
  EXPECT_TRUE(j["extended"]["cv_mae"].is_number());
  EXPECT_TRUE(j["extended"]["gain_pct"].is_number());
  EXPECT_TRUE(j["extended"]["terms"].is_array());
}

TEST_F(DiagnoseCliTest, NamesThePlantedCauseFirstAcrossTwoFiles) {
  const fs::path a = WritePlanted("a.csv", PlantedEffect::kTemperature, 21);
  const fs::path b = WritePlanted("b.csv", PlantedEffect::kTemperature, 22);
  const CliRun r =
      Friction("diagnose " + a.string() + " " + b.string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  nlohmann::json j;
  ASSERT_NO_THROW(j = nlohmann::json::parse(r.out)) << r.out.substr(0, 400);
  ExpectContractShape(j);
  ASSERT_FALSE(j["findings"].empty()) << j.dump(1).substr(0, 2000);
  EXPECT_EQ(j["findings"][0]["cause"], "temp_c") << j["findings"].dump(1);
  EXPECT_EQ(j["findings"][0]["kind"], "covariate");
  EXPECT_LT(j["extended"]["cv_mae"].get<double>(),
            j["baseline"]["cv_mae"].get<double>());
  EXPECT_GT(j["extended"]["gain_pct"].get<double>(), 0.0);
  EXPECT_EQ(j["extended"]["model"].get<std::string>().rfind("linear+temp_c", 0),
            0u)
      << j["extended"]["model"];
  // Both files keep their strokes apart (2 x 60 generated; slow ones merge).
  EXPECT_GT(j["data"]["strokes"].get<int>(), 80);
}

TEST_F(DiagnoseCliTest, NullDataGivesNoFindingsAndExtendedEqualsBaseline) {
  const fs::path a = WritePlanted("null.csv", PlantedEffect::kNone, 31);
  const CliRun r = Friction("diagnose " + a.string() + " --json --report " +
                            (dir_ / "report.html").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ExpectContractShape(j);
  EXPECT_TRUE(j["findings"].empty()) << j["findings"].dump(1);
  EXPECT_EQ(j["extended"]["model"], j["baseline"]["model"]);
  EXPECT_EQ(j["extended"]["cv_mae"], j["baseline"]["cv_mae"]);
  EXPECT_EQ(j["extended"]["gain_pct"].get<double>(), 0.0);
  const std::string html = ReadAll(dir_ / "report.html");
  EXPECT_NE(html.find("<svg"), std::string::npos);
}

TEST_F(DiagnoseCliTest, HumanSummaryWithoutJson) {
  const fs::path a = WritePlanted("p.csv", PlantedEffect::kNonlinearFn, 41);
  const CliRun r = Friction("diagnose " + a.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("findings"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fn_n"), std::string::npos) << r.out;
}

TEST_F(DiagnoseCliTest, BadFileExitsWithCode2AndTheLine) {
  const fs::path good = WritePlanted("good.csv", PlantedEffect::kNone, 51);
  const fs::path bad =
      Write("bad.csv", "t_s,fn_n,ft_n,v_mm_s\n0,1,0.5,0\n0.01,-1,0.5,0\n");
  const CliRun r =
      Friction("diagnose " + good.string() + " " + bad.string() + " --json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find(bad.string() + ": line 3: fn_n"), std::string::npos)
      << r.err;
  EXPECT_TRUE(r.out.empty()) << r.out;
}

TEST_F(DiagnoseCliTest, LuGreReplayBesideCoulombAndLinear) {
  testing::LuGreStrokeSpec spec;  // truth 0.9, 0.6, 5, 0.004, 50, 0.1
  const fs::path f = Write(
      "lugre.csv", FormatStrokeCsv(testing::SimulateLuGreStrokes(spec, 4)));
  CliRun r = Friction("diagnose " + f.string() +
                      " --json --no-tests --lugre 0.9,0.6,5,0.004,50,0.1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  ExpectContractShape(j);
  std::map<std::string, nlohmann::json> by_model;
  for (const auto& m : j["replay"]) by_model[m["model"]] = m;
  ASSERT_EQ(by_model.count("lugre"), 1u) << j["replay"].dump(1);
  ASSERT_EQ(by_model.count("coulomb"), 1u);
  ASSERT_EQ(by_model.count("linear"), 1u);
  const nlohmann::json& lugre = by_model["lugre"]["overall"];
  const nlohmann::json& coulomb = by_model["coulomb"]["overall"];
  EXPECT_LT(lugre["mu_mae"].get<double>(),
            0.5 * coulomb["mu_mae"].get<double>())
      << j["replay"].dump(1);
  EXPECT_LT(lugre["breakaway_abs_error"].get<double>(),
            coulomb["breakaway_abs_error"].get<double>());
  EXPECT_TRUE(lugre["hits"].is_null());  // velocity-driven: no slip forecast
  EXPECT_TRUE(coulomb["hits"].is_number());
  EXPECT_TRUE(by_model["lugre"]["note"].is_string());
  EXPECT_TRUE(j["replay_skipped"].empty()) << j["replay_skipped"];

  // Without --lugre the JSON says why LuGre was not replayed.
  r = Friction("diagnose " + f.string() + " --json --no-tests");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json without = nlohmann::json::parse(r.out);
  for (const auto& m : without["replay"]) EXPECT_NE(m["model"], "lugre");
  ASSERT_EQ(without["replay_skipped"].size(), 1u);

  // Bad parameter sets exit 2 naming the problem.
  r = Friction("diagnose " + f.string() + " --json --lugre 0.9,0.6");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("--lugre"), std::string::npos) << r.err;
  r = Friction("diagnose " + f.string() + " --json --lugre 0.9,0.6,5,0,-50,0");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("sigma0"), std::string::npos) << r.err;

  // --lugre-from fetches a stored LuGre model: both options at once is a
  // usage error, an unreachable daemon a runtime error naming it.
  r = Friction("diagnose " + f.string() +
               " --json --lugre 0.9,0.6,5,0.004,50,0.1 --lugre-from steel");
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.err.find("--lugre-from"), std::string::npos) << r.err;
  r = Friction("--server http://127.0.0.1:1 diagnose " + f.string() +
               " --json --lugre-from steel");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.err.find("127.0.0.1:1"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace frictiond
