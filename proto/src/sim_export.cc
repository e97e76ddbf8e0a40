#include "frictiond/proto/sim_export.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

namespace frictiond {

namespace {

/// Levels quoted in comments (a readable subset of EpsQuantileLevels()).
const std::vector<double>& CommentLevels() {
  static const std::vector<double> kLevels = {
      0.001, 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99, 0.999};
  return kLevels;
}

void CheckInput(const SimExportInput& in) {
  if (in.name.empty() || in.name.size() > 128)
    throw std::invalid_argument("name: length " +
                                std::to_string(in.name.size()) +
                                " (must be 1..128 characters)");
  for (unsigned char c : in.name) {
    if (c < 0x20 || c >= 0x7f)
      throw std::invalid_argument(
          "name: contains a control or non-ASCII character (must be "
          "printable ASCII)");
  }
}

// Usda string literal: double quotes, with backslash and quote escaped.
std::string UsdString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

// Summary lines shared by every format's comments.
std::vector<std::string> SummaryLines(const SimExportInput& in,
                                      const SimFrictionValues& v) {
  std::vector<std::string> lines;
  lines.push_back("frictiond export: material '" + in.material +
                  "', fingertip '" + in.fingertip + "', model version " +
                  std::to_string(in.version));
  lines.push_back("operating point: fn_n = " + FormatRoundTrip(in.fn_n) +
                  " N, v_mm_s = " + FormatRoundTrip(in.v_mm_s) + " mm/s" +
                  (in.operating_point_source.empty()
                       ? std::string()
                       : " (" + in.operating_point_source + ")"));
  char stats[96];
  std::snprintf(stats,
                sizeof stats,
                "mu at the operating point: mean %.6g, sigma %.6g",
                in.mu.mean,
                in.mu.sigma);
  lines.push_back(stats);
  std::string q = "mu quantiles:";
  for (double p : CommentLevels()) {
    char buf[64];
    std::snprintf(buf, sizeof buf, " p%g=%.6g", p * 100, in.mu.Quantile(p));
    q += buf;
  }
  lines.push_back(q + " (p in percent)");
  lines.push_back("sliding mu = " + FormatRoundTrip(v.sliding) +
                  " = the mu quantile at slip risk " + FormatRoundTrip(v.risk) +
                  " (P(true mu < sliding mu) = " + FormatRoundTrip(v.risk) +
                  ")");
  if (in.mu.extrapolated) {
    std::string s = "WARNING: extrapolated beyond the fitted range of:";
    for (const auto& x : in.mu.extrapolated_inputs) s += " " + x;
    lines.push_back(s);
  }
  if (!in.note.empty()) lines.push_back(in.note);
  return lines;
}

std::string XmlHeader(const std::vector<std::string>& lines) {
  std::string out = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  for (const auto& l : lines) out += "<!-- " + XmlCommentText(l) + " -->\n";
  return out;
}

std::string FormatMjcf(const SimExportInput& in, const SimFrictionValues& v) {
  std::vector<std::string> lines = SummaryLines(in, v);
  lines.push_back("torsional " + FormatRoundTrip(kMujocoTorsionalFriction) +
                  " and rolling " + FormatRoundTrip(kMujocoRollingFriction) +
                  " are MuJoCo's defaults (not measured)");
  lines.push_back(
      "MuJoCo takes the element-wise max of two geoms' friction (equal "
      "priority): see docs/export.md");
  std::string out = XmlHeader(lines);
  out += "<mujoco model=\"" + XmlEscape("frictiond-" + in.name) + "\">\n";
  out += "  <default>\n";
  out += "    <default class=\"" + XmlEscape(in.name) + "\">\n";
  out += "      <geom friction=\"" + FormatRoundTrip(v.sliding) + " " +
         FormatRoundTrip(kMujocoTorsionalFriction) + " " +
         FormatRoundTrip(kMujocoRollingFriction) + "\"/>\n";
  out += "    </default>\n";
  out += "  </default>\n";
  out += "</mujoco>\n";
  return out;
}

std::string FormatSdf(const SimExportInput& in, const SimFrictionValues& v) {
  std::vector<std::string> lines = SummaryLines(in, v);
  lines.push_back("collision '" + in.name +
                  "': put this <surface> inside its <collision>; mu and mu2 "
                  "are the same (isotropic)");
  lines.push_back(
      "ODE/Gazebo takes the min of two surfaces' mu: see docs/export.md");
  const std::string mu = FormatRoundTrip(v.sliding);
  std::string out = XmlHeader(lines);
  out += "<surface>\n";
  out += "  <friction>\n";
  out += "    <ode>\n";
  out += "      <mu>" + mu + "</mu>\n";
  out += "      <mu2>" + mu + "</mu2>\n";
  out += "    </ode>\n";
  out += "  </friction>\n";
  out += "</surface>\n";
  return out;
}

std::string FormatUrdf(const SimExportInput& in, const SimFrictionValues& v) {
  std::vector<std::string> lines = SummaryLines(in, v);
  lines.push_back(
      "merge the <gazebo> element into your URDF; reference names the link");
  const std::string mu = FormatRoundTrip(v.sliding);
  std::string out = XmlHeader(lines);
  out += "<robot name=\"" + XmlEscape("frictiond-" + in.name) + "\">\n";
  out += "  <gazebo reference=\"" + XmlEscape(in.name) + "\">\n";
  out += "    <mu1>" + mu + "</mu1>\n";
  out += "    <mu2>" + mu + "</mu2>\n";
  out += "  </gazebo>\n";
  out += "</robot>\n";
  return out;
}

std::string NumberArray(const std::vector<double>& xs) {
  std::string out = "[";
  for (std::size_t k = 0; k < xs.size(); ++k)
    out += (k ? ", " : "") + FormatRoundTrip(xs[k]);
  return out + "]";
}

std::string FormatUsd(const SimExportInput& in, const SimFrictionValues& v) {
  const std::string prim = MakeUsdIdentifier(in.name);
  std::string doc;
  for (const auto& l : SummaryLines(in, v)) doc += l + "; ";
  doc += "static and dynamic friction are the same sliding value";
  const std::string mu = FormatRoundTrip(v.sliding);
  std::ostringstream o;
  o << "#usda 1.0\n";
  o << "(\n";
  o << "    defaultPrim = " << UsdString(prim) << "\n";
  o << "    doc = " << UsdString(doc) << "\n";
  o << ")\n\n";
  o << "def Material " << UsdString(prim) << " (\n";
  o << "    prepend apiSchemas = [\"PhysicsMaterialAPI\"]\n";
  o << ")\n{\n";
  o << "    float physics:dynamicFriction = " << mu << "\n";
  o << "    float physics:staticFriction = " << mu << "\n";
  o << "    custom string frictiond:material = " << UsdString(in.material)
    << "\n";
  o << "    custom string frictiond:fingertip = " << UsdString(in.fingertip)
    << "\n";
  o << "    custom int frictiond:modelVersion = " << in.version << "\n";
  o << "    custom double frictiond:fnN = " << FormatRoundTrip(in.fn_n) << "\n";
  o << "    custom double frictiond:vMmS = " << FormatRoundTrip(in.v_mm_s)
    << "\n";
  o << "    custom double frictiond:slipRisk = " << FormatRoundTrip(v.risk)
    << "\n";
  o << "    custom double frictiond:muMean = " << FormatRoundTrip(in.mu.mean)
    << "\n";
  o << "    custom double frictiond:muSigma = " << FormatRoundTrip(in.mu.sigma)
    << "\n";
  o << "    custom double[] frictiond:muQuantileLevels = "
    << NumberArray(in.mu.levels) << "\n";
  o << "    custom double[] frictiond:muQuantiles = "
    << NumberArray(in.mu.quantiles) << "\n";
  o << "}\n";
  return o.str();
}

std::string FormatIsaac(const SimExportInput& in, const SimFrictionValues& v) {
  using nlohmann::json;
  const json range = {v.range_low, v.range_high};
  json j = {
      {"generator", "frictiond"},
      {"name", in.name},
      {"material", in.material},
      {"fingertip", in.fingertip},
      {"version", in.version},
      {"operating_point",
       {{"fn_n", in.fn_n},
        {"v_mm_s", in.v_mm_s},
        {"source", in.operating_point_source}}},
      {"risk", v.risk},
      {"range_levels", {v.risk, 1.0 - v.risk}},
      {"static_friction_range", range},
      {"dynamic_friction_range", range},
      {"sliding_mu_at_risk", v.sliding},
      {"mu",
       {{"mean", in.mu.mean},
        {"sigma", in.mu.sigma},
        {"levels", in.mu.levels},
        {"quantiles", in.mu.quantiles}}},
      {"extrapolated", in.mu.extrapolated},
      {"extrapolated_inputs", in.mu.extrapolated_inputs},
      {"isaac_lab_event",
       {{"func", "isaaclab.envs.mdp.randomize_rigid_body_material"},
        {"mode", "startup"},
        {"params",
         {{"static_friction_range", range},
          {"dynamic_friction_range", range},
          {"restitution_range", {0.0, 0.0}},
          {"num_buckets", 64}}}}},
      {"notes",
       {"ranges are the mu quantiles at levels risk and 1 - risk of the "
        "stochastic model at the operating point",
        "static and dynamic ranges are the same: the model measures mu "
        "while sliding",
        "restitution is not measured by frictiond (0, 0 is a placeholder)",
        "PhysX averages two materials' friction by default: see "
        "docs/export.md"}}};
  if (!in.note.empty()) j["notes"].push_back(in.note);
  return j.dump(2) + "\n";
}

}  // namespace

const char* SimFormatName(SimFormat format) {
  switch (format) {
    case SimFormat::kMjcf:
      return "mjcf";
    case SimFormat::kSdf:
      return "sdf";
    case SimFormat::kUrdf:
      return "urdf";
    case SimFormat::kUsd:
      return "usd";
    case SimFormat::kIsaac:
      return "isaac";
  }
  return "?";
}

SimFormat ParseSimFormat(const std::string& name) {
  for (SimFormat f : {SimFormat::kMjcf,
                      SimFormat::kSdf,
                      SimFormat::kUrdf,
                      SimFormat::kUsd,
                      SimFormat::kIsaac}) {
    if (name == SimFormatName(f)) return f;
  }
  throw std::invalid_argument("format = '" + name.substr(0, 64) +
                              "' (must be one of mjcf, sdf, urdf, usd, isaac)");
}

const char* SimFormatContentType(SimFormat format) {
  switch (format) {
    case SimFormat::kMjcf:
    case SimFormat::kSdf:
    case SimFormat::kUrdf:
      return "application/xml; charset=utf-8";
    case SimFormat::kUsd:
      return "model/vnd.usda; charset=utf-8";
    case SimFormat::kIsaac:
      return "application/json";
  }
  return "text/plain";
}

const char* SimFormatExtension(SimFormat format) {
  switch (format) {
    case SimFormat::kMjcf:
      return "xml";
    case SimFormat::kSdf:
      return "sdf";
    case SimFormat::kUrdf:
      return "urdf";
    case SimFormat::kUsd:
      return "usda";
    case SimFormat::kIsaac:
      return "json";
  }
  return "txt";
}

std::string FormatSimExport(SimFormat format, const SimExportInput& in) {
  CheckInput(in);
  const SimFrictionValues v = CalcSimFrictionValues(in.mu, in.risk);
  switch (format) {
    case SimFormat::kMjcf:
      return FormatMjcf(in, v);
    case SimFormat::kSdf:
      return FormatSdf(in, v);
    case SimFormat::kUrdf:
      return FormatUrdf(in, v);
    case SimFormat::kUsd:
      return FormatUsd(in, v);
    case SimFormat::kIsaac:
      return FormatIsaac(in, v);
  }
  throw std::invalid_argument("format: unknown");
}

std::string XmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string XmlCommentText(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    if (c == '-' && !out.empty() && out.back() == '-') out += ' ';
    out += c;
  }
  if (!out.empty() && out.back() == '-') out += ' ';
  return out;
}

std::string MakeUsdIdentifier(const std::string& text) {
  std::string out;
  for (unsigned char c : text) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                    (c >= '0' && c <= '9') || c == '_';
    out += ok ? static_cast<char>(c) : '_';
  }
  if (out.empty() || (out[0] >= '0' && out[0] <= '9')) out.insert(0, "_");
  return out;
}

std::string FormatRoundTrip(double x) {
  char buf[40];
  // Start at the number of integer digits so 30 prints as "30", not "3e+01".
  int first = 1;
  if (std::isfinite(x) && std::fabs(x) >= 1 && std::fabs(x) < 1e15)
    first = static_cast<int>(std::floor(std::log10(std::fabs(x)))) + 1;
  for (int precision = first; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof buf, "%.*g", precision, x);
    if (std::strtod(buf, nullptr) == x) break;
  }
  return buf;
}

}  // namespace frictiond
