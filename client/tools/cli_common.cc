#include <filesystem>
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
  // A regular file of bounded size: `/dev/zero` or a 2 GB sparse file was
  // read whole (23 GB of memory before the outside attack run killed it).
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    std::cerr << "friction: " << path << ": cannot open\n";
    throw CLI::RuntimeError(2);
  }
  if (!std::filesystem::is_regular_file(status)) {
    std::cerr << "friction: " << path << ": not a regular file\n";
    throw CLI::RuntimeError(2);
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec && size > kMaxInputFileBytes) {
    std::cerr << "friction: " << path << ": " << size << " bytes (limit "
              << kMaxInputFileBytes << ")\n";
    throw CLI::RuntimeError(2);
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::cerr << "friction: " << path << ": cannot open\n";
    throw CLI::RuntimeError(2);
  }
  // Read at most one byte past the limit (the file may grow meanwhile).
  std::string text;
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    text.append(buf, static_cast<std::size_t>(in.gcount()));
    if (text.size() > kMaxInputFileBytes) {
      std::cerr << "friction: " << path << ": more than " << kMaxInputFileBytes
                << " bytes\n";
      throw CLI::RuntimeError(2);
    }
  }
  return text;
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
