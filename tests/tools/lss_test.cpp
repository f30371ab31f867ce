// `cfgmgr lss` (CiA 305 Layer Setting Services) against `cfgmgr simulate FILE@255` devices, over
// UDP multicast inside a private network namespace (tests/support/run_in_netns.sh); elsewhere
// those tests skip. The devices are tests/data/lss/lss_io.eds (1018h: vendor 7E57C0DEh, product
// 00000305h, revision 00010002h, serial 00001001h; 1000h 00030191h) and lss_io_1003.dcf (the
// same with [DeviceComissioning] LSS_SerialNumber 00001003h: their addresses differ in one bit).
// An LSS master written with python-can alone (tests/io/python/lss_master.py) is the
// independent peer of the simulated LSS slave.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "prerequisite.hpp"
#include "python_peer.hpp"
#include "tool_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::cfgmgr;
using tool_test::ScratchDir;

constexpr const char* kPort = "43193";
const std::string kUrl = test_support::udp_test_url(kPort);

const std::string kIo = tool_test::data_path("lss/lss_io.eds");
const std::string kIo1003 = tool_test::data_path("lss/lss_io_1003.dcf");
constexpr const char* kAddress1001 = "7E57C0DE:00000305:00010002:00001001";
constexpr const char* kAddress1003 = "7E57C0DE:00000305:00010002:00001003";

// ------------------------------------------------------------------- no network -------------

TEST(Lss, HelpDocumentsTheActionsExamplesAndExitCodes) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"lss", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text : {"scan", "set-id", "inquire", "set-bitrate",
                           "Examples:", "Exit codes:", "4  a device refused"}) {
    EXPECT_THAT(r.out, HasSubstr(text));
  }
}

TEST(Lss, UsageErrorsExit2BeforeTheBusIsOpened) {
  ScratchDir dir;
  const auto lss = [&](std::vector<std::string> args) {
    args.insert(args.begin(), {"lss", "--bus", kUrl});
    return cfgmgr(dir, args);
  };
  const auto address = lss({"set-id", "7E57C0DE:305:10002", "5"});
  EXPECT_EQ(address.exit_code, 2);
  EXPECT_THAT(address.err, HasSubstr("expected VENDOR:PRODUCT:REVISION:SERIAL"));
  const auto too_long = lss({"set-id", "7E57C0DE:305:10002:123456789", "5"});
  EXPECT_EQ(too_long.exit_code, 2);
  const auto node = lss({"set-id", kAddress1001, "256"});
  EXPECT_EQ(node.exit_code, 2);
  EXPECT_THAT(node.err, HasSubstr("NODE-ID 256"));
  // CiA 305 bit timing table: 1000, 800, 500, 250, 125, (reserved), 50, 20, 10 kbit/s.
  const auto rate = lss({"set-bitrate", "100"});
  EXPECT_EQ(rate.exit_code, 2);
  EXPECT_THAT(rate.err, HasSubstr("1000, 800, 500, 250, 125, 50, 20 or 10"));
  const auto sim = cfgmgr(dir, {"lss", "--bus", "sim:", "scan"});
  EXPECT_EQ(sim.exit_code, 2);
  const auto bad_url = cfgmgr(dir, {"lss", "--bus", "udp://10.0.0.1:1", "scan"});
  EXPECT_EQ(bad_url.exit_code, 2);
  EXPECT_THAT(bad_url.err, HasSubstr("--bus"));
  const auto product = lss({"scan", "--all", "--product", "7E57C0DE"});
  EXPECT_EQ(product.exit_code, 2);
  EXPECT_THAT(product.err, HasSubstr("expected VENDOR:PRODUCT"));
  const auto without_all = lss({"scan", "--product", "7E57C0DE:305"});
  EXPECT_EQ(without_all.exit_code, 2);
  EXPECT_THAT(without_all.err, HasSubstr("--product and --device go with --all"));
}

