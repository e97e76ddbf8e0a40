#include "../src/udp_drops.h"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace frictiond::internal {
namespace {

// Two sockets of /proc/net/udp (Linux 6.x layout), one with 17 drops.
constexpr const char* kTable =
    "   sl  local_address rem_address   st tx_queue rx_queue tr tm->when "
    "retrnsmt   uid  timeout inode ref pointer drops            \n"
    "  123: 00000000:1DF3 00000000:0000 07 00000000:00034000 00:00000000 "
    "00000000     0        0 40001 2 0000000000000000 17        \n"
    "  456: 0100007F:A5C2 00000000:0000 07 00000000:00000000 00:00000000 "
    "00000000     0        0 40002 2 0000000000000000 0         \n"
    "  789: garbage\n";

TEST(UdpDrops, SumsTheDropsOfTheGivenSocketsOnly) {
  EXPECT_EQ(SumUdpDrops(kTable, {40001}), 17u);
  EXPECT_EQ(SumUdpDrops(kTable, {40001, 40002}), 17u);
  EXPECT_EQ(SumUdpDrops(kTable, {40002}), 0u);
  EXPECT_EQ(SumUdpDrops(kTable, {99}), 0u);
  EXPECT_EQ(SumUdpDrops("", {40001}), 0u);
  EXPECT_EQ(SumUdpDrops("header only\n", {40001}), 0u);
}

TEST(UdpDrops, FindsAUdpSocketThisProcessOpened) {
  const std::set<std::uint64_t> before = SocketInodes();
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  std::set<std::uint64_t> opened;
  for (std::uint64_t inode : SocketInodes())
    if (!before.count(inode)) opened.insert(inode);
  const std::set<std::uint64_t> udp = UdpSocketsAmong(opened);
  EXPECT_EQ(udp.size(), 1u);
  EXPECT_EQ(ReadUdpDrops(udp), 0u);
  ::close(fd);
}

}  // namespace
}  // namespace frictiond::internal
