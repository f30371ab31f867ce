// `cfgmgr push --lss` and `cfgmgr master --lss`: devices out of the box, without
// node-ID (CiA 305), are found by Fastscan and given the node-ID of the node whose DCF has their
// LSS address (DSP 302 §4 figure 1 step 3, before the reset of all nodes), then booted as usual.
// The network is made in the test from tests/data/lss/lss_io_1003.dcf (1018h: vendor 7E57C0DEh,
// product 00000305h, revision 00010002h): nodes 16, 17, 18 with [DeviceComissioning]
// LSS_SerialNumber 2001h, 2002h, 2003h. On `sim:` with unconfigured=, and over UDP multicast
// with `cfgmgr simulate FILE@255` inside a private network namespace (elsewhere those skip).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "prerequisite.hpp"
#include "tool_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::cfgmgr;
using tool_test::ScratchDir;

const std::string kUrl = test_support::udp_test_url("43197");

// lss_io.eds: the same product with serial number 1001h, a device of no node of the network.
const std::string kStranger = tool_test::data_path("lss/lss_io.eds");
constexpr const char* kStrangerAddress = "7E57C0DE:00000305:00010002:00001001";

// ioN.dcf for N = 16, 17, 18 (serial 2000h + N - 15) and nodelist.cpj naming them.
void write_network(const ScratchDir& dir) {
  const std::string base = tool_test::slurp(tool_test::data_path("lss/lss_io_1003.dcf"));
  std::string cpj = "[Topology]\nNetName=lss out of the box\nNodes=0x03\n";
  for (int node = 16; node <= 18; ++node) {
    std::istringstream lines(base);
    std::string text;
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("LSS_SerialNumber=", 0) == 0) {
        line = "LSS_SerialNumber=0x0000200" + std::to_string(node - 15);
      } else if (line.rfind("NodeID=", 0) == 0) {
        line = "NodeID=" + std::to_string(node);
      }
      text += line + "\n";
    }
    const std::string name = "io" + std::to_string(node) + ".dcf";
    std::ofstream(dir / name) << text;
    cpj += "Node" + std::to_string(node) + "Present=0x01\nNode" + std::to_string(node) +
           "DCFName=" + name + "\n";
  }
  std::ofstream(dir / "nodelist.cpj") << cpj;
}

std::vector<bool> lss_assigned(const tool_test::Json& report) {
  std::vector<bool> out;
  for (const auto& n : report.get("nodes")->array) out.push_back(n.get("lss_assigned")->boolean);
  return out;
}

std::vector<std::string> unmatched(const tool_test::Json& report) {
  std::vector<std::string> out;
  for (const auto& a : report.get("lss_unmatched")->array) out.push_back(a.string);
  return out;
}

// LSS frames (7E5h master -> slave, 7E4h slave -> master) in a candump log.
int lss_frames(const std::string& log, const char* cob_id) {
  int count = 0;
  std::istringstream lines(log);
  for (std::string line; std::getline(lines, line);) {
    if (line.find(std::string(" ") + cob_id + "#") != std::string::npos) ++count;
  }
  return count;
}

TEST(PushLss, HelpDocumentsLssForPushAndMaster) {
  ScratchDir dir;
  const auto push = cfgmgr(dir, {"push", "--help"});
  EXPECT_EQ(push.exit_code, 0);
  for (const char* text : {"--lss", "--lss-scan-step", "Devices out of the box", "lss_assigned",
                           "lss_unmatched", "--bus 'sim:?unconfigured=2-4' --lss"}) {
    EXPECT_THAT(push.out, HasSubstr(text));
  }
  const auto master = cfgmgr(dir, {"master", "--help"});
  EXPECT_EQ(master.exit_code, 0);
  for (const char* text : {"--lss", "--lss-period", "0.025 %", "--lss --lss-period 1000"}) {
    EXPECT_THAT(master.out, HasSubstr(text));
  }
}

