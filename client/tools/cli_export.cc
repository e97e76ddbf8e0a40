// `friction export` (a material's friction in a simulator's format) and
// `friction pair` (the friction distribution of a fingertip-object pair).
#include <fstream>
#include <iostream>

#include "frictiond/client/client.h"

#include "cli.h"

namespace frictiond::cli {

namespace {

using Params = std::vector<std::pair<std::string, std::string>>;

// Adds name=value when the option was given (values go to the daemon
// verbatim; it validates them and names the field on error).
void AddIfSet(Params* p, const char* name, const std::string& value) {
  if (!value.empty()) p->emplace_back(name, value);
}

}  // namespace

void RegisterExportCommands(CLI::App& app, Globals& g) {
  {
    auto* cmd = app.add_subcommand(
        "export",
        "a material's friction for a simulator (MuJoCo MJCF, SDFormat, "
        "URDF/Gazebo, USD, Isaac Lab ranges); see docs/export.md");
    static std::string id, format, risk, fn, v, name, version, out_path;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--format", format, "mjcf, sdf, urdf, usd or isaac")
        ->required();
    cmd->add_option(
        "--risk", risk, "slip risk of the exported mu (default 0.05)");
    cmd->add_option(
        "--fn-n", fn, "operating normal force [N] (default: fitted mean)");
    cmd->add_option(
        "--v-mm-s", v, "operating speed [mm/s] (default: fitted mean)");
    cmd->add_option("--name", name, "class / link / prim name (default: ID)");
    cmd->add_option("--version", version, "model version (default: newest)");
    cmd->add_option("-o,--output", out_path, "write to FILE instead of stdout");
    cmd->callback([&g] {
      RunCommand([&] {
        Params p;
        AddIfSet(&p, "risk", risk);
        AddIfSet(&p, "fn_n", fn);
        AddIfSet(&p, "v_mm_s", v);
        AddIfSet(&p, "name", name);
        AddIfSet(&p, "version", version);
        const std::string text = MakeClient(g).ExportMaterial(id, format, p);
        if (out_path.empty()) {
          std::cout << text;
          return;
        }
        std::ofstream out(out_path, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out) {
          std::cerr << "friction: " << out_path << ": cannot write\n";
          throw CLI::RuntimeError(2);
        }
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "pair",
        "friction of a fingertip-object pair: measured, or combined by a rule");
    static std::string tip, object, fn, v, rule, risk, reference;
    cmd->add_option("FINGERTIP", tip, "fingertip material id")->required();
    cmd->add_option("OBJECT", object, "object material id")->required();
    cmd->add_option("--fn-n", fn, "operating normal force [N]");
    cmd->add_option("--v-mm-s", v, "operating speed [mm/s]");
    cmd->add_option("--rule", rule, "max, harmonic (default) or average");
    cmd->add_option("--risk", risk, "slip risk for mu_at_risk (default 0.05)");
    cmd->add_option("--reference",
                    reference,
                    "fingertip the single-material models were measured with");
    cmd->callback([&g] {
      RunCommand([&] {
        Params p;
        AddIfSet(&p, "fn_n", fn);
        AddIfSet(&p, "v_mm_s", v);
        AddIfSet(&p, "rule", rule);
        AddIfSet(&p, "risk", risk);
        AddIfSet(&p, "reference", reference);
        std::cout << MakeClient(g).FetchPairFriction(tip, object, p).dump(2)
                  << "\n";
      });
    });
  }
}

}  // namespace frictiond::cli
