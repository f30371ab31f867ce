// lely dcfgen's output as it is, end to end on sim: (corpus tier): a master.dcf whose 1F22h sub N
// names each slave's concise DCF by UploadFile= with an absolute path of the machine that ran
// dcfgen, and the slaves' .bin files. `cfgmgr push master.dcf --bus sim:?device=EDS@N` (the
// slaves simulated from the EDS files dcfgen read) downloads every entry of each .bin; a file
// that is nowhere is an error at its line before the bus; a slave whose 1F22h sub N is empty is
// reported as having no configuration. The corpus sets (../shared/corpus, README there):
//  - ros2_canopen-dcfgen/{cia402,robot_control,simple}: master.dcf beside the .bin files,
//    UploadFile=/opt/ros/share/canopen_tests/config/<slave>.bin;
//  - starnus-ros2_canopen-build: <set>__master.dcf and <set>__<slave>.bin (the corpus flattened
//    the install directory), UploadFile=/home/starnus/.../<slave>.bin.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/download_order.hpp"
#include "multicast_netns.hpp"
#include "prerequisite.hpp"
#include "push_test_support.hpp"
#include "tool_test_support.hpp"

namespace {

namespace fs = std::filesystem;
using push_test::cfgmgr;
using push_test::Json;
using push_test::ScratchDir;
using ::testing::HasSubstr;
using ::testing::Not;

std::string corpus(const std::string& relative) {
  return std::string(CANOPEN_CORPUS_DIR) + "/" + relative;
}

#define SKIP_WITHOUT_CORPUS()                                       \
  if (!fs::exists(corpus("MANIFEST.tsv"))) {                        \
    PREREQUISITE_MISSING("corpus not found: ", CANOPEN_CORPUS_DIR); \
  }

// What the master downloads from a .bin: its entries (the stream's first 4 bytes count them,
// DSP 302 §6.2) in the PDO-safe order of cfg::plan_download, which puts a PDO's COB-ID invalid
// before its mapping where the stream does not (dcfgen leaves it out when the EDS's default is
// invalid already). Fails the test when the count and the entries differ.
struct Expected {
  std::size_t in_stream = 0;  ///< the .bin's count
  std::size_t written = 0;    ///< writes the master sends
  std::uint64_t bytes = 0;
};
Expected expected_download(const std::string& bin) {
  const std::string text = tool_test::slurp(bin);
  EXPECT_GE(text.size(), 4U) << bin;
  Expected e;
  for (int i = 3; i >= 0; --i) {
    e.in_stream =
        (e.in_stream << 8) | static_cast<std::uint8_t>(text.at(static_cast<std::size_t>(i)));
  }
  const std::vector<std::uint8_t> bytes(text.begin(), text.end());
  auto writes = cfg::decode_concise_dcf(bytes);
  EXPECT_TRUE(writes.ok()) << bin;
  if (!writes) return e;
  EXPECT_EQ(writes->size(), e.in_stream) << bin;
  const auto order = cfg::plan_download(*writes);
  e.written = order.writes.size();
  for (const auto& w : order.writes) e.bytes += w.data.size();
  return e;
}

// push of `master` with the slaves `devices` ("EDS@2,3") on sim:, the report's nodes by node-ID.
struct Push {
  tool_test::RunResult run;
  Json report;
};
Push push(const ScratchDir& dir, const std::string& master, const std::string& devices,
          const std::string& report, std::vector<std::string> more = {}) {
  std::vector<std::string> args{"push",   master,
                                "--bus",  "sim:?device=" + devices + "&state=" + (dir / "state"),
                                "--json", report};
  args.insert(args.end(), more.begin(), more.end());
  Push p;
  p.run = cfgmgr(dir, args);
  if (fs::exists(report)) p.report = push_test::parse_json(report);
  return p;
}

// Each slave of a ros2_canopen test configuration: its .bin and EDS as dcfgen read them.
struct Slave {
  int node_id;
  std::string bin;
};

void expect_configured_from_bins(const std::string& set, const std::string& eds,
                                 const std::vector<Slave>& slaves) {
  ScratchDir dir;
  std::string nodes;
  for (const auto& s : slaves) nodes += (nodes.empty() ? "" : ",") + std::to_string(s.node_id);
  const std::string master = corpus(set + "/master.dcf");
  auto first = push(dir, master, corpus(set + "/" + eds) + "@" + nodes, dir / "first.json");
  ASSERT_EQ(first.run.exit_code, 0) << first.run.err << first.run.out;
  // The absolute path of dcfgen's machine is not here: the .bin beside master.dcf is used.
  EXPECT_THAT(first.run.err, HasSubstr("UploadFile '/opt/ros/share/canopen_tests/config/"));
  EXPECT_THAT(first.run.err, HasSubstr("beside the master DCF instead"));
  const auto reported = push_test::nodes_of(first.report);
  ASSERT_EQ(reported.size(), slaves.size()) << first.run.out;
  for (const auto& s : slaves) {
    const Expected e = expected_download(corpus(set + "/" + s.bin));
    const Json* n = reported.at(s.node_id);
    EXPECT_EQ(n->get("result")->string, "configured") << s.bin;
    EXPECT_EQ(static_cast<std::size_t>(n->get("entries")->number), e.written) << s.bin;
    EXPECT_EQ(static_cast<std::uint64_t>(n->get("bytes")->number), e.bytes) << s.bin;
    EXPECT_GE(e.written, e.in_stream) << s.bin;
  }
  // CiA 302-2 §3.5 a: dcfgen writes no 1F26h/1F27h and these devices have no 1020h, so the
  // configuration is not verified: the second push downloads it again, entry for entry, and
  // says so rather than "up to date".
  auto second = push(dir, master, corpus(set + "/" + eds) + "@" + nodes, dir / "second.json");
  ASSERT_EQ(second.run.exit_code, 0) << second.run.err << second.run.out;
  const auto again = push_test::nodes_of(second.report);
  for (const auto& s : slaves) {
    EXPECT_EQ(again.at(s.node_id)->get("result")->string, "configured") << s.bin;
    EXPECT_EQ(again.at(s.node_id)->get("entries")->number,
              reported.at(s.node_id)->get("entries")->number)
        << s.bin;
  }
}

TEST(DcfgenPush, Ros2CanopenCia402ConfiguresItsSlaveFromTheBinBesideMasterDcf) {
  SKIP_WITHOUT_CORPUS();
  // 24 entries in the stream (MANIFEST.tsv), 28 writes: 4 PDOs made invalid around their mapping.
  expect_configured_from_bins("ros2_canopen-dcfgen/cia402", "cia402_slave.eds",
                              {{2, "cia402_device_1.bin"}});
}

TEST(DcfgenPush, Ros2CanopenRobotControlConfiguresBothJointsFromTheirBins) {
  SKIP_WITHOUT_CORPUS();
  // 30 entries each (MANIFEST.tsv), every PDO's invalid COB-ID in the stream already.
  expect_configured_from_bins("ros2_canopen-dcfgen/robot_control", "cia402_slave.eds",
                              {{2, "joint_1.bin"}, {3, "joint_2.bin"}});
}

// The starnus build with its .bin files in a directory of their own, as an install tree has
// them: --dcf-path finds each by its name, without a warning.
TEST(DcfgenPush, StarnusRobotControlFindsTheBinsInTheDcfPathDirectory) {
  SKIP_WITHOUT_CORPUS();
  ScratchDir dir;
  const std::string set = "starnus-ros2_canopen-build/robot_control__";
  fs::create_directories(dir / "install");
  fs::copy_file(corpus(set + "master.dcf"), dir / "master.dcf");
  fs::copy_file(corpus(set + "joint_1.bin"), dir / "install/joint_1.bin");
  fs::copy_file(corpus(set + "joint_2.bin"), dir / "install/joint_2.bin");
  auto p = push(dir, dir / "master.dcf", corpus(set + "cia402_slave.eds") + "@2,3",
                dir / "report.json", {"--dcf-path", dir / "install"});
  ASSERT_EQ(p.run.exit_code, 0) << p.run.err << p.run.out;
  EXPECT_THAT(p.run.err, Not(HasSubstr("warning")));
  const auto nodes = push_test::nodes_of(p.report);
  ASSERT_EQ(nodes.size(), 2U);
  for (const auto& [id, bin] : {std::pair{2, "joint_1.bin"}, std::pair{3, "joint_2.bin"}}) {
    const Expected e = expected_download(dir / ("install/" + std::string(bin)));
    EXPECT_EQ(e.in_stream, 30U);  // MANIFEST.tsv
    EXPECT_EQ(nodes.at(id)->get("result")->string, "configured");
    EXPECT_EQ(static_cast<std::size_t>(nodes.at(id)->get("entries")->number), e.written);
  }
}

// starnus cia402__master.dcf names six slaves' files under /home/starnus/...; the corpus has
// two of them, under other names. Each file that is nowhere is an error at its UploadFile= line
// (1678, 1684, ..., 1708), push exits 1 before it opens the bus (no trace), and check names the
// same lines.
TEST(DcfgenPush, StarnusCia402FilesThatAreNowhereAreErrorsAtTheirLinesAndNothingIsSent) {
  SKIP_WITHOUT_CORPUS();
  ScratchDir dir;
  const std::string master = corpus("starnus-ros2_canopen-build/cia402__master.dcf");
  const std::string eds = corpus("starnus-ros2_canopen-build/cia402__cia402_slave.eds");
  const auto r = cfgmgr(dir, {"push", master, "--bus", "sim:?device=" + eds + "@2-7", "--candump",
                              dir / "bus.log", "--json", dir / "report.json"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  for (int n = 1; n <= 6; ++n) {
    const std::string line = std::to_string(1678 + 6 * (n - 1));
    const std::string sub = "0" + std::to_string(n + 1);
    EXPECT_THAT(r.err, HasSubstr(master + ":" + line + ": error: 1F22h sub " + sub +
                                 "h UploadFile '/home/starnus/"));
    EXPECT_THAT(r.err, HasSubstr("/cia402_device_" + std::to_string(n) + ".bin': no such file"));
  }
  EXPECT_THAT(r.err, HasSubstr("rebuild the master DCF here (dcfgen) or pass the directory that "
                               "holds 'cia402_device_6.bin' with --dcf-path DIR"));
  EXPECT_FALSE(fs::exists(dir / "bus.log"));
  EXPECT_FALSE(fs::exists(dir / "report.json"));
  EXPECT_THAT(r.err, Not(HasSubstr("simulated device")));

  const auto check = cfgmgr(dir, {"check", "--network", master});
  EXPECT_EQ(check.exit_code, 1);
  EXPECT_THAT(check.err, HasSubstr(master + ":1690: error: 1F22h sub 04h UploadFile"));

  // With the two files the corpus has, under dcfgen's names, four remain missing.
  fs::create_directories(dir / "bins");
  for (const char* name : {"cia402_device_1.bin", "cia402_device_2.bin"}) {
    fs::copy_file(corpus(std::string("starnus-ros2_canopen-build/cia402__") + name),
                  dir / ("bins/" + std::string(name)));
  }
  const auto partly = cfgmgr(dir, {"check", "--network", master, "--dcf-path", dir / "bins"});
  EXPECT_EQ(partly.exit_code, 1);
  EXPECT_THAT(partly.err, Not(HasSubstr("cia402_device_1.bin': no such file")));
  EXPECT_THAT(partly.err, HasSubstr("cia402_device_3.bin': no such file"));
  EXPECT_THAT(partly.err, HasSubstr("(nor '" + (dir / "bins/cia402_device_3.bin") + "', '"));
  EXPECT_THAT(partly.out, HasSubstr("4 errors"));
}

// ros2_canopen's simple configuration: two proxy slaves with nothing to configure, so dcfgen
// left 1F22h out. Push boots them and says so in its line, table and JSON; check warns at
// their 1F81h entries ([1F81Value] 2= and 3=, lines 502 and 503).
TEST(DcfgenPush, Ros2CanopenSimpleSaysNoConfigurationForSlavesWithAnEmpty1F22h) {
  SKIP_WITHOUT_CORPUS();
  ScratchDir dir;
  const std::string master = corpus("ros2_canopen-dcfgen/simple/master.dcf");
  auto p = push(dir, master, corpus("ros2_canopen-dcfgen/simple/simple.eds") + "@2,3",
                dir / "report.json");
  ASSERT_EQ(p.run.exit_code, 0) << p.run.err << p.run.out;
  EXPECT_THAT(p.run.err, Not(HasSubstr("up to date")));
  EXPECT_THAT(p.run.err,
              HasSubstr("node 2: booted, no configuration for node 2 (1F22h sub 02h empty)"));
  EXPECT_THAT(p.run.err,
              HasSubstr("node 3: booted, no configuration for node 3 (1F22h sub 03h empty)"));
  EXPECT_THAT(p.run.out, HasSubstr("   2        no_configuration        0"));
  EXPECT_THAT(p.run.out,
              HasSubstr("node 3: no configuration for node 3 (1F22h sub 03h empty): nothing "
                        "downloaded\n"));
  const auto nodes = push_test::nodes_of(p.report);
  ASSERT_EQ(nodes.size(), 2U);
  for (const int id : {2, 3}) {
    EXPECT_EQ(nodes.at(id)->get("result")->string, "no_configuration");
    EXPECT_EQ(nodes.at(id)->get("entries")->number, 0);
    EXPECT_THAT(nodes.at(id)->get("message")->string,
                HasSubstr("no configuration for node " + std::to_string(id) + " (1F22h sub 0" +
                          std::to_string(id) + "h empty)"));
  }

  const auto check = cfgmgr(dir, {"check", "--network", master});
  EXPECT_EQ(check.exit_code, 0) << check.err;
  EXPECT_THAT(check.err, HasSubstr(master + ":502: warning: 1F81h sub 02h: node 2 is a slave the "
                                            "master boots, but there is no configuration for "
                                            "node 2 (1F22h sub 02h empty)"));
  EXPECT_THAT(check.err, HasSubstr(master + ":503: warning: 1F81h sub 03h"));
}

// The same master.dcf over the UDP multicast bus in real time, against `cfgmgr simulate`
// processes built from the EDS dcfgen read (ros2_canopen's robot_control: two joints, 30
// entries each in their .bin). Runs inside a private network namespace; elsewhere it skips.
TEST(DcfgenPush, EndToEndOverUdp) {
  tool_test::run_in_private_netns("DcfgenPushInNetns.*");
}

TEST(DcfgenPushInNetns, Ros2CanopenRobotControlConfiguresBothJointsOverUdp) {
  REQUIRE_ISOLATED_MULTICAST();
  SKIP_WITHOUT_CORPUS();
  ScratchDir dir;
  const std::string set = corpus("ros2_canopen-dcfgen/robot_control");
  const std::string bus = test_support::udp_test_url("43228");
  tool_test::SimulatedDevices devices(dir.path(), bus, {});
  ASSERT_NO_FATAL_FAILURE(
      devices.simulate({set + "/cia402_slave.eds@2", set + "/cia402_slave.eds@3"}));
  const auto r = cfgmgr(dir, {"push", set + "/master.dcf", "--bus", bus, "--dcf-path", set,
                              "--json", dir / "report.json"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err << devices.output();
  const Json report = push_test::parse_json(dir / "report.json");
  const auto nodes = push_test::nodes_of(report);
  ASSERT_EQ(nodes.size(), 2U);
  for (const auto& [id, bin] : {std::pair{2, "joint_1.bin"}, std::pair{3, "joint_2.bin"}}) {
    const Expected e = expected_download(set + "/" + bin);
    EXPECT_EQ(e.in_stream, 30U);  // MANIFEST.tsv
    EXPECT_EQ(nodes.at(id)->get("result")->string, "configured");
    EXPECT_EQ(static_cast<std::size_t>(nodes.at(id)->get("entries")->number), e.written);
  }
  // Issue 33: the bus's counters are in the report (a UDP bus has no controller errors).
  const Json* counters = report.get("bus");
  ASSERT_TRUE(counters != nullptr && counters->is(Json::Kind::Object));
  for (const char* key :
       {"error_frames", "bus_off", "error_passive", "lost_arbitration", "queue_full", "refused"}) {
    ASSERT_NE(counters->get(key), nullptr) << key;
    EXPECT_EQ(counters->get(key)->number, 0.0) << key;
  }
  // The devices hold the .bin's values: verify reads every entry back and finds none differing.
  const auto v = cfgmgr(dir, {"verify", set + "/master.dcf", "--bus", bus, "--dcf-path", set});
  EXPECT_EQ(v.exit_code, 0) << v.out << v.err;
  EXPECT_EQ(devices.stop(), 0) << devices.output();
}

}  // namespace