TEST(PushLss, LssPeriodWithoutLssIsAUsageError) {
  ScratchDir dir;
  write_network(dir);
  const auto r =
      cfgmgr(dir, {"master", dir / "nodelist.cpj", "--bus", "sim:", "--lss-period", "100"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--lss-period needs --lss"));
}

// The devices of all three nodes power on without node-ID: --lss gives each its node-ID before
// the boot; they store it (sim:?state=), so the second push finds them configured and LSS has
// nothing to do: its switch to waiting and one Fastscan reset nobody answers.
TEST(PushLss, SimDevicesOutOfTheBoxAreAllConfiguredAndASecondPushNeedsNoLss) {
  ScratchDir dir;
  write_network(dir);
  const std::string bus = "sim:?unconfigured=16-18&state=" + (dir / "state");
  const auto first = cfgmgr(dir, {"push", dir / "nodelist.cpj", "--bus", bus, "--lss", "--json",
                                  dir / "first.json", "--candump", dir / "first.log"});
  ASSERT_EQ(first.exit_code, 0) << first.err;
  const auto report = tool_test::json_object_of(tool_test::slurp(dir / "first.json"));
  EXPECT_TRUE(report.get("ok")->boolean);
  EXPECT_EQ(lss_assigned(report), (std::vector<bool>{true, true, true}));
  EXPECT_TRUE(unmatched(report).empty());
  for (const auto& n : report.get("nodes")->array) {
    EXPECT_EQ(n.get("result")->string, "configured") << n.get("node_id")->number;
  }
  EXPECT_THAT(first.out, HasSubstr("lss"));
  EXPECT_THAT(first.out, HasSubstr("  17  io_1003  configured  assigned"));
  EXPECT_THAT(first.err, HasSubstr("node 17: LSS: vendor 7E57C0DEh product 00000305h revision "
                                   "00010002h serial 00002002h got node-ID 17, stored"));
  // configure node-ID (11h) and store (17h) per device, each answered.
  const std::string log = tool_test::slurp(dir / "first.log");
  EXPECT_THAT(log, HasSubstr("7E5#1110000000000000"));
  EXPECT_THAT(log, HasSubstr("7E5#1111000000000000"));
  EXPECT_THAT(log, HasSubstr("7E5#1112000000000000"));

  const auto second = cfgmgr(dir, {"push", dir / "nodelist.cpj", "--bus", bus, "--lss", "--json",
                                   dir / "second.json", "--candump", dir / "second.log"});
  ASSERT_EQ(second.exit_code, 0) << second.err;
  const auto again = tool_test::json_object_of(tool_test::slurp(dir / "second.json"));
  EXPECT_EQ(lss_assigned(again), (std::vector<bool>{false, false, false}));
  const std::string log2 = tool_test::slurp(dir / "second.log");
  EXPECT_EQ(lss_frames(log2, "7E5"), 2);  // 04h to waiting, 4Ch (identify non-configured)
  EXPECT_EQ(lss_frames(log2, "7E4"), 0);
  EXPECT_THAT(second.err, HasSubstr("LSS: 0 unconfigured devices found"));
}

// --only 16: the other nodes are left as they are, LSS included: their devices stay without
// node-ID and are reported as matching no node of this run.
TEST(PushLss, OnlyGivesNodeIdsToTheSelectedNodes) {
  ScratchDir dir;
  write_network(dir);
  const auto r = cfgmgr(dir, {"push", dir / "nodelist.cpj", "--bus", "sim:?unconfigured=16-18",
                              "--lss", "--only", "16", "--json", dir / "r.json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = tool_test::json_object_of(tool_test::slurp(dir / "r.json"));
  EXPECT_EQ(lss_assigned(report), (std::vector<bool>{true}));
  EXPECT_EQ(unmatched(report), (std::vector<std::string>{"7E57C0DE:00000305:00010002:00002002",
                                                         "7E57C0DE:00000305:00010002:00002003"}));
}

// Without --lss, the same devices are missing (status B), as before.
TEST(PushLss, WithoutLssTheUnconfiguredDevicesAreMissing) {
  ScratchDir dir;
  write_network(dir);
  const auto r = cfgmgr(dir, {"push", dir / "nodelist.cpj", "--bus", "sim:?unconfigured=17",
                              "--boot-time", "1", "--json", dir / "r.json"});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  const auto report = tool_test::json_object_of(tool_test::slurp(dir / "r.json"));
  EXPECT_EQ(report.get("nodes")->array.at(1).get("status")->string, "B");
  EXPECT_THAT(tool_test::slurp(dir / "r.json"), HasSubstr("\"lss_assigned\": false"));
}

// --------------------------------------------------------- over UDP, in a namespace ----------

TEST(PushLss, EndToEndOverUdp) {
  tool_test::run_in_private_netns("PushLssInNetns.*");
}

class PushLssInNetns : public ::testing::Test {
 protected:
  void SetUp() override {
    REQUIRE_ISOLATED_MULTICAST();
    write_network(dir_);
  }
  std::string file(int node) const { return dir_ / ("io" + std::to_string(node) + ".dcf"); }

  ScratchDir dir_;
  tool_test::SimulatedDevices devices_{dir_.path(), kUrl};
};

TEST_F(PushLssInNetns, PushLssConfiguresDevicesOutOfTheBoxAndReportsAStranger) {
  devices_.simulate({file(16) + "@255", file(17) + "@255", file(18) + "@255", kStranger + "@255"});
  // The scan step is generous: the devices answer from another process on a shared machine.
  const auto r = cfgmgr(dir_, {"push", dir_ / "nodelist.cpj", "--bus", kUrl, "--lss",
                               "--lss-scan-step", "40", "--json", dir_ / "r.json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = tool_test::json_object_of(tool_test::slurp(dir_ / "r.json"));
  EXPECT_EQ(lss_assigned(report), (std::vector<bool>{true, true, true}));
  EXPECT_EQ(unmatched(report), (std::vector<std::string>{kStrangerAddress}));
  EXPECT_THAT(r.out, HasSubstr(std::string("LSS: device ") + kStrangerAddress +
                               " without node-ID matches no node: left without node-ID"));
  // The stranger stays without node-ID: the next push (stored node-IDs) finds only it.
  const auto again = cfgmgr(dir_, {"push", dir_ / "nodelist.cpj", "--bus", kUrl, "--lss",
                                   "--lss-scan-step", "40", "--json", dir_ / "again.json"});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const auto second = tool_test::json_object_of(tool_test::slurp(dir_ / "again.json"));
  EXPECT_EQ(lss_assigned(second), (std::vector<bool>{false, false, false}));
  EXPECT_EQ(unmatched(second), (std::vector<std::string>{kStrangerAddress}));
}

// A drive is replaced while the master runs: the new one comes out of the box without node-ID.
// --lss-period finds it, gives it its node-ID, and the boot-up handler boots and configures it.
TEST_F(PushLssInNetns, MasterLssPeriodConfiguresAReplacedDevice) {
  devices_.simulate({file(16) + "@16", file(17) + "@17", file(18) + "@18"});
  tool_test::SpawnedTool master("cfgmgr",
                                {"master", dir_ / "nodelist.cpj", "--bus", kUrl, "--lss",
                                 "--lss-scan-step", "40", "--lss-period", "300", "--run-for", "60"},
                                dir_ / "master.out", dir_ / "master.err");
  ASSERT_TRUE(master.started());
  ASSERT_TRUE(master.wait_for_output("NMT start-up complete", 30s)) << master.output();
  EXPECT_THAT(master.output(), Not(HasSubstr("got node-ID")));
  // Node 17's device is replaced by a new one with the same LSS address, without node-ID.
  devices_.simulate({file(16) + "@16", file(17) + "@255", file(18) + "@18"});
  ASSERT_TRUE(master.wait_for_output("got node-ID 17, stored", 30s)) << master.output();
  // Then its boot, with the configuration (the boot-up handler: "reconfigured", as the master
  // says of a second configuration of a node).
  const auto booted_after_lss = [&] {
    const std::string out = master.output();
    const auto lss = out.find("got node-ID 17, stored");
    return lss != std::string::npos && out.find("node 17: reconfigured", lss) != std::string::npos;
  };
  const auto end = std::chrono::steady_clock::now() + 30s;
  while (!booted_after_lss() && std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_TRUE(booted_after_lss()) << master.output();
  EXPECT_EQ(master.stop(SIGINT, 5000ms), std::optional<int>(0));
}

}  // namespace
