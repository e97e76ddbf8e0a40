#pragma once
/// @file
/// Datagrams the kernel dropped on some of this process's UDP sockets
/// (receive buffer full): the `drops` column of /proc/net/udp and
/// /proc/net/udp6 (Linux), for sockets identified by their inodes.
///
/// Why: LCM's udpm provider owns its receive socket and does not expose it
/// (lcm_get_fileno gives a notification pipe), so a flood that overflows the
/// socket's buffer lost messages without a trace. The LCM endpoint notes the
/// sockets the provider opened (the inodes that appear while it is created,
/// SocketInodes before and after) and counts their drops in
/// frictiond_lcm_dropped_total{reason="receive_buffer_full"}. A UDP socket
/// another thread opens during that window is counted too while it stays
/// open (the daemon opens none; two endpoints built at once in one process,
/// as no caller does, would share their counts).

#include <cstdint>
#include <set>
#include <string_view>

namespace frictiond::internal {

/// Inodes of the sockets this process has open (/proc/self/fd); empty when
/// /proc cannot be read.
std::set<std::uint64_t> SocketInodes();

/// Sum of the `drops` column over the rows of `table` (the text of
/// /proc/net/udp or /proc/net/udp6) whose inode is in `inodes`. Rows that do
/// not parse are skipped.
std::uint64_t SumUdpDrops(std::string_view table,
                          const std::set<std::uint64_t>& inodes);

/// SumUdpDrops over /proc/net/udp and /proc/net/udp6 (0 when unreadable).
std::uint64_t ReadUdpDrops(const std::set<std::uint64_t>& inodes);

/// Those of `inodes` that are UDP sockets (rows of /proc/net/udp{,6}).
std::set<std::uint64_t> UdpSocketsAmong(const std::set<std::uint64_t>& inodes);

}  // namespace frictiond::internal