TEST(Lss, SimulateUnconfiguredNeedsLssSupportedInTheFile) {
  ScratchDir dir;
  const auto r =
      cfgmgr(dir, {"simulate", "--for", "0.1", tool_test::data_path("lss/no_lss.eds") + "@255"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("no_lss.eds: error: cannot simulate it unconfigured (@255)"));
  EXPECT_THAT(r.err, HasSubstr("LSS_Supported=1"));
  const auto range = cfgmgr(dir, {"simulate", "--for", "0.1", kIo + "@254"});
  EXPECT_EQ(range.exit_code, 2);
  EXPECT_THAT(range.err, HasSubstr("255 or 'unconfigured'"));
}

// The --state file of a DEVICE@255 is named by its LSS address; two devices with one
// address would share it, so simulate refuses them (before the bus) instead of letting one
// overwrite the other's stored node-ID. Without --state they may run (CiA 305's uniqueness is
// then the user's business, e.g. to test a master against it); devices with different addresses
// have a file each (LssInNetns.SimulateStateKeepsTheNodeIdLssStoredOverARestart).
TEST(Lss, SimulateStateRefusesTwoUnconfiguredDevicesWithOneLssAddress) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"simulate", "--for", "0.1", "--state", dir / "state", kIo + "@255",
                              kIo + "@unconfigured"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("have the same LSS address " + std::string(kAddress1001) +
                               " and would share the state file "
                               "lss-7E57C0DE-00000305-00010002-00001001.saved"));
  EXPECT_FALSE(
      std::filesystem::exists(dir / "state/lss-7E57C0DE-00000305-00010002-00001001.saved"));
}

// sim:?unconfigured=LIST: the devices of those nodes power on without node-ID, as out of the box;
// without LSS the master cannot reach them. tests/data/lss/nodelist.cpj: node 16, lss_io_1003.dcf.
TEST(Lss, SimUnconfiguredDeviceSendsNoBootUpSoTheMasterMissesIt) {
  ScratchDir dir;
  const std::string cpj = tool_test::data_path("lss/nodelist.cpj");
  const auto node16 = [](const tool_test::Json& report) -> const tool_test::Json* {
    for (const auto& n : report.get("nodes")->array) {
      if (n.get("node_id")->number == 16) return &n;
    }
    return nullptr;
  };
  const auto configured =
      cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--json", dir / "configured.json"});
  EXPECT_EQ(configured.exit_code, 0) << configured.err;
  const auto unconfigured = cfgmgr(dir, {"push", cpj, "--bus", "sim:?unconfigured=16",
                                         "--boot-time", "1", "--json", dir / "unconfigured.json"});
  // CiA 302-2 Table 1: status B, the mandatory slave did not answer.
  EXPECT_EQ(unconfigured.exit_code, 4) << unconfigured.err;
  const auto report = tool_test::json_object_of(tool_test::slurp(dir / "unconfigured.json"));
  ASSERT_NE(node16(report), nullptr);
  EXPECT_EQ(node16(report)->get("status")->string, "B");
  // A node whose DCF does not say LSS_Supported=1 cannot start unconfigured.
  const auto no_lss = cfgmgr(
      dir, {"push", tool_test::test_network("nodelist.cpj"), "--bus", "sim:?unconfigured=3"});
  EXPECT_NE(no_lss.exit_code, 0);
  EXPECT_THAT(no_lss.err, HasSubstr("cannot simulate node 3 unconfigured"));
  EXPECT_THAT(no_lss.err, HasSubstr("LSS_Supported=1"));
  const auto bad = cfgmgr(dir, {"push", cpj, "--bus", "sim:?unconfigured=200"});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr("unconfigured=200: '200' is no node-ID 1..127"));
}

// --------------------------------------------------------- over UDP, in a namespace ----------

TEST(Lss, EndToEndOverUdp) {
  tool_test::run_in_private_netns("LssInNetns.*");
}

class LssInNetns : public ::testing::Test {
 protected:
  void SetUp() override { REQUIRE_ISOLATED_MULTICAST(); }
  std::string sim_out() const { return devices_.out(); }
  // sim_out() once it holds `text` (what the devices print follows the frames that caused it).
  std::string sim_out_with(const std::string& text) const {
    const auto end = std::chrono::steady_clock::now() + 5s;
    while (sim_out().find(text) == std::string::npos && std::chrono::steady_clock::now() < end) {
      std::this_thread::sleep_for(20ms);
    }
    return sim_out();
  }

  // The scan step is generous: the devices answer from another process on a shared machine.
  tool_test::RunResult lss(std::vector<std::string> args) {
    args.insert(args.begin(), {"lss", "--bus", kUrl, "--scan-step", "40", "--timeout", "500"});
    return cfgmgr(dir_, args);
  }
  static std::vector<std::string> addresses_of(const tool_test::RunResult& r) {
    const auto json = tool_test::json_object_of(r.out);
    std::vector<std::string> out;
    const auto* list = json.get("unconfigured");
    if (list == nullptr) return out;
    for (const auto& d : list->array) out.push_back(d.get("address")->string);
    return out;
  }

  ScratchDir dir_;
  tool_test::SimulatedDevices devices_{dir_.path(), kUrl, {"-v"}};
};

