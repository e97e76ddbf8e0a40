// Measured actuator logs (issue 20, docs/actuator.md): `friction actuator
// fit`, `simulate` and `diagnose`, all local (no daemon).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "frictiond/estimators/actuator_sim.h"
#include "frictiond/proto/actuator_json.h"
#include "frictiond/proto/actuator_report.h"
#include "frictiond/proto/json_parse.h"

#include "cli.h"

namespace frictiond::cli {

using nlohmann::json;

namespace {

std::vector<ActuatorLog> ReadLogs(const std::vector<std::string>& paths) {
  std::vector<ActuatorLog> logs;
  for (const std::string& path : paths) {
    const std::string text = ReadFileOrFail(path);
    try {
      logs.push_back(
          ParseActuatorLog(text, std::filesystem::path(path).stem().string()));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(path + ": " + e.what());
    }
  }
  return logs;
}

}  // namespace

void RegisterActuatorCommands(CLI::App& app, Globals& /*g*/) {
  auto* actuator = app.add_subcommand(
      "actuator",
      "servo + pendulum logs: identify, replay and diagnose joint friction "
      "(docs/actuator.md)");
  actuator->require_subcommand(1);
  {
    auto* cmd = actuator->add_subcommand(
        "fit", "identify motor constants and friction from logs");
    static std::vector<std::string> files;
    static std::string out, law = "auto";
    static int bootstrap = 0;
    cmd->add_option("LOG", files, "log JSON files")->required();
    cmd->add_option("--out", out, "model JSON to write")->required();
    cmd->add_option("--law",
                    law,
                    "auto (the diagnosed law: extended), coulomb_viscous, "
                    "stribeck, load_dependent, directional, m6, lugre, mixed, "
                    "extended");
    cmd->add_option("--bootstrap",
                    bootstrap,
                    "log-resampling refits for 90% intervals (default 0)");
    cmd->callback([] {
      RunCommand([&] {
        if (bootstrap < 0 || bootstrap > 1000)
          throw std::invalid_argument(
              "--bootstrap = " + std::to_string(bootstrap) +
              " (must be in [0, 1000])");
        const ActuatorFrictionLaw l = ParseActuatorFrictionLaw(
            law == "auto" ? ActuatorFrictionLawName(kAutoActuatorLaw) : law);
        const std::vector<ActuatorLog> logs = ReadLogs(files);
        ActuatorFitOptions options;
        options.bootstrap = bootstrap;
        const ActuatorFitResult r = FitActuatorLaw(logs, l, options);
        json j = ActuatorFitToJson(r);
        std::ofstream f(out);
        if (!f) throw std::invalid_argument("--out " + out + ": cannot write");
        f << j.dump(2) << "\n";
        if (!f) throw std::invalid_argument("--out " + out + ": write failed");
        std::cout << json{{"law", ActuatorFrictionLawName(l)},
                          {"mae_rad", r.mae_rad},
                          {"logs", logs.size()},
                          {"converged", r.converged},
                          {"out", out}}
                         .dump()
                  << "\n";
      });
    });
  }
  {
    auto* cmd = actuator->add_subcommand(
        "simulate", "closed-loop rollout of a model on a log");
    static std::string file, model_file, bam_file;
    static bool as_json = false;
    cmd->add_option("LOG", file, "log JSON file")->required();
    auto* m = cmd->add_option("--model", model_file, "model JSON (fit --out)");
    auto* b = cmd->add_option("--params-bam",
                              bam_file,
                              "a BAM parameter file (m1/m2/m6.json) instead");
    m->excludes(b);
    cmd->add_flag("--json", as_json, "print one JSON object");
    cmd->callback([] {
      RunCommand([&] {
        if (model_file.empty() && bam_file.empty())
          throw std::invalid_argument("give --model FILE or --params-bam FILE");
        ActuatorModel model;
        try {
          if (!bam_file.empty()) {
            model = ParseBamParams(ReadFileOrFail(bam_file));
          } else {
            const std::string text = ReadFileOrFail(model_file);
            const json j = ParseJson(text, "model");
            model = ActuatorModelFromJson(j.contains("model") ? j["model"] : j);
          }
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(
              (bam_file.empty() ? model_file : bam_file) + ": " + e.what());
        }
        const std::vector<ActuatorLog> logs = ReadLogs({file});
        const double mae = SimulateActuatorLog(model, logs[0]);
        const json j = {{"mae_rad", mae},
                        {"samples", logs[0].size()},
                        {"law", ActuatorFrictionLawName(model.law)}};
        if (as_json)
          std::cout << j.dump() << "\n";
        else
          std::cout << "mae " << mae << " rad over " << logs[0].size()
                    << " samples (law " << ActuatorFrictionLawName(model.law)
                    << ")\n";
      });
    });
  }
  {
    auto* cmd = actuator->add_subcommand(
        "diagnose",
        "where and why the Coulomb-viscous simulation departs from the logs");
    static std::vector<std::string> files;
    static bool as_json = false;
    cmd->add_option("LOG", files, "log JSON files")->required();
    cmd->add_flag("--json", as_json, "print the findings as JSON");
    cmd->callback([] {
      RunCommand([&] {
        const std::vector<ActuatorLog> logs = ReadLogs(files);
        const json j = DiagnoseActuatorLogs(logs);
        if (as_json) {
          std::cout << j.dump() << "\n";
        } else {
          for (const json& f : j.at("findings"))
            std::cout << "- " << f.value("summary", "") << "\n";
        }
      });
    });
  }
  {
    auto* cmd = actuator->add_subcommand(
        "compare",
        "held-out MAE per log: our Coulomb-viscous and extended fits "
        "(leave-one-log-out and leave-one-trajectory-out) beside BAM's "
        "published parameter files replayed in our simulator");
    static std::vector<std::string> files, bam_files;
    static int budget = 600;
    cmd->add_option("LOG", files, "log JSON files")->required();
    cmd->add_option("--params-bam", bam_files, "BAM parameter files");
    cmd->add_option("--fold-budget",
                    budget,
                    "Nelder-Mead evaluations per held-out fold (default 600)");
    cmd->callback([] {
      RunCommand([&] {
        if (budget < 10 || budget > 100000)
          throw std::invalid_argument(
              "--fold-budget = " + std::to_string(budget) +
              " (must be in [10, 100000])");
        const std::vector<ActuatorLog> logs = ReadLogs(files);
        std::vector<const ActuatorLog*> all;
        for (const ActuatorLog& l : logs) all.push_back(&l);
        std::vector<int> loo(logs.size()), shape(logs.size());
        std::vector<std::string> shapes;
        for (std::size_t i = 0; i < logs.size(); ++i) {
          loo[i] = static_cast<int>(i);
          auto it = std::find(shapes.begin(), shapes.end(), logs[i].trajectory);
          if (it == shapes.end()) {
            shapes.push_back(logs[i].trajectory);
            it = shapes.end() - 1;
          }
          shape[i] = static_cast<int>(it - shapes.begin());
        }
        ActuatorFitOptions full;
        ActuatorFitOptions fold;
        fold.nm_max_evaluations = budget;
        fold.nm_restarts = 0;
        fold.lm_iterations = 2;
        json rows = json::array();
        json columns = json::object();
        auto add_column = [&](const std::string& name,
                              const std::vector<double>& v) {
          columns[name] = v;
        };
        const std::vector<ActuatorVariant> variants = {
            LawVariant(ActuatorFrictionLaw::kCoulombViscous),
            AutoActuatorVariant()};
        json in_sample = json::object();
        for (const ActuatorVariant& v : variants) {
          const ActuatorFitResult f = FitActuatorVariant(all, v, full);
          in_sample[v.name] = f.mae_rad;
          add_column(v.name + " loo",
                     CalcHeldOutMae(logs, v, loo, fold, &f.model));
          add_column(v.name + " lso",
                     CalcHeldOutMae(logs, v, shape, fold, &f.model));
        }
        for (const std::string& b : bam_files) {
          const ActuatorModel m = ParseBamParams(ReadFileOrFail(b));
          std::vector<double> v;
          for (const ActuatorLog& l : logs)
            v.push_back(SimulateActuatorLog(m, l));
          add_column("bam " + std::filesystem::path(b).stem().string(), v);
        }
        for (std::size_t i = 0; i < logs.size(); ++i) {
          json r = {{"log", logs[i].name}};
          for (auto& [k, v] : columns.items()) r[k] = v[i];
          rows.push_back(r);
        }
        json mean = json::object();
        for (auto& [k, v] : columns.items()) {
          double s = 0;
          for (const json& x : v) s += x.get<double>();
          mean[k] = s / static_cast<double>(v.size());
        }
        std::cout << json{{"rows", rows},
                          {"mean", mean},
                          {"in_sample", in_sample}}
                         .dump(1)
                  << "\n";
      });
    });
  }
}

}  // namespace frictiond::cli
