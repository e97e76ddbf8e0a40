// Model-query subcommands of `friction` (paper 000) that ask the daemon:
// controlled sliding (eq. 3) and velocity prediction (eq. 4).
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "frictiond/client/client.h"

#include "cli.h"

namespace frictiond::cli {

namespace {}  // namespace

void RegisterModelQueryCommands(CLI::App& app, Globals& g) {
  // target-force (eq. 3)
  {
    auto* cmd = app.add_subcommand(
        "target-force",
        "tangential force to slide at a desired speed (paper 000, eq. 3)");
    static std::string id;
    static double fn = 0, v = 0;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--fn-n", fn, "normal force [N]")->required();
    cmd->add_option("--v-mm-s", v, "desired sliding speed [mm/s]")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        RequirePositive("--fn-n", fn);
        RequireNonNegative("--v-mm-s", v);
        std::cout << MakeClient(g).FetchTargetForce(id, fn, v).dump(2) << "\n";
      });
    });
  }
  // sliding-speed (eq. 4)
  {
    auto* cmd = app.add_subcommand(
        "sliding-speed",
        "sliding speed from measured forces of a slipping contact (paper "
        "000, eq. 4)");
    static std::string id;
    static double fn = 0, ft = 0;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--fn-n", fn, "measured normal force [N]")->required();
    cmd->add_option("--ft-n", ft, "measured tangential force [N]")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        RequirePositive("--fn-n", fn);
        RequireNonNegative("--ft-n", ft);
        std::cout << MakeClient(g).FetchSlidingSpeed(id, fn, ft).dump(2)
                  << "\n";
      });
    });
  }
  // conditional-slip (eq. 2)
  {
    auto* cmd = app.add_subcommand(
        "conditional-slip",
        "slip likelihood L(Fn, Ft/Fn) from Fn-windowed fits (paper 000, eq. "
        "2); says when Fn is outside the fitted windows");
    static std::string id;
    static double fn = 0, ratio = 0;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--fn-n", fn, "normal force [N]")->required();
    cmd->add_option("--ratio", ratio, "force ratio Ft/Fn")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        RequirePositive("--fn-n", fn);
        RequireNonNegative("--ratio", ratio);
        std::cout << MakeClient(g)
                         .FetchConditionalSlipLikelihood(id, fn, ratio)
                         .dump(2)
                  << "\n";
      });
    });
  }
  // forms (Table II)
  {
    auto* cmd = app.add_subcommand(
        "forms",
        "compare mu = f(Fn) forms (linear, reciprocal, a/Fn^3+b, Schallamach, "
        "Thirion, Coulomb) by held-out strokes");
    static std::string id;
    static int folds = 5;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--folds", folds, "stroke folds (2..50)")
        ->capture_default_str();
    cmd->callback([&g] {
      RunCommand([&] {
        std::cout << MakeClient(g).FetchForms(id, folds).dump(2) << "\n";
      });
    });
  }
  // mu-spread (III-B, Fig. 6)
  {
    auto* cmd = app.add_subcommand(
        "mu-spread",
        "std of mu inside Fn and v windows vs window width (paper 000, Fig. "
        "6)");
    static std::string id, fn_widths, v_widths;
    static double fn = 0, v = 0;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--fn-n", fn, "window centre Fn [N]")->required();
    cmd->add_option("--v-mm-s", v, "window centre v [mm/s]")->required();
    cmd->add_option("--fn-widths-n", fn_widths, "e.g. inf,2,1,0.5");
    cmd->add_option("--v-widths-mm-s", v_widths, "e.g. inf,40,20,10");
    cmd->callback([&g] {
      RunCommand([&] {
        std::vector<std::pair<std::string, std::string>> p;
        if (!fn_widths.empty()) p.emplace_back("fn_widths_n", fn_widths);
        if (!v_widths.empty()) p.emplace_back("v_widths_mm_s", v_widths);
        std::cout << MakeClient(g).FetchMuSpread(id, fn, v, p).dump(2) << "\n";
      });
    });
  }
  // span-variability (III-C-2, Fig. 10)
  {
    auto* cmd = app.add_subcommand(
        "span-variability",
        "spread of eq. (1) estimates vs span percentage over random stroke "
        "subsets (paper 000, Fig. 10)");
    static std::string id;
    static int subsets = 200, seed = 1;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--subsets", subsets, "random subsets (1..2000)")
        ->capture_default_str();
    cmd->add_option("--seed", seed, "random seed")->capture_default_str();
    cmd->callback([&g] {
      RunCommand([&] {
        std::cout << MakeClient(g)
                         .FetchSpanVariability(
                             id,
                             {{"subsets", std::to_string(subsets)},
                              {"seed", std::to_string(seed)}})
                         .dump(2)
                  << "\n";
      });
    });
  }
}

}  // namespace frictiond::cli
