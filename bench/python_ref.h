#pragma once
/// @file
/// The NumPy/SciPy reference implementations (bench/ref/*.py) that the
/// paper benchmarks run beside themselves in the same invocation: argument
/// parsing ([--python PATH]), the script's path, and running it.

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>

namespace frictiond::bench {

/// The interpreter and the reference script of one benchmark program.
struct PythonReference {
  std::string python = "/usr/bin/python3";  ///< Debian's (python3-numpy/scipy)
  std::string script;                       ///< absolute path
};

/// Parses `[--python PATH]`; the script is bench/ref/`script_name` under
/// $FRICTIOND_SOURCE_DIR (or `source_dir`). Prints the usage and returns
/// nullopt on any other argument.
inline std::optional<PythonReference> ParsePythonReference(
    int argc,
    char** argv,
    const std::string& program,
    const std::string& script_name,
    const std::string& source_dir) {
  PythonReference ref;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--python" && i + 1 < argc) {
      ref.python = argv[++i];
    } else {
      std::cerr << "usage: " << program << " [--python PATH]\n";
      return std::nullopt;
    }
  }
  const char* env_root = std::getenv("FRICTIOND_SOURCE_DIR");
  ref.script = (env_root ? std::string(env_root) : source_dir) + "/bench/ref/" +
               script_name;
  return ref;
}

/// Runs a command and returns its standard output.
/// @throws std::runtime_error when it cannot run or exits with non-zero.
inline std::string RunCommand(const std::string& cmd) {
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) throw std::runtime_error("cannot run: " + cmd);
  std::string out;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int rc = pclose(p);
  if (rc != 0)
    throw std::runtime_error("'" + cmd + "' exited with status " +
                             std::to_string(rc));
  return out;
}

}  // namespace frictiond::bench
