#include <fstream>
#include <iostream>
#include <sstream>

#include "frictiond/estimators/stroke_csv.h"

#include "cli.h"

namespace frictiond::cli {

ClientOptions MakeClientOptions(const Globals& g) {
  ClientOptions o;
  o.base_url = g.server;
  o.fingertip = g.fingertip;
  o.cache_dir = g.cache_dir;
  o.token = g.token;
  return o;
}

FrictionClient MakeClient(const Globals& g) {
  return FrictionClient(MakeClientOptions(g));
}

void RunCommand(const std::function<void()>& body) {
  try {
    body();
  } catch (const ClientError& e) {
    std::cerr << "friction: " << e.what() << "\n";
    const nlohmann::json& b = e.body();
    if (b.is_object() && b.contains("identification")) {
      std::cerr << "identification requested; stroke to perform:\n"
                << b["identification"]["stroke"].dump(2) << "\n";
    } else if (b.is_object()) {
      std::cerr << b.dump(2) << "\n";
    }
    throw CLI::RuntimeError(1);
  } catch (const std::invalid_argument& e) {
    std::cerr << "friction: " << e.what() << "\n";
    throw CLI::RuntimeError(2);
  }
}

void RequirePositive(const char* option, double value) {
  if (!(value > 0))
    throw std::invalid_argument(std::string(option) + " = " +
                                std::to_string(value) + " (must be > 0)");
}

void RequireNonNegative(const char* option, double value) {
  if (!(value >= 0))
    throw std::invalid_argument(std::string(option) + " = " +
                                std::to_string(value) + " (must be >= 0)");
}

std::string ReadFileOrFail(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::cerr << "friction: " << path << ": cannot open\n";
    throw CLI::RuntimeError(2);
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

StrokeData ReadStrokeCsvFile(const std::string& path) {
  const std::string text = ReadFileOrFail(path);
  try {
    return ParseStrokeCsv(text);
  } catch (const StrokeCsvError& e) {
    std::cerr << "friction: " << path << ": " << e.what() << "\n";
    throw CLI::RuntimeError(2);
  }
}

}  // namespace frictiond::cli
