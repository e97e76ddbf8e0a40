// Joint friction and repeatability (paper 002): `friction joint-upload`,
// `joint-friction`, `joint-fit` (local, no daemon), `robot-put` and
// `repeatability`.
#include <cmath>
#include <fstream>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/client/client.h"
#include "frictiond/client/joint_client.h"
#include "frictiond/client/joint_report.h"
#include "frictiond/estimators/joint_identification.h"
#include "frictiond/proto/joint_json.h"
#include "frictiond/proto/json_parse.h"

#include "cli.h"

namespace frictiond::cli {

using nlohmann::json;

namespace {

// "name=value" -> pair. @throws std::invalid_argument.
std::pair<std::string, std::string> SplitParam(const std::string& s) {
  const auto eq = s.find('=');
  if (eq == std::string::npos || eq == 0)
    throw std::invalid_argument("--param '" + s + "' (must be name=value)");
  return {s.substr(0, eq), s.substr(eq + 1)};
}

}  // namespace

void RegisterJointCommands(CLI::App& app, Globals& g) {
  {
    auto* cmd = app.add_subcommand(
        "joint-upload",
        "upload joint data (CSV: v_mm_s, load_n, mu, temp_c or eta_pa_s) and "
        "fit the joint family (paper 002)");
    static std::string id, file, joint = "default";
    static std::vector<std::string> params;
    cmd->add_option("ID", id, "material (pair) id")->required();
    cmd->add_option("FILE", file, "joint data CSV")->required();
    cmd->add_option("--joint", joint, "joint id (default: default)");
    cmd->add_option("--param",
                    params,
                    "joint property name=value (area_mm2, alt_um, salt_um, "
                    "summits, vogel_a_pa_s, ...), repeatable");
    cmd->callback([&g] {
      RunCommand([&] {
        std::vector<std::pair<std::string, std::string>> p;
        for (const auto& s : params) p.push_back(SplitParam(s));
        const std::string csv = ReadFileOrFail(file);
        FrictionClient client = MakeClient(g);
        std::cout << UploadJointData(client, id, joint, csv, p).dump(2) << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "joint-friction",
        "friction coefficient of a joint at speed, load and temperature");
    static std::string id, joint = "default";
    static double v = 0, load = 0, temp = 40;
    cmd->add_option("ID", id, "material (pair) id")->required();
    cmd->add_option("--joint", joint, "joint id (default: default)");
    cmd->add_option("--v-mm-s", v, "sliding speed [mm/s], > 0")->required();
    cmd->add_option("--load-n", load, "contact load [N], > 0")->required();
    cmd->add_option("--temp-c", temp, "lubricant temperature [C] (40)");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient client = MakeClient(g);
        std::cout
            << FetchJointFriction(client, id, joint, v, load, temp).body.dump(2)
            << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "joint-fit",
        "fit the mixed, Stribeck+viscous and LuGre steady-state models to a "
        "joint data CSV here (no daemon) and compare held-out errors");
    static std::string file;
    static double area = 50;
    static int folds = 5;
    cmd->add_option("FILE", file, "joint data CSV")->required();
    cmd->add_option("--area-mm2", area, "apparent contact area [mm^2] (50)");
    cmd->add_option("--folds", folds, "cross-validation folds (5)");
    cmd->callback([] {
      RunCommand([&] {
        JointConfig config;
        config.contact.area_mm2 = area;
        RequirePositive("--area-mm2", area);
        JointData data;
        try {
          data = ParseJointCsv(ReadFileOrFail(file), config.lubricant);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(file + ": " + e.what());
        }
        JointFamily f;
        f.config = config;
        f.samples = data.size();
        f.mixed = FitJointModel(JointModelKind::kMixed, data, config);
        f.stribeck =
            FitJointModel(JointModelKind::kStribeckViscous, data, config);
        f.lugre =
            FitJointModel(JointModelKind::kLuGreSteadyState, data, config);
        f.scores = CompareJointModels(data, config, folds);
        json out = JointFamilyToJson(f);
        out.erase("span");
        std::cout << out.dump(2) << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "joint-report",
        "HTML report of a joint: f(S) curve, model table and (with --robot) "
        "a repeatability field, as inline SVG");
    static std::string id, joint = "default", robot, out = "joint.html";
    static double z = 0, x0 = 0, y0 = -200, size = 400;
    static int n = 20;
    cmd->add_option("ID", id, "material (pair) id")->required();
    cmd->add_option("--joint", joint, "joint id (default: default)");
    cmd->add_option("--robot", robot, "robot id for the repeatability field");
    cmd->add_option("--z-mm", z, "plane of the field [mm] (0)");
    cmd->add_option("--x0-mm", x0, "field corner x [mm] (0)");
    cmd->add_option("--y0-mm", y0, "field corner y [mm] (-200)");
    cmd->add_option("--size-mm", size, "field edge [mm] (400, as the paper)");
    cmd->add_option("--n", n, "grid points per edge (20)");
    cmd->add_option("-o,--output", out, "HTML file to write (joint.html)");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient client = MakeClient(g);
        const ModelSet m = client.FetchModel(id, 0, joint);
        const auto family = JointFamilyFromModel(m);
        if (!family)
          throw std::invalid_argument(
              "model version " + std::to_string(m.version) + " of '" + id +
              "' joint '" + joint + "' has no joint family");
        json grid;
        if (!robot.empty()) {
          grid = client.GetJson(
              "/v1/robots/" + UrlEncode(robot) +
              "/repeatability-grid?z_mm=" + std::to_string(z) +
              "&x0_mm=" + std::to_string(x0) + "&y0_mm=" + std::to_string(y0) +
              "&size_mm=" + std::to_string(size) + "&n=" + std::to_string(n));
        }
        std::ofstream f(out, std::ios::binary);
        f << RenderJointReportHtml(id, joint, *family, grid);
        if (!f) throw std::invalid_argument(out + ": cannot write");
        std::cout << out << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "robot-put", "register a robot (JSON: DH joints, stiffness, friction)");
    static std::string id, file;
    cmd->add_option("ID", id, "robot id")->required();
    cmd->add_option("FILE", file, "robot description JSON")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        const json d = ParseJson(ReadFileOrFail(file), file.c_str());
        FrictionClient client = MakeClient(g);
        std::cout << PutRobot(client, id, d).dump(2) << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "repeatability",
        "repeatability ellipsoid of a robot at an end-effector position");
    static std::string id;
    static double x = 0, y = 0, z = 0, c = 0.95;
    cmd->add_option("ID", id, "robot id")->required();
    cmd->add_option("--x-mm", x, "target x [mm]")->required();
    cmd->add_option("--y-mm", y, "target y [mm]")->required();
    cmd->add_option("--z-mm", z, "target z [mm]")->required();
    cmd->add_option("--probability", c, "ellipsoid probability (0.95)");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient client = MakeClient(g);
        std::cout << FetchRepeatability(client, id, x, y, z, c).body.dump(2)
                  << "\n";
      });
    });
  }
}

}  // namespace frictiond::cli
