#include "frictiond/proto/sim_export.h"

#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tinyxml2.h>

#include "frictiond/testing/usda_checker.h"

namespace frictiond {
namespace {

// Known truth (see also estimators/test/contact_friction_test.cc):
// mu = b0 + b1*v + b2*Fn + eps, eps ~ U(-half, half), no coefficient
// uncertainty, so Q_mu(r) = b0 + b1*v + b2*Fn - half + 2*half*r exactly.
constexpr double kB0 = 0.9, kB1 = 0.004, kB2 = -0.06, kHalf = 0.1;
constexpr double kFn = 3.0, kV = 20.0;

double Truth(double r) {
  return kB0 + kB1 * kV + kB2 * kFn - kHalf + 2 * kHalf * r;
}

StochasticFrictionModel UniformEpsModel() {
  StochasticFrictionModel m;
  m.mu.terms = {
      Term::Intercept(), Term::Linear("v_mm_s"), Term::Linear("fn_n")};
  m.mu.beta = Eigen::Vector3d(kB0, kB1, kB2);
  m.mu.std_err = Eigen::Vector3d::Zero();
  m.mu.P_beta = Eigen::Matrix3d::Zero();
  m.mu.sigma_eps = 2 * kHalf / std::sqrt(12.0);
  for (double p : EpsQuantileLevels())
    m.mu.eps_quantiles.push_back(-kHalf + 2 * kHalf * p);
  m.inputs["fn_n"] = {2.5, 0.5, 4.5};
  m.inputs["v_mm_s"] = {40.0, 15.0, 80.0};
  return m;
}

SimExportInput Input(double risk, const std::string& name = "felt") {
  SimExportInput in;
  in.name = name;
  in.material = "felt";
  in.version = 4;
  in.fn_n = kFn;
  in.v_mm_s = kV;
  in.operating_point_source = "query";
  in.risk = risk;
  in.mu =
      CalcMuDistribution(UniformEpsModel(), {{"fn_n", kFn}, {"v_mm_s", kV}});
  return in;
}

// Parses XML with tinyxml2; fails the test with the parser's message.
bool ParseXml(const std::string& text, tinyxml2::XMLDocument* doc) {
  const tinyxml2::XMLError err = doc->Parse(text.c_str(), text.size());
  if (err != tinyxml2::XML_SUCCESS) {
    ADD_FAILURE() << "XML parse error: " << doc->ErrorStr() << "\n" << text;
    return false;
  }
  return true;
}

double ToDouble(const char* text) {
  if (!text) {
    ADD_FAILURE() << "missing number";
    return std::nan("");
  }
  char* end = nullptr;
  const double x = std::strtod(text, &end);
  EXPECT_EQ(*end, '\0') << "trailing text after number: " << text;
  return x;
}

void ExpectRel(double actual, double expected, const std::string& what) {
  EXPECT_LE(std::fabs(actual - expected), 1e-9 * std::fabs(expected))
      << what << ": actual " << actual << ", expected " << expected;
}

const double kRisks[] = {0.001, 0.0123, 0.05, 0.2};

TEST(SimExport, MjcfParsesAndCarriesTheRiskQuantile) {
  for (double r : kRisks) {
    const std::string text = FormatSimExport(SimFormat::kMjcf, Input(r));
    tinyxml2::XMLDocument doc;
    ASSERT_TRUE(ParseXml(text, &doc));
    const auto* root = doc.FirstChildElement("mujoco");
    ASSERT_NE(root, nullptr) << text;
    const auto* cls =
        root->FirstChildElement("default")->FirstChildElement("default");
    ASSERT_NE(cls, nullptr) << text;
    EXPECT_STREQ(cls->Attribute("class"), "felt");
    const auto* geom = cls->FirstChildElement("geom");
    ASSERT_NE(geom, nullptr) << text;
    double s = 0, t = 0, roll = 0;
    ASSERT_EQ(
        std::sscanf(geom->Attribute("friction"), "%lf %lf %lf", &s, &t, &roll),
        3);
    ExpectRel(s, Truth(r), "sliding at risk " + std::to_string(r));
    EXPECT_EQ(t, kMujocoTorsionalFriction);
    EXPECT_EQ(roll, kMujocoRollingFriction);
    // The distribution is stated in comments.
    EXPECT_NE(text.find("<!-- mu at the operating point: mean"),
              std::string::npos);
    EXPECT_NE(text.find("p0.1="), std::string::npos) << text;
  }
}

TEST(SimExport, SdfParsesAndRoundTrips) {
  for (double r : kRisks) {
    tinyxml2::XMLDocument doc;
    ASSERT_TRUE(ParseXml(FormatSimExport(SimFormat::kSdf, Input(r)), &doc));
    const auto* ode = doc.FirstChildElement("surface")
                          ->FirstChildElement("friction")
                          ->FirstChildElement("ode");
    ASSERT_NE(ode, nullptr);
    ExpectRel(
        ToDouble(ode->FirstChildElement("mu")->GetText()), Truth(r), "mu");
    ExpectRel(
        ToDouble(ode->FirstChildElement("mu2")->GetText()), Truth(r), "mu2");
  }
}

TEST(SimExport, UrdfGazeboTagsParseAndRoundTrip) {
  for (double r : kRisks) {
    tinyxml2::XMLDocument doc;
    ASSERT_TRUE(ParseXml(
        FormatSimExport(SimFormat::kUrdf, Input(r, "finger_pad")), &doc));
    const auto* gz =
        doc.FirstChildElement("robot")->FirstChildElement("gazebo");
    ASSERT_NE(gz, nullptr);
    EXPECT_STREQ(gz->Attribute("reference"), "finger_pad");
    ExpectRel(
        ToDouble(gz->FirstChildElement("mu1")->GetText()), Truth(r), "mu1");
    ExpectRel(
        ToDouble(gz->FirstChildElement("mu2")->GetText()), Truth(r), "mu2");
  }
}

TEST(SimExport, UsdFollowsTheGrammarAndRoundTrips) {
  for (double r : kRisks) {
    const std::string text = FormatSimExport(SimFormat::kUsd, Input(r));
    usda::Layer layer;
    try {
      layer = usda::Parse(text);
    } catch (const usda::SyntaxError& e) {
      FAIL() << e.what() << "\n" << text;
    }
    ASSERT_EQ(layer.prims.size(), 1u);
    const usda::Prim& p = layer.prims[0];
    EXPECT_EQ(p.specifier, "def");
    EXPECT_EQ(p.type, "Material");
    EXPECT_EQ(p.name, "felt");
    EXPECT_EQ(layer.metadata.at("defaultPrim").at(0), "felt");
    ASSERT_EQ(p.metadata.count("apiSchemas"), 1u);
    EXPECT_EQ(p.metadata.at("apiSchemas"),
              std::vector<std::string>{"PhysicsMaterialAPI"});
    for (const char* attr :
         {"physics:staticFriction", "physics:dynamicFriction"}) {
      ASSERT_EQ(p.attributes.count(attr), 1u) << attr;
      const usda::Attribute& a = p.attributes.at(attr);
      EXPECT_EQ(a.type, "float");
      EXPECT_FALSE(a.custom);
      ExpectRel(ToDouble(a.values.at(0).c_str()), Truth(r), attr);
    }
    const usda::Attribute& q = p.attributes.at("frictiond:muQuantiles");
    EXPECT_TRUE(q.array);
    EXPECT_EQ(q.values.size(), EpsQuantileLevels().size());
    ExpectRel(ToDouble(q.values.front().c_str()), Truth(0.001), "q[0]");
  }
}

TEST(SimExport, UsdCheckerRejectsBrokenText) {
  const std::string good = FormatSimExport(SimFormat::kUsd, Input(0.05));
  EXPECT_NO_THROW(usda::Parse(good));
  // The checker is not a rubber stamp: each of these breaks the grammar.
  const std::string broken[] = {
      good.substr(1),                                            // header
      good.substr(0, good.rfind('}')),                           // unbalanced {
      "#usda 1.0\ndef Material \"3x\" {\n}\n",                   // prim name
      "#usda 1.0\ndef Material \"m\" {\n float a = \"x\"\n}\n",  // type
      "#usda 1.0\ndef Material \"m\" {\n float[] a = 1\n}\n",    // array
      "#usda 1.0\ndef Material \"m\" (\n apiSchemas = [\"A\"\n) {}\n",
      "#usda 1.0\ndef Material \"m {\n}\n",  // string
  };
  for (const std::string& b : broken)
    EXPECT_THROW(usda::Parse(b), usda::SyntaxError) << b;
}

TEST(SimExport, IsaacRangesAreTheQuantilesAtRiskAndOneMinusRisk) {
  for (double r : kRisks) {
    const nlohmann::json j =
        nlohmann::json::parse(FormatSimExport(SimFormat::kIsaac, Input(r)));
    for (const char* key :
         {"static_friction_range", "dynamic_friction_range"}) {
      ASSERT_EQ(j.at(key).size(), 2u) << key;
      ExpectRel(j[key][0].get<double>(), Truth(r), key);
      ExpectRel(j[key][1].get<double>(), Truth(1 - r), key);
      EXPECT_EQ(j["isaac_lab_event"]["params"][key], j[key]);
    }
    EXPECT_DOUBLE_EQ(j.at("operating_point").at("fn_n").get<double>(), kFn);
    EXPECT_EQ(j.at("mu").at("quantiles").size(), EpsQuantileLevels().size());
  }
}

TEST(SimExport, NamesAreEscapedForEveryFormat) {
  // Hostile name: XML metacharacters, comment terminator, USD-invalid chars.
  const std::string name = "a<b>&\"c'--d-";
  SimExportInput in = Input(0.05, name);
  in.material = "x--y-";
  for (SimFormat f : {SimFormat::kMjcf, SimFormat::kSdf, SimFormat::kUrdf}) {
    const std::string text = FormatSimExport(f, in);
    tinyxml2::XMLDocument doc;
    ASSERT_TRUE(ParseXml(text, &doc)) << SimFormatName(f);
  }
  tinyxml2::XMLDocument doc;
  ASSERT_TRUE(ParseXml(FormatSimExport(SimFormat::kMjcf, in), &doc));
  EXPECT_EQ(std::string(doc.FirstChildElement("mujoco")
                            ->FirstChildElement("default")
                            ->FirstChildElement("default")
                            ->Attribute("class")),
            name);
  const usda::Layer layer = usda::Parse(FormatSimExport(SimFormat::kUsd, in));
  EXPECT_EQ(layer.prims.at(0).name, "a_b___c___d_");
  EXPECT_EQ(MakeUsdIdentifier("3d-felt.v2"), "_3d_felt_v2");
  EXPECT_EQ(MakeUsdIdentifier(""), "_");
  EXPECT_EQ(XmlCommentText("a--b-"), "a- -b- ");
}

TEST(SimExport, RejectsBadInputNamingTheField) {
  auto expect_msg = [](const SimExportInput& in, const std::string& field) {
    try {
      FormatSimExport(SimFormat::kMjcf, in);
      ADD_FAILURE() << "accepted bad " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).rfind(field, 0), 0u) << e.what();
    }
  };
  expect_msg(Input(0.05, ""), "name");
  expect_msg(Input(0.05, std::string(129, 'a')), "name");
  expect_msg(Input(0.05, "tab\there"), "name");
  expect_msg(Input(0.7), "risk");
  expect_msg(Input(0.0001), "risk");
  try {
    ParseSimFormat("stl");
    ADD_FAILURE() << "accepted stl";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("format = 'stl'"), std::string::npos);
  }
  for (SimFormat f : {SimFormat::kMjcf,
                      SimFormat::kSdf,
                      SimFormat::kUrdf,
                      SimFormat::kUsd,
                      SimFormat::kIsaac})
    EXPECT_EQ(ParseSimFormat(SimFormatName(f)), f);
}

TEST(SimExport, FormatRoundTripIsShortestExact) {
  for (double x : {0.1, 0.8234567890123456, 1e-300, -2.5, 1.0 / 3.0}) {
    const std::string s = FormatRoundTrip(x);
    EXPECT_EQ(std::strtod(s.c_str(), nullptr), x) << s;
  }
  EXPECT_EQ(FormatRoundTrip(0.1), "0.1");
  EXPECT_EQ(FormatRoundTrip(0.005), "0.005");
  EXPECT_EQ(FormatRoundTrip(30), "30");
  EXPECT_EQ(FormatRoundTrip(123456), "123456");
  EXPECT_EQ(FormatRoundTrip(-2.5), "-2.5");
}

}  // namespace
}  // namespace frictiond
