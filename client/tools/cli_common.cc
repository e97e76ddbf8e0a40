#include <fstream>
#include <iostream>
#include <sstream>

#include "frictiond/estimators/stroke_csv.h"

#include "cli.h"

namespace frictiond::cli {

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
