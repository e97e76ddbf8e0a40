#include "model_cache.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fcntl.h>
#include <unistd.h>

#include "frictiond/proto/json_parse.h"
#include "frictiond/proto/model_json.h"

namespace frictiond::internal {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kFormat = "frictiond-model-cache/1";
constexpr const char* kLatest = ".latest.json";

// File-name-safe encoding: [A-Za-z0-9_-] kept, every other byte %XX.
std::string EncodeName(const std::string& s) {
  static const char* kHex = "0123456789ABCDEF";
  std::string out;
  for (unsigned char c : s) {
    if (std::isalnum(c) || c == '-' || c == '_') {
      out += static_cast<char>(c);
    } else {
      out += '%';
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  return out;
}

std::optional<std::string> DecodeName(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '%') {
      out += s[i];
      continue;
    }
    if (i + 2 >= s.size()) return std::nullopt;
    unsigned v = 0;
    if (std::sscanf(s.substr(i + 1, 2).c_str(), "%2X", &v) != 1)
      return std::nullopt;
    out += static_cast<char>(v);
    i += 2;
  }
  return out;
}

// 64-bit FNV-1a (detects torn or flipped bytes; not a security measure).
std::string Fnv1a64Hex(const std::string& s) {
  std::uint64_t h = 14695981039346656037ull;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

std::string SysError(const std::string& what, const std::string& path) {
  return what + " " + path + ": " + std::strerror(errno);
}

void WriteAtomically(const std::string& path, const std::string& text) {
  static unsigned counter = 0;
  const std::string tmp = path + ".tmp." + std::to_string(::getpid()) + "." +
                          std::to_string(++counter);
  const int fd =
      ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) throw std::runtime_error(SysError("cannot create", tmp));
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = SysError("cannot write", tmp);
      ::close(fd);
      ::unlink(tmp.c_str());
      throw std::runtime_error(why);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const std::string why = SysError("cannot fsync", tmp);
    ::close(fd);
    ::unlink(tmp.c_str());
    throw std::runtime_error(why);
  }
  ::close(fd);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = SysError("cannot rename to", path);
    ::unlink(tmp.c_str());
    throw std::runtime_error(why);
  }
  // The rename itself must reach the disk.
  const std::string dir = fs::path(path).parent_path().string();
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

}  // namespace

std::string UtcNowIso8601() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string ModelCache::PathOf(const std::string& material,
                               const std::string& fingertip,
                               int version) const {
  const std::string base =
      (fs::path(dir_) / (EncodeName(material) + "@" + EncodeName(fingertip)))
          .string();
  return version > 0 ? base + ".v" + std::to_string(version) + ".json"
                     : base + kLatest;
}

void ModelCache::Put(const std::string& material,
                     const std::string& fingertip,
                     const json& model,
                     int version,
                     bool latest,
                     const std::string& fetched_at,
                     const std::string& server) const {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec)
    throw std::runtime_error("cannot create the cache directory " + dir_ +
                             ": " + ec.message());
  const std::string model_text = model.dump();
  const json doc = {{"format", kFormat},
                    {"material", material},
                    {"fingertip", fingertip},
                    {"version", version},
                    {"fetched_at", fetched_at},
                    {"server", server},
                    {"model_fnv1a64", Fnv1a64Hex(model_text)},
                    {"model", model}};
  const std::string text = doc.dump(1) + "\n";
  WriteAtomically(PathOf(material, fingertip, version), text);
  if (latest) WriteAtomically(PathOf(material, fingertip, 0), text);
}

std::optional<CachedEntry> ModelCache::Get(const std::string& material,
                                           const std::string& fingertip,
                                           int version) const {
  const std::string path = PathOf(material, fingertip, version);
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream ss;
  ss << in.rdbuf();
  auto corrupted = [&](const std::string& why) {
    return std::runtime_error("the cached model " + path + " is corrupted (" +
                              why + ")");
  };
  const json doc = ParseJsonOrDiscarded(ss.str());
  if (doc.is_discarded()) throw corrupted("not valid JSON");
  if (!doc.is_object() || doc.value("format", "") != kFormat)
    throw corrupted(std::string("format is not ") + kFormat);
  for (const char* key :
       {"material", "fingertip", "fetched_at", "server", "model_fnv1a64"}) {
    if (!doc.contains(key) || !doc[key].is_string())
      throw corrupted(std::string(key) + " missing or not a string");
  }
  if (!doc.contains("version") || !doc["version"].is_number_integer() ||
      doc["version"].get<int>() < 1)
    throw corrupted("version missing or not a positive integer");
  if (!doc.contains("model") || !doc["model"].is_object())
    throw corrupted("model missing");
  if (Fnv1a64Hex(doc["model"].dump()) != doc["model_fnv1a64"])
    throw corrupted("model checksum mismatch");
  CachedEntry e;
  e.material = doc["material"];
  e.fingertip = doc["fingertip"];
  e.version = doc["version"];
  e.fetched_at = doc["fetched_at"];
  e.server = doc["server"];
  e.model = doc["model"];
  if (e.material != material || e.fingertip != fingertip)
    throw corrupted("it holds " + e.material + "/" + e.fingertip);
  if (version > 0 && e.version != version)
    throw corrupted("it holds version " + std::to_string(e.version));
  int model_version = 0;
  try {
    model_version = ModelSetFromJson(e.model).version;
  } catch (const std::exception& ex) {
    throw corrupted(std::string("model unreadable: ") + ex.what());
  }
  if (model_version != e.version)
    throw corrupted("model version " + std::to_string(model_version) +
                    " differs from the entry's " + std::to_string(e.version));
  return e;
}

std::vector<std::pair<std::string, std::string>> ModelCache::ListLatest()
    const {
  std::vector<std::pair<std::string, std::string>> out;
  std::error_code ec;
  for (fs::directory_iterator it(dir_, ec), end; !ec && it != end;
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const std::size_t n = std::strlen(kLatest);
    if (name.size() <= n || name.compare(name.size() - n, n, kLatest) != 0)
      continue;
    const std::string stem = name.substr(0, name.size() - n);
    const std::size_t at = stem.find('@');
    if (at == std::string::npos) continue;
    auto material = DecodeName(stem.substr(0, at));
    auto fingertip = DecodeName(stem.substr(at + 1));
    if (material && fingertip) out.emplace_back(*material, *fingertip);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace frictiond::internal
