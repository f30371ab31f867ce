// The software update in the boot (DSP 302 §9) of `cfgmgr push` over the UDP
// multicast bus, against slaves written with python-can alone from the spec
// (tests/io/python/program_slaves.py: 1F50h by block download, 1F51h with DSP 302 v3.2.1's range
// 0..2, so that the master's clear (3) is refused, 1F52h from the image's trailer). Runs inside
// a private network namespace (tests/support/run_in_netns.sh) as the other UDP tool tests do;
// elsewhere it skips. The same slaves also have CiA 302-3's 1F56h/1F57h, for the update that a
// bus.yml's software_version/software_file asks for (lely's master's way).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "multicast_netns.hpp"
#include "python_peer.hpp"
#include "tool_test_support.hpp"

namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::ScratchDir;

constexpr const char* kPort = "43224";  // one port per test (43225, 43226 the next)

std::ptrdiff_t position(const std::vector<std::string>& lines, const std::string& line) {
  const auto it = std::find(lines.begin(), lines.end(), line);
  return it == lines.end() ? -1 : it - lines.begin();
}

TEST(ProgramUpdate, EndToEndOverUdp) {
  tool_test::run_in_private_netns("ProgramUpdateInNetns.*");
}

// The run against slaves started with `extra` options: the slaves' lines, both pushes' results.
struct Runs {
  tool_test::RunResult first, second;
  std::vector<std::string> lines;
  std::string all;
};

Runs push_twice(const ScratchDir& dir, const char* port, std::vector<std::string> slave_args) {
  const std::string bus = test_support::udp_test_url(port);
  slave_args.insert(slave_args.end(), {test_support::kUdpTestGroup, port, "40", "3"});
  test_support::PythonPeer slave(test_support::python_script("program_slaves.py"), slave_args);
  Runs r;
  if (slave.read_line() != "READY") return r;
  const std::string network = tool_test::data_path("program/python.cpj");
  r.first = tool_test::cfgmgr(dir, {"push", network, "--bus", bus});
  r.second = tool_test::cfgmgr(dir, {"push", network, "--bus", bus});
  {
    // The slaves' end: 7FFh without data, sent by python-can (can_peer.py).
    test_support::PythonPeer end({"send", test_support::kUdpTestGroup, port, "7FF#"});
    (void)end.finish();
  }
  r.lines = slave.read_all();
  (void)slave.finish();
  for (const auto& line : r.lines) r.all += line + "\n";
  return r;
}

void expect_updated_once(const Runs& r) {
  ASSERT_EQ(r.first.exit_code, 0) << r.first.out << r.first.err << "--- slave:\n" << r.all;
  EXPECT_THAT(r.first.out, HasSubstr("node 3 (drive): program updated: 1012 bytes in "));
  EXPECT_THAT(r.first.out, HasSubstr("before 2025-08-01 07:30:00.000"));
  EXPECT_THAT(r.first.out, HasSubstr("after 2026-11-27 08:15:00.000"));
  // DSP 302 §9 order: stop, clear (CiA 302-3; refused or not, the download goes on), the image,
  // start.
  const auto stop = position(r.lines, "CONTROL 3 0");
  const auto clear = position(r.lines, "CONTROL 3 3");
  const auto image = position(r.lines, "PROGRAM 3 1012");
  const auto start = position(r.lines, "CONTROL 3 1");
  ASSERT_GE(stop, 0) << r.all;
  EXPECT_LT(stop, clear) << r.all;
  EXPECT_LT(clear, image) << r.all;
  EXPECT_LT(image, start) << r.all;
  // The second push finds 1F52h = 1F53h/1F54h: no download.
  ASSERT_EQ(r.second.exit_code, 0) << r.second.out << r.second.err;
  EXPECT_THAT(r.second.out, Not(HasSubstr("program updated")));
  EXPECT_EQ(std::count(r.lines.begin(), r.lines.end(), "PROGRAM 3 1012"), 1) << r.all;
}

TEST(ProgramUpdateInNetns, PushUpdatesAPythonSlaveOnceAndTheSecondPushDoesNot) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  expect_updated_once(push_twice(dir, kPort, {}));
}

// DSP 302 v3.2.1 §9: 1F51h range 0..2; a device built to it refuses clear (3) with 0609 0030,
// which is no failure: the download goes on.
TEST(ProgramUpdateInNetns, ASlaveRefusingClearIsUpdatedAnyway) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  expect_updated_once(push_twice(dir, "43225", {"--refuse-clear"}));
}

