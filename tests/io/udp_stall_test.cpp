// The event loop over a real UDP socket, with a real stall (tests/support/heartbeat_stall.hpp).
// Sends multicast: runs only in the private network namespace of the ctest test
// io_udp_bus_netns (tests/support/run_in_netns.sh); elsewhere it skips.
#include <gtest/gtest.h>

#include "heartbeat_stall.hpp"
#include "multicast_netns.hpp"
#include "nmt/io/udp_bus.hpp"

namespace nmt {
namespace {

constexpr std::uint16_t kPort = 47030;  // one port per test file (python-can binds to the port)

std::unique_ptr<UdpBus> open_udp() {
  UdpBusOptions options;
  options.port = kPort;
  auto bus = UdpBus::open(options);
  EXPECT_TRUE(bus.ok()) << bus.error().message;
  return bus.ok() ? std::move(*bus) : nullptr;
}

TEST(UdpBus, HeartbeatsQueuedWhileTheLoopStallsCountAsInTimeAndARealLossIsSeen) {
  REQUIRE_ISOLATED_MULTICAST();
  auto bus = open_udp();
  auto peer = open_udp();
  ASSERT_TRUE(bus && peer);
  test_support::check_stall_is_not_a_heartbeat_loss(*bus, std::move(peer));
}

}  // namespace
}  // namespace nmt
