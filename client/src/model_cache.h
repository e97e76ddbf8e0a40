#pragma once
// The client's offline model cache (docs/offline.md): one JSON file per
// (material, fingertip) newest model and per pinned version, written
// atomically (temp file + fsync + rename + directory fsync).

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace frictiond::internal {

/// A cache entry as read back.
struct CachedEntry {
  std::string material;
  std::string fingertip;
  int version = 0;
  std::string fetched_at;
  std::string server;
  nlohmann::json model;  ///< the daemon's model JSON, verified
};

/// The cache in one directory. Not thread-safe by itself (FrictionClient is
/// thread-compatible); concurrent processes are safe: a reader sees a whole
/// old or a whole new file.
class ModelCache {
 public:
  explicit ModelCache(std::string dir) : dir_(std::move(dir)) {}

  /// Writes `model` (the daemon's JSON) for (material, fingertip): the file
  /// of its version, and the newest-model file when `latest`.
  /// @throws std::runtime_error naming the file and the system error.
  void Put(const std::string& material,
           const std::string& fingertip,
           const nlohmann::json& model,
           int version,
           bool latest,
           const std::string& fetched_at,
           const std::string& server) const;

  /// Reads the newest (version 0) or a given version. nullopt when there is
  /// no such file. @throws std::runtime_error "FILE is corrupted: why" when
  /// the file exists but cannot be trusted.
  std::optional<CachedEntry> Get(const std::string& material,
                                 const std::string& fingertip,
                                 int version) const;

  /// (material, fingertip) of every newest-model file (by file name, so a
  /// corrupted file is listed too).
  std::vector<std::pair<std::string, std::string>> ListLatest() const;

  /// File of an entry (version 0: the newest-model file).
  std::string PathOf(const std::string& material,
                     const std::string& fingertip,
                     int version) const;

  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

/// Current UTC time as "YYYY-MM-DDTHH:MM:SSZ".
std::string UtcNowIso8601();

}  // namespace frictiond::internal
