#include "udp_drops.h"

#include <charconv>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <dirent.h>
#include <unistd.h>

namespace frictiond::internal {

namespace {

std::string ReadProcFile(const char* path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in),
                     std::istreambuf_iterator<char>());
}

// Whitespace-separated fields of one line.
std::vector<std::string_view> Fields(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

bool ParseU64(std::string_view s, std::uint64_t* out) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), *out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// Calls f(inode, drops) for every row of a /proc/net/udp table.
template <class F>
void ForEachRow(std::string_view table, F f) {
  // Columns: sl local_address rem_address st tx_queue:rx_queue tr:tm->when
  // retrnsmt uid timeout inode ref pointer drops.
  constexpr std::size_t kInode = 9, kDrops = 12;
  bool header = true;
  while (!table.empty()) {
    const std::size_t nl = table.find('\n');
    const std::string_view line = table.substr(0, nl);
    table = nl == std::string_view::npos ? std::string_view()
                                         : table.substr(nl + 1);
    if (header) {  // the first line names the columns
      header = false;
      continue;
    }
    const std::vector<std::string_view> cols = Fields(line);
    std::uint64_t inode = 0, drops = 0;
    if (cols.size() <= kDrops || !ParseU64(cols[kInode], &inode) ||
        !ParseU64(cols[kDrops], &drops))
      continue;
    f(inode, drops);
  }
}

}  // namespace

std::set<std::uint64_t> SocketInodes() {
  std::set<std::uint64_t> out;
  DIR* dir = ::opendir("/proc/self/fd");
  if (dir == nullptr) return out;
  while (const dirent* e = ::readdir(dir)) {
    if (e->d_name[0] == '.') continue;
    char target[64] = {0};
    const std::string path = std::string("/proc/self/fd/") + e->d_name;
    const ssize_t n = ::readlink(path.c_str(), target, sizeof target - 1);
    if (n <= 0) continue;
    std::string_view t(target, static_cast<std::size_t>(n));
    // "socket:[12345]"
    constexpr std::string_view kPrefix = "socket:[";
    if (t.substr(0, kPrefix.size()) != kPrefix || t.back() != ']') continue;
    std::uint64_t inode = 0;
    if (ParseU64(t.substr(kPrefix.size(), t.size() - kPrefix.size() - 1),
                 &inode))
      out.insert(inode);
  }
  ::closedir(dir);
  return out;
}

std::uint64_t SumUdpDrops(std::string_view table,
                          const std::set<std::uint64_t>& inodes) {
  std::uint64_t sum = 0;
  ForEachRow(table, [&](std::uint64_t inode, std::uint64_t drops) {
    if (inodes.count(inode)) sum += drops;
  });
  return sum;
}

std::uint64_t ReadUdpDrops(const std::set<std::uint64_t>& inodes) {
  if (inodes.empty()) return 0;
  return SumUdpDrops(ReadProcFile("/proc/net/udp"), inodes) +
         SumUdpDrops(ReadProcFile("/proc/net/udp6"), inodes);
}

std::set<std::uint64_t> UdpSocketsAmong(const std::set<std::uint64_t>& inodes) {
  std::set<std::uint64_t> out;
  for (const char* path : {"/proc/net/udp", "/proc/net/udp6"}) {
    ForEachRow(ReadProcFile(path), [&](std::uint64_t inode, std::uint64_t) {
      if (inodes.count(inode)) out.insert(inode);
    });
  }
  return out;
}

}  // namespace frictiond::internal
