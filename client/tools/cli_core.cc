// Core subcommands of `friction`: library lookups through the daemon, local
// model evaluation, and offline fitting.
#include <cstdio>
#include <iostream>
#include <limits>

#include "frictiond/client/client.h"
#include "frictiond/estimators/grip_force.h"
#include "frictiond/estimators/mu_admissibility.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/proto/model_json.h"

#include "cli.h"

namespace frictiond::cli {

using nlohmann::json;

namespace {

void PrintModelSummary(const ModelSet& m) {
  std::printf("material %s  fingertip %s  version %d  (%s)\n",
              m.material.c_str(),
              m.fingertip.c_str(),
              m.version,
              m.created_at.c_str());
  if (!m.stochastic) {
    std::printf("  no stochastic model\n");
    return;
  }
  const StochasticFrictionModel& s = *m.stochastic;
  std::printf("  mu = ");
  for (std::size_t k = 0; k < s.mu.terms.size(); ++k) {
    std::printf("%s%+.5g%s%s",
                k ? " " : "",
                s.mu.beta(k),
                s.mu.terms[k].kind == TermKind::kIntercept ? "" : "*",
                s.mu.terms[k].kind == TermKind::kIntercept
                    ? ""
                    : s.mu.terms[k].Name().c_str());
  }
  std::printf(
      " + eps\n  sigma_eps %.4g  R2 %.3f  samples %d (slip) of %d  strokes "
      "%d\n",
      s.mu.sigma_eps,
      s.mu.r2,
      s.samples_slip,
      s.samples_total,
      s.strokes);
  std::printf("  MAE %.4g vs Coulomb (mu %.4g) %.4g\n",
              s.mu.mae,
              s.mu_coulomb,
              s.mae_coulomb);
  for (const auto& u : s.mu.unidentified)
    std::printf("  not identified (no span): %s\n", u.c_str());
  if (s.likelihood.valid) {
    std::printf(
        "  slip likelihood L = 1/(1+exp(-%.4g (Ft/Fn - %.4g)))  never < %.3f, "
        "always > %.3f\n",
        s.likelihood.c1,
        s.likelihood.c2,
        s.likelihood.ratio_never,
        s.likelihood.ratio_always);
  } else {
    std::printf("  slip likelihood from the eps distribution (%s)\n",
                s.likelihood.why.c_str());
  }
}

void AddLabellingOptions(CLI::App* cmd, double* peak, double* floor) {
  cmd->add_option(
      "--slip-peak-mm-s", *peak, "slip episode peak speed threshold [mm/s]");
  cmd->add_option("--slip-floor-mm-s",
                  *floor,
                  "slip episode neighbour speed threshold [mm/s]");
}

}  // namespace

void RegisterCoreCommands(CLI::App& app, Globals& g) {
  // materials
  {
    auto* cmd = app.add_subcommand("materials", "list the library's materials");
    static bool as_json = false;
    cmd->add_flag("--json", as_json, "print JSON");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient c = MakeClient(g);
        if (as_json) {
          std::cout << c.GetJson("/v1/materials").dump(2) << "\n";
          return;
        }
        for (const MaterialInfo& m : c.ListMaterials()) {
          std::printf("%-24s v%-4s %s\n",
                      m.id.c_str(),
                      m.latest_version
                          ? std::to_string(*m.latest_version).c_str()
                          : "-",
                      m.name.c_str());
        }
      });
    });
  }
  // show
  {
    auto* cmd = app.add_subcommand(
        "show",
        "show a material's newest (or a given) model (alias: model); with "
        "--cache-dir served from the cache, with a warning, when no daemon "
        "answers");
    cmd->alias("model");
    static std::string id;
    static int version = 0;
    static bool as_json = false;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--version", version, "model version (default: newest)");
    cmd->add_flag("--json", as_json, "print the model JSON");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient c = MakeClient(g);
        const FetchResult r = c.FetchModelWithInfo(id, version);
        const ModelSet& m = r.model;
        if (r.info.stale) {
          std::cerr << "friction: warning: STALE model from the cache "
                    << g.cache_dir << " (version " << r.info.version
                    << ", fetched " << r.info.fetched_at << " from "
                    << r.info.server
                    << "): no daemon answered: " << r.info.daemon_error << "\n";
        }
        if (!r.info.cache_error.empty())
          std::cerr << "friction: warning: cache not updated: "
                    << r.info.cache_error << "\n";
        if (as_json) {
          std::cout << ModelSetToJson(m).dump(2) << "\n";
        } else {
          PrintModelSummary(m);
        }
      });
    });
  }
  // resync
  {
    auto* cmd = app.add_subcommand(
        "resync",
        "refresh every model in the offline cache (--cache-dir) from the "
        "daemon");
    cmd->callback([&g] {
      RunCommand([&] {
        if (g.cache_dir.empty())
          throw std::invalid_argument(
              "resync: no cache (give --cache-dir or FRICTIOND_CACHE_DIR)");
        FrictionClient c = MakeClient(g);
        int failed = 0;
        for (const ResyncEntry& e : c.Resync()) {
          if (e.error.empty()) {
            std::printf("%-24s %-12s v%d -> v%d\n",
                        e.material.c_str(),
                        e.fingertip.c_str(),
                        e.cached_version,
                        e.version);
          } else {
            ++failed;
            std::printf("%-24s %-12s not refreshed: %s\n",
                        e.material.c_str(),
                        e.fingertip.c_str(),
                        e.error.c_str());
          }
        }
        if (failed > 0) throw CLI::RuntimeError(1);
      });
    });
  }
  // upload
  {
    auto* cmd = app.add_subcommand(
        "upload",
        "upload a stroke CSV; the daemon refits and stores a new version");
    static std::string id, file, robot;
    static double peak = std::numeric_limits<double>::quiet_NaN(),
                  floor = std::numeric_limits<double>::quiet_NaN();
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("FILE", file, "stroke CSV")->required();
    cmd->add_option("--robot", robot, "source robot id");
    AddLabellingOptions(cmd, &peak, &floor);
    cmd->callback([&g] {
      const std::string csv = ReadFileOrFail(file);
      RunCommand([&] {
        ClientOptions o = MakeClientOptions(g);  // the token included
        o.robot = robot;
        o.timeout_s = 60;
        FrictionClient c(o);
        std::vector<std::pair<std::string, std::string>> params;
        if (std::isfinite(peak))
          params.emplace_back("slip_peak_mm_s", std::to_string(peak));
        if (std::isfinite(floor))
          params.emplace_back("slip_floor_mm_s", std::to_string(floor));
        const UploadReply r = c.UploadStrokes(id, csv, params);
        std::cout << r.body.dump(2) << "\n";
      });
    });
  }
  // predict (local evaluation of the fetched model)
  {
    auto* cmd = app.add_subcommand(
        "predict",
        "predict mu at (Fn, v): fetches the model once, evaluates locally");
    static std::string id;
    static double fn = 0, v = 0;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--fn-n", fn, "normal force [N]")->required();
    cmd->add_option("--v-mm-s", v, "sliding speed [mm/s]")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        RequirePositive("--fn-n", fn);
        RequireNonNegative("--v-mm-s", v);
        FrictionClient c = MakeClient(g);
        const ModelSet m = c.FetchModel(id);
        if (!m.stochastic)
          throw ClientError(200, "model has no stochastic family");
        MuPrediction p = PredictMu(*m.stochastic, fn, v);
        // The daemon's rule (mu_admissibility.h): no mean mu below 0, the
        // interval floored at 0.
        const MeanMuCheck check =
            CheckServableMu(*m.stochastic, {{"fn_n", fn}, {"v_mm_s", v}}, p);
        if (!check.admissible) throw ClientError(422, check.why);
        const bool floored = FloorAtZero(&p);
        json out = {{"material", id},
                    {"version", m.version},
                    {"mu", p.mu},
                    {"sigma", p.sigma},
                    {"interval95", {p.lo95, p.hi95}},
                    {"floored_at_zero", floored},
                    {"extrapolated", p.extrapolated},
                    {"extrapolated_inputs", p.extrapolated_inputs}};
        std::cout << out.dump(2) << "\n";
      });
    });
  }
  // slip
  {
    auto* cmd = app.add_subcommand(
        "slip", "likelihood of slip at (Fn, Ft), evaluated locally");
    static std::string id;
    static double fn = 0, ft = 0;
    static GripForceOptions state;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--fn-n", fn, "normal force [N]")->required();
    cmd->add_option("--ft-n", ft, "tangential force [N]")->required();
    auto* v_opt = cmd->add_option(
        "--v-mm-s",
        state.v_mm_s,
        "sliding speed of the grasp [mm/s]: with it (or --hold-s) the "
        "answer is P(any slip during the hold) by eq. (1), the forward "
        "model of 'grip' (default 0 then)");
    auto* hold_opt = cmd->add_option(
        "--hold-s", state.hold_s, "hold duration [s], as 'grip' takes it");
    cmd->callback([&g, v_opt, hold_opt] {
      RunCommand([&] {
        RequirePositive("--fn-n", fn);
        RequireNonNegative("--ft-n", ft);
        const bool at_state = v_opt->count() > 0 || hold_opt->count() > 0;
        std::string why;
        if (at_state && !state.IsValid(&why)) throw ClientError(400, why);
        FrictionClient c = MakeClient(g);
        const ModelSet m = c.FetchModel(id);
        if (!m.stochastic)
          throw ClientError(200, "model has no stochastic family");
        json out{{"material", id}, {"version", m.version}, {"ratio", ft / fn}};
        if (at_state) {
          // The daemon's slip-likelihood at a grasp state: one rule
          // (mu_admissibility.h, CalcServedHoldSlip).
          ServedHoldSlip s;
          try {
            s = CalcServedHoldSlip(*m.stochastic, fn, ft, state);
          } catch (const std::invalid_argument& e) {
            throw ClientError(422, e.what());
          }
          if (!s.check.admissible) throw ClientError(422, s.check.why);
          out["likelihood"] = s.probability;
          out["method"] = "eq1_hold";
          out["v_mm_s"] = state.v_mm_s;
          out["hold_s"] = state.hold_s;
        } else {
          out["likelihood"] = CalcSlipLikelihood(*m.stochastic, fn, ft);
        }
        std::cout << out.dump(2) << "\n";
      });
    });
  }
  // grip
  {
    auto* cmd = app.add_subcommand(
        "grip", "grip force holding a load at a slip risk (paper 000, IV-A)");
    static std::string id;
    static double load = 0, risk = 0.001, hold_s = 0, v_mm_s = 0;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--hold-s",
                    hold_s,
                    "seconds the grasp is held; risk is the probability of "
                    "any slip during the hold (default 0: one instant)");
    cmd->add_option("--v-mm-s",
                    v_mm_s,
                    "sliding speed of the grasp [mm/s] (default 0: at rest)");
    cmd->add_option("--load-n", load, "tangential load to hold [N]")
        ->required();
    cmd->add_option(
        "--risk",
        risk,
        "acceptable slip probability, e.g. 0.001 (coffee) or 0.05 (shirt)");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient c = MakeClient(g);
        const ModelSet m = c.FetchModel(id);
        if (!m.stochastic)
          throw ClientError(200, "model has no stochastic family");
        GripForceOptions options;
        options.hold_s = hold_s;
        options.v_mm_s = v_mm_s;
        const GripForce gf = CalcGripForce(*m.stochastic, load, risk, options);
        if (gf.status == GripForceStatus::kUnsupportedRisk)
          throw ClientError(422,
                            gf.why,
                            json{{"error", "risk below what the data support"},
                                 {"detail", gf.why},
                                 {"field", "risk"},
                                 {"min_supported_risk", gf.min_supported_risk},
                                 {"hold_s", hold_s}});
        if (!gf.attainable)
          throw ClientError(422, "no grip force holds the load: " + gf.why);
        const double half = 1.959963984540054 * gf.fn_n_sd;
        std::cout << json{{"material", id},
                          {"version", m.version},
                          {"fn_n", gf.fn_n},
                          {"fn_n_sd", gf.fn_n_sd},
                          {"fn_n_interval95", {gf.fn_n - half, gf.fn_n + half}},
                          {"mu_used", gf.mu_used},
                          {"load_n", load},
                          {"risk", risk},
                          {"hold_s", hold_s},
                          {"v_mm_s", v_mm_s},
                          {"instant_risk", gf.instant_risk},
                          {"hold_samples", gf.hold_samples},
                          {"min_supported_risk", gf.min_supported_risk},
                          {"extrapolated", gf.extrapolated}}
                         .dump(2)
                  << "\n";
      });
    });
  }
  // versions
  {
    auto* cmd =
        app.add_subcommand("versions", "list a material's model versions");
    static std::string id;
    cmd->add_option("ID", id, "material id")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient c = MakeClient(g);
        std::cout << c.GetJson("/v1/materials/" + UrlEncode(id) +
                               "/models?fingertip=" + UrlEncode(g.fingertip))
                         .dump(2)
                  << "\n";
      });
    });
  }
  // put / delete
  {
    auto* cmd = app.add_subcommand("put", "create or update a material");
    static std::string id, name, description;
    static std::vector<std::string> tags;
    cmd->add_option("ID", id, "material id")->required();
    cmd->add_option("--name", name, "display name");
    cmd->add_option("--description", description, "description");
    cmd->add_option("--tag", tags, "tag (repeatable)");
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient c = MakeClient(g);
        json body = json::object();
        if (!name.empty()) body["name"] = name;
        if (!description.empty()) body["description"] = description;
        if (!tags.empty()) body["tags"] = tags;
        std::cout << c.SendJson(
                          "PUT", "/v1/materials/" + UrlEncode(id), body.dump())
                         .dump(2)
                  << "\n";
      });
    });
  }
  {
    auto* cmd = app.add_subcommand(
        "delete", "delete a material with its strokes and models");
    static std::string id;
    cmd->add_option("ID", id, "material id")->required();
    cmd->callback([&g] {
      RunCommand([&] {
        FrictionClient c = MakeClient(g);
        std::cout << c.SendJson("DELETE", "/v1/materials/" + UrlEncode(id), "")
                         .dump(2)
                  << "\n";
      });
    });
  }
  // fit (offline)
  {
    auto* cmd = app.add_subcommand(
        "fit",
        "fit the stochastic model to stroke CSV files offline (no daemon)");
    static std::vector<std::string> files;
    static bool as_json = false;
    static double peak = std::numeric_limits<double>::quiet_NaN(),
                  floor = std::numeric_limits<double>::quiet_NaN();
    cmd->add_option("FILE", files, "stroke CSV file(s)")->required();
    cmd->add_flag("--json", as_json, "print the model JSON");
    AddLabellingOptions(cmd, &peak, &floor);
    cmd->callback([] {
      StrokeData all;
      StochasticFitOptions options;
      if (std::isfinite(peak)) options.labelling.peak_mm_s = peak;
      if (std::isfinite(floor)) options.labelling.floor_mm_s = floor;
      std::string why;
      if (!options.IsValid(&why)) {
        std::cerr << "friction: " << why << "\n";
        throw CLI::RuntimeError(2);
      }
      for (const auto& f : files) {
        StrokeData d = ReadStrokeCsvFile(f);
        EnsureLabels(&d, options.labelling);
        all.Append(d);
      }
      const StochasticFit fit = FitStochasticModel(all, options);
      if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial) {
        std::cerr << "friction: no model: " << fit.why << "\n";
        throw CLI::RuntimeError(1);
      }
      ModelSet set;
      set.material = files.size() == 1 ? files[0] : "offline";
      set.stochastic = fit.model;
      if (as_json) {
        std::cout << ModelSetToJson(set).dump(2) << "\n";
      } else {
        PrintModelSummary(set);
        if (!fit.why.empty()) std::printf("  note: %s\n", fit.why.c_str());
      }
    });
  }
}

}  // namespace frictiond::cli
