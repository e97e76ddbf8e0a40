#pragma once
/// @file
/// Files compiled into the daemon at build time (cmake/EmbedFiles.cmake):
/// the operator console's static files (server/console/*, docs/console.md).

#include <cstddef>

namespace frictiond {

/// One embedded file: its name (no directory) and bytes.
struct EmbeddedFile {
  const char* name;
  const unsigned char* data;
  std::size_t size;
};

/// The console's files; kConsoleFilesCount entries (plus a null sentinel).
extern const EmbeddedFile kConsoleFiles[];
extern const std::size_t kConsoleFilesCount;

}  // namespace frictiond
