// friction: command line client of frictiond (and offline fitting tools).
#include <cstdlib>
#include <iostream>

#include "cli.h"

int main(int argc, char** argv) {
  CLI::App app{"friction: friction material library client (frictiond)"};
  app.require_subcommand(1);
  frictiond::cli::Globals g;
  if (const char* env = std::getenv("FRICTIOND_SERVER")) g.server = env;
  app.add_option("--server", g.server, "daemon base URL")
      ->capture_default_str();
  app.add_option("--fingertip", g.fingertip, "fingertip id")
      ->capture_default_str();
  if (const char* env = std::getenv("FRICTIOND_CACHE_DIR")) g.cache_dir = env;
  app.add_option("--cache-dir",
                 g.cache_dir,
                 "offline model cache: fetched models are kept there and "
                 "served (stale) when no daemon answers (env "
                 "FRICTIOND_CACHE_DIR)");
  if (const char* env = std::getenv("FRICTIOND_TOKEN")) g.token = env;
  app.add_option("--token",
                 g.token,
                 "API token secret sent as bearer token (env FRICTIOND_TOKEN; "
                 "see docs/auth.md)");
  frictiond::cli::RegisterCoreCommands(app, g);
  frictiond::cli::RegisterDiagnoseCommand(app, g);
  frictiond::cli::RegisterReportCommand(app, g);
  frictiond::cli::RegisterLuGreCommands(app, g);
  frictiond::cli::RegisterExportCommands(app, g);
  frictiond::cli::RegisterJointCommands(app, g);
  frictiond::cli::RegisterModelQueryCommands(app, g);
  frictiond::cli::RegisterTokenCommands(app, g);
  frictiond::cli::RegisterActuatorCommands(app, g);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "friction: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
