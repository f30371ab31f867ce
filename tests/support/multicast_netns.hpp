// Tests that send UDP multicast run only inside the private network namespace the ctest test
// io_udp_bus_netns creates with tests/support/run_in_netns.sh (CANOPEN_UDP_NETNS=1, lo the only
// interface, the multicast route on lo): nothing they send can leave the machine. Elsewhere they
// skip.
#pragma once

#include <gtest/gtest.h>
#include <net/if.h>

#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>

#include "prerequisite.hpp"
#include "python_peer.hpp"

namespace test_support {

/// The multicast group of the UDP bus tests: python-can udp_multicast's default IPv4 group
/// (udp_multicast/bus.py, DEFAULT_GROUP_IPv4). Each test file takes ports of its own.
inline constexpr const char* kUdpTestGroup = "239.74.163.2";

/// The --bus URL of a test on `port` of that group: "udp://239.74.163.2:PORT".
inline std::string udp_test_url(std::string_view port) {
  return std::string("udp://") + kUdpTestGroup + ":" + std::string(port);
}

/// True inside the namespace run_in_netns.sh made (it sets CANOPEN_UDP_NETNS=1).
inline bool in_multicast_netns() {
  const char* env = std::getenv("CANOPEN_UDP_NETNS");
  return env != nullptr && std::string(env) == "1";
}

/// Why multicast must not be sent here, or nullopt when this is that namespace.
inline std::optional<std::string> multicast_not_isolated() {
  if (!in_multicast_netns()) {
    return "sends multicast: runs only in the private network namespace of the ctest test "
           "io_udp_bus_netns (ctest -R io_udp_bus_netns)";
  }
  struct if_nameindex* names = if_nameindex();
  if (names == nullptr) return "cannot list network interfaces";
  std::optional<std::string> why;
  for (auto* n = names; n->if_index != 0; ++n) {
    if (std::string(n->if_name) != "lo") {
      why = std::string("interface ") + n->if_name + " exists: refusing to send multicast";
    }
  }
  if_freenameindex(names);
  return why;
}

}  // namespace test_support

// Outside the namespace the test is not missing anything: it runs in the ctest test
// io_udp_bus_netns (or tools_simulate_netns) instead, so it skips plainly, even under CI=true.
// Inside it, an interface other than lo is a broken namespace: a missing prerequisite.
#define REQUIRE_ISOLATED_MULTICAST()                                     \
  do {                                                                   \
    if (auto why_not = test_support::multicast_not_isolated()) {         \
      if (!test_support::in_multicast_netns()) GTEST_SKIP() << *why_not; \
      PREREQUISITE_MISSING(*why_not);                                    \
    }                                                                    \
  } while (0)

#define REQUIRE_PYTHON_CAN()                                                               \
  do {                                                                                     \
    if (auto why_not = test_support::python_can_missing()) PREREQUISITE_MISSING(*why_not); \
  } while (0)