TEST_F(LssInNetns, ScanListsTheUnconfiguredDevicesAndSetIdBootsOne) {
  devices_.simulate({kIo + "@255", kIo1003 + "@unconfigured"});
  EXPECT_THAT(sim_out(), HasSubstr("unconfigured (LSS address " + std::string(kAddress1001)));
  EXPECT_THAT(sim_out(), HasSubstr("unconfigured (LSS address " + std::string(kAddress1003)));

  // Fastscan finds both, lowest first, and leaves them without node-ID.
  const auto scan = lss({"--json", "scan"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_EQ(addresses_of(scan), (std::vector<std::string>{kAddress1001, kAddress1003}));
  const auto json = tool_test::json_object_of(scan.out);
  const auto& first = json.get("unconfigured")->array.at(0);
  EXPECT_EQ(first.get("vendor_id")->number, 0x7E57C0DE);
  EXPECT_EQ(first.get("product_code")->number, 0x305);
  EXPECT_EQ(first.get("revision")->number, 0x10002);
  EXPECT_EQ(first.get("serial")->number, 0x1001);
  EXPECT_THAT(sim_out(), Not(HasSubstr("tx  705#00")));

  // set-id: the device boots as node 5 and answers SDO with the file's 1000h.
  const auto set = lss({"set-id", kAddress1003, "5"});
  ASSERT_EQ(set.exit_code, 0) << set.err;
  EXPECT_THAT(set.out, HasSubstr("node-ID 5 configured and stored; the device boots with it now"));
  EXPECT_THAT(sim_out_with("tx  705#00"), HasSubstr("tx  705#00"));
  const auto read = cfgmgr(dir_, {"sdo", "--bus", kUrl, "read", "5", "1000", "--type", "u32"});
  EXPECT_EQ(read.exit_code, 0) << read.err;
  EXPECT_EQ(read.out, "197009 (0x00030191)\n");

  // Now only the other one is unconfigured; inquire by address sees node 5.
  const auto again = lss({"--json", "scan"});
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(addresses_of(again), (std::vector<std::string>{kAddress1001}));
  const auto inquire = lss({"inquire", "7E57C0DE:305:10002:1003h"});
  ASSERT_EQ(inquire.exit_code, 0) << inquire.err;
  EXPECT_EQ(inquire.out, std::string(kAddress1003) + "  node-ID 5\n");
}

TEST_F(LssInNetns, SimulateStateKeepsTheNodeIdLssStoredOverARestart) {
  // CiA 305 store configuration: the node-ID survives a power cycle. With --state DIR it
  // survives a restart of `cfgmgr simulate`: the device started @255 boots as node 5 at once,
  // without LSS, and Fastscan finds no unconfigured device.
  const std::string state = dir_ / "state";
  devices_.simulate({"--state", state, kIo + "@255"});
  const auto set = lss({"set-id", kAddress1001, "5"});
  ASSERT_EQ(set.exit_code, 0) << set.err;
  EXPECT_THAT(sim_out_with("tx  705#00"), HasSubstr("tx  705#00"));
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(state) /
                                      "lss-7E57C0DE-00000305-00010002-00001001.saved"));

  devices_.simulate({"--state", state, kIo + "@255"});
  EXPECT_THAT(sim_out(), HasSubstr("node 5 (node-ID stored by LSS): " + kIo));
  EXPECT_THAT(sim_out_with("tx  705#00"), HasSubstr("tx  705#00")) << "the boot-up of node 5";
  EXPECT_THAT(sim_out(), Not(HasSubstr("rx  7E5#"))) << "no LSS before it";
  const auto read = cfgmgr(dir_, {"sdo", "--bus", kUrl, "read", "5", "1000", "--type", "u32"});
  EXPECT_EQ(read.out, "197009 (0x00030191)\n") << read.err;
  const auto scan = lss({"--json", "scan"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_TRUE(addresses_of(scan).empty());

  // Without --state the same device is unconfigured again.
  devices_.simulate({kIo + "@255"});
  EXPECT_THAT(sim_out(), HasSubstr("unconfigured (LSS address " + std::string(kAddress1001)));
}

TEST_F(LssInNetns, ScanAllListsConfiguredAndUnconfiguredDevicesWithTheirNodeIds) {
  // lss_io.eds runs as node 7, lss_io_1003.dcf unconfigured: Fastscan finds only the second;
  // --all looks for every device of its product (identify remote slave 46h-4Bh) and inquires
  // each one's node-ID (5Eh).
  devices_.simulate({kIo + "@7", kIo1003 + "@255"});
  const auto scan = lss({"--json", "scan", "--all"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_EQ(addresses_of(scan), (std::vector<std::string>{kAddress1003}));
  const auto json = tool_test::json_object_of(scan.out);
  const auto* devices = json.get("devices");
  ASSERT_NE(devices, nullptr) << scan.out;
  ASSERT_EQ(devices->array.size(), 2U) << scan.out;
  EXPECT_EQ(devices->array[0].get("address")->string, kAddress1001);
  EXPECT_EQ(devices->array[0].get("serial")->number, 0x1001);
  EXPECT_EQ(devices->array[0].get("node_id")->number, 7);
  EXPECT_EQ(devices->array[1].get("address")->string, kAddress1003);
  EXPECT_EQ(devices->array[1].get("node_id")->kind, tool_test::Json::Kind::Null);

  const auto text = lss({"scan", "--all"});
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_EQ(text.out, std::string(kAddress1001) + "  node-ID 7\n" + kAddress1003 +
                          "  node-ID FFh (unconfigured)\n");
  EXPECT_THAT(text.err, HasSubstr("2 devices, 1 unconfigured"));
  // Nothing was assigned: the unconfigured one sent no boot-up.
  EXPECT_THAT(sim_out(), Not(HasSubstr("tx  7FF#")));
}

TEST_F(LssInNetns, ScanAllFindsConfiguredDevicesOfTheProductsItIsGiven) {
  // No unconfigured device names a product: only --device (or --product) does.
  devices_.simulate({kIo + "@7"});
  const auto none = lss({"--json", "scan", "--all"});
  ASSERT_EQ(none.exit_code, 0) << none.err;
  EXPECT_TRUE(tool_test::json_object_of(none.out).get("devices")->array.empty()) << none.out;
  const auto found = lss({"scan", "--all", "--device", kIo});
  ASSERT_EQ(found.exit_code, 0) << found.err;
  EXPECT_EQ(found.out, std::string(kAddress1001) + "  node-ID 7\n");
  const auto other = lss({"scan", "--all", "--product", "7E57C0DE:306"});
  ASSERT_EQ(other.exit_code, 0) << other.err;
  EXPECT_EQ(other.out, "");
}

TEST_F(LssInNetns, ANodeIdOutOfRangeIsAUsageErrorAndAnAbsentDeviceExits4InWords) {
  devices_.simulate({kIo + "@255"});
  // CiA 305 configure node-ID: 1..127 or FFh; 0 and 128 are no node-ID and never reach the bus.
  for (const char* id : {"0", "128"}) {
    const auto r = lss({"set-id", kAddress1001, id});
    EXPECT_EQ(r.exit_code, 2) << id;
    EXPECT_THAT(r.err, HasSubstr(std::string("NODE-ID ") + id +
                                 ": expected a node-ID 1..127 (or 255, 'unconfigured')"));
  }
  // Left unconfigured and in waiting: Fastscan still finds it.
  const auto scan = lss({"--json", "scan"});
  EXPECT_EQ(addresses_of(scan), (std::vector<std::string>{kAddress1001}));
  const auto absent = lss({"set-id", kAddress1003, "5"});
  EXPECT_EQ(absent.exit_code, 4);
  EXPECT_THAT(absent.err, HasSubstr(std::string("LSS address ") + kAddress1003 +
                                    ": switch state selective: no answer within 500 ms"));
}

TEST_F(LssInNetns, PythonCanLssMasterGivesTheSimulatedDeviceItsNodeId) {
  if (auto missing = test_support::python_can_missing()) PREREQUISITE_MISSING(*missing);
  devices_.simulate({kIo + "@255"});
  test_support::PythonPeer master(test_support::python_script("lss_master.py"),
                                  {test_support::kUdpTestGroup, kPort, "10", "7E57C0DE", "00000305",
                                   "00010002", "00001001", "10"});
  ASSERT_EQ(master.read_line(), "READY");
  // CiA 305: switch state selective answered 44h; configure node-ID 11h and store 17h, each
  // with error code 0; then, back in waiting, the boot-up of node 10h.
  EXPECT_EQ(master.read_all(),
            (std::vector<std::string>{"ANSWER 7E4#4400000000000000", "ANSWER 7E4#1100000000000000",
                                      "ANSWER 7E4#1700000000000000", "BOOT 710#00", "END"}));
  EXPECT_EQ(master.finish(), 0);
  const auto read = cfgmgr(dir_, {"sdo", "--bus", kUrl, "read", "16", "1000", "--type", "u32"});
  EXPECT_EQ(read.out, "197009 (0x00030191)\n") << read.err;
}

}  // namespace
