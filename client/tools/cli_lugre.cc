// `friction breakaway`: break-away friction ratio of a material's LuGre model
// (paper 001), answered by the daemon or, with --local, predicted here from
// the fetched model.
#include <cmath>
#include <iostream>
#include <optional>

#include "frictiond/client/client.h"
#include "frictiond/client/lugre_client.h"
#include "frictiond/estimators/breakaway.h"

#include "cli.h"

namespace frictiond::cli {

using nlohmann::json;

void RegisterLuGreCommands(CLI::App& app, Globals& g) {
  auto* cmd = app.add_subcommand(
      "breakaway",
      "break-away friction ratio at a drag-ratio rate (LuGre, paper 001)");
  static std::string id;
  static double rho = 0, fn = 0, mass = std::nan("");
  static bool local = false;
  cmd->add_option("ID", id, "material id")->required();
  cmd->add_option("--rho", rho, "drag-ratio rate d(Ft/Fn)/dt [1/s], > 0")
      ->required();
  cmd->add_option("--fn-n", fn, "normal (grasping) force [N], > 0")->required();
  cmd->add_option("--mass-kg", mass, "mass held by the contact [kg] (0.2)");
  cmd->add_flag("--local",
                local,
                "fetch the model once and predict here (no daemon "
                "simulation)");
  cmd->callback([&g] {
    try {
      FrictionClient client = MakeClient(g);
      const std::optional<double> mass_kg =
          std::isnan(mass) ? std::nullopt : std::optional<double>(mass);
      if (!local) {
        const BreakawayReply r = FetchBreakaway(client, id, rho, fn, mass_kg);
        std::cout << r.body.dump(2) << "\n";
        return;
      }
      // Validate before the request, as the daemon would.
      ForceDrivenOptions options;
      if (mass_kg) options.mass_kg = *mass_kg;
      std::string why;
      if (!(rho > 0) || !std::isfinite(rho))
        throw std::invalid_argument("--rho = " + std::to_string(rho) +
                                    " (must be finite and > 0)");
      if (!(fn > 0) || !std::isfinite(fn))
        throw std::invalid_argument("--fn-n = " + std::to_string(fn) +
                                    " (must be finite and > 0)");
      if (!options.IsValid(&why))
        throw std::invalid_argument("--mass-kg: " + why);
      const ModelSet m = client.FetchModel(id);
      const std::optional<LuGreTheta> theta = LuGreFromModel(m);
      if (!theta) {
        std::cerr << "friction: model version " << m.version << " of '" << id
                  << "' has no LuGre family (lugre): upload a "
                     "low-acceleration (<= 3 mm/s^2) and a high-acceleration "
                     "(>= 5 mm/s^2) stroke\n";
        throw CLI::RuntimeError(1);
      }
      const ForceDrivenResult p =
          PredictBreakawayRatio(*theta, rho, fn, options);
      auto finite = [](double x) {
        return std::isfinite(x) ? json(x) : json();
      };
      json out = {{"material", m.material},
                  {"fingertip", m.fingertip},
                  {"version", m.version},
                  {"bf_ratio", finite(p.bf_ratio)},
                  {"t_breakaway_s", finite(p.t_breakaway_s)},
                  {"mu_applied", finite(p.mu_applied)},
                  {"rho", rho},
                  {"fn_n", fn},
                  {"mass_kg", options.mass_kg},
                  {"status", ToString(p.status)},
                  {"steps", p.steps},
                  {"local", true}};
      if (!p.why.empty()) out["why"] = p.why;
      std::cout << out.dump(2) << "\n";
    } catch (const ClientError& e) {
      std::cerr << "friction: " << e.what() << "\n";
      if (e.body().is_object() && e.body().contains("identification")) {
        std::cerr << "identification requested; stroke to perform:\n"
                  << e.body()["identification"]["stroke"].dump(2) << "\n";
      }
      throw CLI::RuntimeError(1);
    } catch (const std::invalid_argument& e) {
      std::cerr << "friction: " << e.what() << "\n";
      throw CLI::RuntimeError(2);
    }
  });
}

}  // namespace frictiond::cli
