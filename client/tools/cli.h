#pragma once
/// @file
/// The `friction` command line: each cli_<name>.cc registers its
/// subcommands. A command reports failure by printing to stderr and throwing
/// CLI::RuntimeError(exit_code).

#include <cstdint>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>

#include "frictiond/client/client.h"
#include "frictiond/estimators/stroke_data.h"

namespace frictiond::cli {

/// Options shared by all subcommands.
struct Globals {
  std::string server = "http://127.0.0.1:8080";  ///< daemon base URL (--server,
                                                 ///< env FRICTIOND_SERVER)
  std::string fingertip = "default";             ///< fingertip id (--fingertip)
  std::string cache_dir;  ///< offline model cache (--cache-dir, env
                          ///< FRICTIOND_CACHE_DIR); "" = none
  std::string token;      ///< API token secret (--token, env FRICTIOND_TOKEN)
};

/// Reads and parses a stroke CSV file.
/// @throws CLI::RuntimeError(2) after printing "FILE: line N: ..." to stderr.
StrokeData ReadStrokeCsvFile(const std::string& path);
/// The client options every command starts from: server, fingertip, cache
/// directory and token of the global flags (one place, so that no command
/// forgets the token).
ClientOptions MakeClientOptions(const Globals& g);
/// A client for the daemon and fingertip the global options name.
FrictionClient MakeClient(const Globals& g);
/// Runs a command body. A ClientError prints the daemon's message (with the
/// stroke to perform when the daemon requested an identification, else the
/// error body, which names the field) and exits 1; std::invalid_argument (a
/// bad argument caught before asking the daemon) prints why and exits 2.
void RunCommand(const std::function<void()>& body);
/// Largest input file a command reads [bytes] (256 MiB).
inline constexpr std::uintmax_t kMaxInputFileBytes = 256u << 20;
/// Reads a whole regular file of at most kMaxInputFileBytes.
/// @throws CLI::RuntimeError(2) after printing why (missing, not a regular
/// file, too large).
std::string ReadFileOrFail(const std::string& path);
/// Checks a numeric option inside RunCommand: throws std::invalid_argument
/// "OPTION = VALUE (must be > 0)" (or ">= 0" when zero is allowed), which
/// RunCommand turns into exit code 2.
void RequirePositive(const char* option, double value);
void RequireNonNegative(const char* option, double value);

void RegisterCoreCommands(
    CLI::App& app,
    Globals& g);  // cli_core.cc: materials, show, upload, predict, fit, ...
void RegisterDiagnoseCommand(CLI::App& app,
                             Globals& g);  // cli_diagnose.cc: diagnose
void RegisterReportCommand(CLI::App& app, Globals& g);  // cli_report.cc: report
void RegisterLuGreCommands(CLI::App& app, Globals& g);  // cli_lugre.cc
void RegisterExportCommands(CLI::App& app,
                            Globals& g);  // cli_export.cc: export, pair
void RegisterJointCommands(CLI::App& app, Globals& g);  // cli_joint.cc
void RegisterActuatorCommands(CLI::App& app,
                              Globals& g);  // cli_actuator.cc: actuator
void RegisterTokenCommands(CLI::App& app,
                           Globals& g);  // cli_token.cc: token, audit
void RegisterModelQueryCommands(
    CLI::App& app,
    Globals& g);  // cli_model_queries.cc: target-force, sliding-speed, ...

}  // namespace frictiond::cli