// `cfgmgr simulate --state DIR` keeps a downloaded program image (DSP 302 §9 program memory)
// across a restart of the process, as a device keeps its flash across a power cycle: the second
// simulate reports the image's version in 1F52h at once, so verify finds nothing to list and a
// push nothing to update.
TEST(ProgramUpdateInNetns, SimulateStateKeepsTheDownloadedImageAcrossARestart) {
  REQUIRE_ISOLATED_MULTICAST();
  ScratchDir dir;
  const std::string bus = test_support::udp_test_url("43226");
  const std::string state = dir / "state";
  const std::string network = tool_test::data_path("program/program.cpj");
  const std::string device = tool_test::data_path("program/nodes/drive_node3.dcf") + "@3";
  tool_test::SimulatedDevices devices(dir.path(), bus, {"--state", state});
  ASSERT_NO_FATAL_FAILURE(devices.simulate({device}));
  const auto before = tool_test::cfgmgr(dir, {"verify", network, "--bus", bus});
  EXPECT_EQ(before.exit_code, 4) << before.out << before.err;
  EXPECT_THAT(before.out, HasSubstr("1F52h sub 01h"));
  const auto push = tool_test::cfgmgr(dir, {"push", network, "--bus", bus});
  ASSERT_EQ(push.exit_code, 0) << push.out << push.err << devices.output();
  EXPECT_THAT(push.out, HasSubstr("node 3 (drive): program updated: 1012 bytes in "));
  EXPECT_EQ(devices.stop(), 0) << devices.output();
  // The image is a file of its own next to the device's state file (nmt/sim/device_state.hpp).
  EXPECT_EQ(std::filesystem::file_size(dir / "state/node-03.program01.bin"),
            std::filesystem::file_size(tool_test::data_path("program/drive_v2.img")));

  ASSERT_NO_FATAL_FAILURE(devices.simulate({device}));
  const auto verify = tool_test::cfgmgr(dir, {"verify", network, "--bus", bus});
  EXPECT_EQ(verify.exit_code, 0) << verify.out << verify.err;
  EXPECT_THAT(verify.out, Not(HasSubstr("1F52h")));
  const auto again = tool_test::cfgmgr(dir, {"push", network, "--bus", bus});
  ASSERT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_THAT(again.out, Not(HasSubstr("program updated")));
  EXPECT_EQ(devices.stop(), 0) << devices.output();
}

// CiA 302-3 as lely's master does it, from a bus.yml (dcfgen's software_version and
// software_file): 1F56h sub 1 against 1F55h, the image, then 1F57h sub 1 read until bit 0
// ("in progress") clears, every 100 ms, over a real-time bus; start; 1F56h again. The second
// push finds 1F56h = 1F55h and downloads nothing.
TEST(ProgramUpdateInNetns, BusYmlSoftwareVersionUpdatesByIdentificationAfterTheFlashStatus) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  const char* port = "43227";
  std::vector<std::uint8_t> image(700);
  for (std::size_t i = 0; i < image.size(); ++i) image[i] = static_cast<std::uint8_t>(i * 13);
  tool_test::write_file(dir / "drive_v3.img", image);
  const std::uint32_t id = cfg::crc32(image);  // zlib's, as the python slave computes it
  tool_test::write_file(dir / "bus.yml",
                        std::string("master:\n  node_id: 1\n\ndrive:\n  dcf: \"") +
                            tool_test::data_path("program/nodes/python_node3.dcf") +
                            "\"\n  node_id: 3\n  software_version: " + cfg::hex(id, 8) +
                            "\n  software_file: \"drive_v3.img\"\n");
  const std::string bus = test_support::udp_test_url(port);
  test_support::PythonPeer slave(
      test_support::python_script("program_slaves.py"),
      {"--flash-busy", "2", test_support::kUdpTestGroup, port, "40", "3"});
  ASSERT_EQ(slave.read_line(), "READY");
  const auto first = tool_test::cfgmgr(dir, {"push", dir / "bus.yml", "--bus", bus});
  const auto second = tool_test::cfgmgr(dir, {"push", dir / "bus.yml", "--bus", bus});
  {
    test_support::PythonPeer end({"send", test_support::kUdpTestGroup, port, "7FF#"});
    (void)end.finish();
  }
  const auto lines = slave.read_all();
  (void)slave.finish();
  std::string all;
  for (const auto& line : lines) all += line + "\n";
  ASSERT_EQ(first.exit_code, 0) << first.out << first.err << "--- slave:\n" << all;
  EXPECT_THAT(first.out, HasSubstr("node 3 (drive): program updated: 700 bytes in "));
  EXPECT_THAT(first.out, HasSubstr("before software identification 0x0BAD0001, after " +
                                   cfg::hex(id, 8) + " (1F56h sub 1)"));
  // The image, two reads of "in progress", one of "done", then start.
  const auto image_at = position(lines, "PROGRAM 3 700");
  const auto busy = position(lines, "FLASH 3 1");
  const auto done = position(lines, "FLASH 3 0");
  const auto start = position(lines, "CONTROL 3 1");
  ASSERT_GE(image_at, 0) << all;
  EXPECT_LT(image_at, busy) << all;
  EXPECT_LT(busy, done) << all;
  EXPECT_LT(done, start) << all;
  EXPECT_EQ(std::count(lines.begin(), lines.end(), "FLASH 3 1"), 2) << all;
  EXPECT_EQ(std::count(lines.begin(), lines.end(), "READ 3 1F52 01"), 0) << "no DSP 302 read";
  ASSERT_EQ(second.exit_code, 0) << second.out << second.err;
  EXPECT_THAT(second.out, Not(HasSubstr("program updated")));
  EXPECT_EQ(std::count(lines.begin(), lines.end(), "PROGRAM 3 700"), 1) << all;
}

}  // namespace
