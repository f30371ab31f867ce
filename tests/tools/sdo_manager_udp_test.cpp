// The SDO manager (CiA DSP 302 §7) of `cfgmgr master` over the UDP multicast bus,
// against an SDO requesting device written with python-can alone from the spec
// (tests/io/python/sdo_requesting_device.py) and two `cfgmgr simulate` slaves. Runs inside a
// private network namespace (tests/support/run_in_netns.sh) as the other UDP tool tests do;
// elsewhere it skips.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "python_peer.hpp"
#include "tool_test_support.hpp"

namespace {

using tool_test::ScratchDir;

constexpr const char* kPort = "43197";  // one port per test

std::string master_data(const std::string& name) {
  return tool_test::data_path("master/" + name);
}
std::string manager_data(const std::string& name) {
  return tool_test::data_path("sdo_manager/" + name);
}

std::ptrdiff_t position(const std::vector<std::string>& lines, const std::string& prefix) {
  const auto it = std::find_if(lines.begin(), lines.end(),
                               [&](const std::string& line) { return line.rfind(prefix, 0) == 0; });
  return it == lines.end() ? -1 : it - lines.begin();
}

TEST(SdoManager, EndToEndOverUdp) {
  tool_test::run_in_private_netns("SdoManagerInNetns.*");
}

// The SRD at node 127 (§7.2.4 guideline 2), slaves 2 and 3 from tests/data/master/slave.eds, the
// master from tests/data/sdo_manager/manager.dcf (node 1; its 1F00h turns the SDO manager on,
// 1F02h is its pool of COB-IDs 681h-688h).
TEST(SdoManagerInNetns, PythonSrdRegistersConnectsReadsAndReleases) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  const std::string bus = test_support::udp_test_url(kPort);
  test_support::PythonPeer srd(test_support::python_script("sdo_requesting_device.py"),
                               {test_support::kUdpTestGroup, kPort, "40", "127", "2"});
  ASSERT_EQ(srd.read_line(), "READY");
  tool_test::SpawnedTool devices("cfgmgr",
                                 {"simulate", "--bus", bus, "--for", "60",
                                  master_data("slave.eds") + "@2", master_data("slave.eds") + "@3"},
                                 dir / "sim.out", dir / "sim.err");
  ASSERT_TRUE(devices.started());
  ASSERT_TRUE(devices.wait_until_simulating()) << devices.output();
  tool_test::SpawnedTool master(
      "cfgmgr",
      {"master", manager_data("manager.dcf"), "--bus", bus, "--node-id", "1", "--run-for", "60"},
      dir / "master.out", dir / "master.err");
  ASSERT_TRUE(master.started());

  // The script ends by itself: END, or TIMEOUT after 40 s.
  const auto lines = srd.read_all();
  const int srd_exit = srd.finish();
  (void)master.stop(SIGINT, std::chrono::milliseconds(3000));
  (void)devices.stop(SIGINT, std::chrono::milliseconds(3000));
  std::string all;
  for (const auto& line : lines) all += line + "\n";
  const std::string master_err = tool_test::slurp(dir / "master.err");
  ASSERT_EQ(srd_exit, 0) << all << "--- master:\n" << master_err;
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines.back(), "END");

  // §7.2.1: the manager wrote the client entry 1280h (sub 3 = the manager, node 1), then
  // confirmed in 1F10h: index 1280h, Cnxn state 1, Rq indication 0 (§7.2.3).
  const auto confirmed = position(lines, "WRITE 1F10 00 12800002");
  ASSERT_GE(confirmed, 0) << all;
  EXPECT_LT(position(lines, "WRITE 1280 01 "), confirmed) << all;
  EXPECT_LT(position(lines, "WRITE 1280 02 "), confirmed) << all;
  EXPECT_LT(position(lines, "WRITE 1280 03 00000001"), confirmed) << all;
  const auto registered = position(lines, "REGISTERED 1280 ");
  ASSERT_GE(registered, 0) << all;
  // Both COB-IDs from the pool 681h-688h of manager.dcf (bit 31 clear: valid), and the server
  // node-ID 1.
  const std::string& entry = lines[static_cast<std::size_t>(registered)];
  EXPECT_EQ(entry.substr(16, 7), "0000068") << entry;
  EXPECT_EQ(entry.substr(25, 7), "0000068") << entry;
  EXPECT_EQ(entry.substr(entry.size() - 2), "01") << entry;
  // §7.2.2 / §7.1: node 2's default SDO is free, so the connection is on it (CiA 301 pre-defined
  // connection set: 602h / 582h) and 1F10h says Cnxn state 3 for 1281h.
  EXPECT_GE(position(lines, "REQUESTED"), 0) << all;
  EXPECT_GE(position(lines, "WRITE 1F10 00 12810006"), 0) << all;
  EXPECT_GE(position(lines, "CONNECTED 1281 00000602 00000582 02"), 0) << all;
  // slave.eds: 1018h sub 1 = 0000ABCDh.
  EXPECT_GE(position(lines, "READ 1018 01 0000ABCD"), 0) << all;
  // §7.2.3 1F01h: released; the SRD sees it in its client entry (bit 31).
  EXPECT_GE(position(lines, "RELEASE"), 0) << all;
  EXPECT_GE(position(lines, "RELEASED 1281"), 0) << all;
}

}  // namespace
