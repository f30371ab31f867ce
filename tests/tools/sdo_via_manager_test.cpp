// `cfgmgr sdo --via-manager`: the tool as an SDO requesting device (CiA DSP 302 §7) against
// `cfgmgr master` with its SDO manager and `cfgmgr simulate` slaves, over UDP multicast inside a
// private network namespace (tests/support/run_in_netns.sh); elsewhere those tests skip. A
// second SRD, written with python-can alone from the spec (tests/io/python/
// sdo_requesting_device.py), holds a slave's default SDO where a test needs it taken.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "python_peer.hpp"
#include "tool_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using tool_test::cfgmgr;
using tool_test::Json;
using tool_test::JsonParser;
using tool_test::ScratchDir;

constexpr const char* kPort = "43183";
const std::string kUrl = test_support::udp_test_url(kPort);

// The tool's own node-ID as an SRD: free in every network below.
constexpr const char* kToolNode = "120";

std::string master_data(const std::string& name) {
  return tool_test::data_path("master/" + name);
}
std::string manager_data(const std::string& name) {
  return tool_test::data_path("sdo_manager/" + name);
}

TEST(SdoViaManager, UsageErrorsExit2BeforeTheBusIsOpened) {
  ScratchDir dir;
  const auto run = [&](std::vector<std::string> args) {
    args.insert(args.begin(), {"sdo", "--bus", kUrl});
    return cfgmgr(dir, args);
  };
  const auto no_id = run({"read", "--via-manager", "5", "1000"});
  EXPECT_EQ(no_id.exit_code, 2);
  EXPECT_THAT(no_id.err, HasSubstr("--via-manager needs --node-id"));
  const auto no_manager = run({"read", "--node-id", "120", "5", "1000"});
  EXPECT_EQ(no_manager.exit_code, 2);
  EXPECT_THAT(no_manager.err, HasSubstr("--node-id is for --via-manager"));
  const auto same = run({"read", "--via-manager", "--node-id", "5", "5", "1000"});
  EXPECT_EQ(same.exit_code, 2);
  EXPECT_THAT(same.err, HasSubstr("that is NODE"));
  const auto bad = run({"read", "--via-manager", "--node-id", "128", "5", "1000"});
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr("--node-id 128: expected a node-ID 1..127"));
  EXPECT_THAT(cfgmgr(dir, {"sdo", "--help"}).out, HasSubstr("--via-manager"));
}

TEST(SdoViaManager, EndToEndOverUdp) {
  tool_test::run_in_private_netns("SdoViaManagerInNetns.*");
}

class SdoViaManagerInNetns : public ::testing::Test {
 protected:
  void SetUp() override { REQUIRE_ISOLATED_MULTICAST(); }
  void TearDown() override {
    if (master_) (void)master_->stop(SIGINT, 3000ms);
    if (devices_) (void)devices_->stop(SIGINT, 3000ms);
  }

  // Slaves 2 (`node2`) and 3 (slave.eds) on `cfgmgr simulate`, then the master of
  // tests/data/sdo_manager/manager.dcf as node 1 (its 1F00h turns the SDO manager on; 1F02h
  // is its pool of COB-IDs 681h-688h), started once both slaves are operational.
  void start_network(const std::string& node2) {
    devices_.emplace("cfgmgr",
                     std::vector<std::string>{"simulate", "--bus", kUrl, "--for", "60",
                                              node2 + "@2", master_data("slave.eds") + "@3"},
                     dir_ / "sim.out", dir_ / "sim.err");
    ASSERT_TRUE(devices_->started());
    ASSERT_TRUE(devices_->wait_until_simulating()) << devices_->output();
    master_.emplace(
        "cfgmgr",
        std::vector<std::string>{"master", manager_data("manager.dcf"), "--bus", kUrl, "--node-id",
                                 "1", "--run-for", "60", "--json-events", dir_ / "events.jsonl"},
        dir_ / "master.out", dir_ / "master.err");
    ASSERT_TRUE(master_->started());
    ASSERT_TRUE(master_->wait_for_output("NMT start-up complete"))
        << tool_test::slurp(dir_ / "master.err");
  }

  // The python SRD (node 127) registers once the master started node 2, connects to node 2's
  // default SDO, reads its 1018h sub 1 and holds the connection 3 s before it releases it.
  void start_network_with_holder(const std::string& node2) {
    holder_.emplace(
        test_support::python_script("sdo_requesting_device.py"),
        std::vector<std::string>{test_support::kUdpTestGroup, kPort, "40", "127", "2", "3"});
    ASSERT_EQ(holder_->read_line(), "READY");
    start_network(node2);
    while (auto line = holder_->read_line()) {
      holder_lines_ += *line + "\n";
      if (line->rfind("READ ", 0) == 0 || *line == "TIMEOUT") break;
    }
  }
  // The holder's exit code once it released its connection and ended.
  int finish_holder() {
    while (auto line = holder_->read_line()) holder_lines_ += *line + "\n";
    return holder_->finish();
  }

  tool_test::RunResult sdo(std::vector<std::string> args) {
    args.insert(args.begin(), {"sdo", "--bus", kUrl});
    return cfgmgr(dir_, args);
  }
  static Json json_of(const tool_test::RunResult& r) { return tool_test::json_object_of(r.out); }
  // The master's events after it stopped.
  std::vector<Json> master_events() {
    (void)master_->stop(SIGINT, 3000ms);
    master_.reset();
    return tool_test::json_lines(dir_ / "events.jsonl");
  }
  static std::vector<const Json*> events_of(const std::vector<Json>& events,
                                            const std::string& name, int node) {
    std::vector<const Json*> out;
    for (const auto& e : events) {
      if (e.get("event")->string == name && static_cast<int>(e.get("node_id")->number) == node) {
        out.push_back(&e);
      }
    }
    return out;
  }

  ScratchDir dir_;
  std::optional<tool_test::SpawnedTool> devices_;
  std::optional<tool_test::SpawnedTool> master_;
  std::optional<test_support::PythonPeer> holder_;
  std::string holder_lines_;
};

// §7.2.1 registration, §7.2.2 a connection on the slave's default SDO while no one holds it,
// §7.2.3 1F01h with slave 0 at the end: the manager's events show each step for node 120 and
// no loss of it (the tool stays on the bus until the manager cleared its entries).
TEST_F(SdoViaManagerInNetns, ReadsAndWritesOnTheDefaultSdoTheManagerGrants) {
  start_network(master_data("slave.eds"));
  // slave.eds: 1018h sub 1 (Vendor-ID) = 0000ABCDh.
  const auto read = sdo(
      {"read", "--via-manager", "--node-id", kToolNode, "--json", "2", "1018:1", "--type", "u32"});
  ASSERT_EQ(read.exit_code, 0) << read.err << tool_test::slurp(dir_ / "master.err");
  const Json json = json_of(read);
  EXPECT_TRUE(json.get("ok")->boolean);
  EXPECT_EQ(json.get("hex")->string, "cdab0000");
  // CiA 301 §7.2.4.1: node 2's default SDO, 602h / 582h.
  EXPECT_EQ(json.get("cob_id_client_to_server")->number, 0x602);
  EXPECT_EQ(json.get("cob_id_server_to_client")->number, 0x582);
  const Json* via = json.get("via_manager");
  ASSERT_TRUE(via != nullptr && via->is(Json::Kind::Object)) << read.out;
  EXPECT_EQ(via->get("node_id")->number, 120);
  EXPECT_EQ(via->get("client_index")->number, 0x1281);

  // A write through the manager, read back on the default SDO without it.
  const auto write =
      sdo({"write", "--via-manager", "--node-id", kToolNode, "3", "1017", "150", "--type", "u16"});
  ASSERT_EQ(write.exit_code, 0) << write.err;
  const auto back = sdo({"read", "3", "1017", "--type", "u16"});
  EXPECT_EQ(back.exit_code, 0) << back.err;
  EXPECT_EQ(back.out, "150 (0x0096)\n");

  const auto events = master_events();
  EXPECT_EQ(events_of(events, "srd_registered", 120).size(), 2U);
  const auto established = events_of(events, "sdo_connection_established", 120);
  ASSERT_EQ(established.size(), 2U);
  for (const Json* e : established) {
    EXPECT_EQ(e->get("connection")->get("client_index")->number, 0x1281);
    EXPECT_EQ(e->get("connection")->get("server_index")->number, 0x1200);
  }
  // Each run releases both of its connections (to the slave and to the manager).
  EXPECT_EQ(events_of(events, "sdo_connection_released", 120).size(), 4U);
  EXPECT_EQ(events_of(events, "srd_deregistered", 120).size(), 2U);
  EXPECT_TRUE(events_of(events, "srd_lost", 120).empty());
  EXPECT_TRUE(events_of(events, "heartbeat_lost", 120).empty());
}

// §7.2.2: while another SRD holds node 2's default SDO, the manager configures a free server
// channel of node 2 (1201h, tests/data/sdo_manager/slave_channels.eds) with two COB-IDs of its
// pool (1F02h of manager.dcf: 681h-688h).
TEST_F(SdoViaManagerInNetns, GetsAnotherServerChannelWhileTheDefaultSdoIsTaken) {
  REQUIRE_PYTHON_CAN();
  start_network_with_holder(manager_data("slave_channels.eds"));
  ASSERT_THAT(holder_lines_, HasSubstr("CONNECTED 1281 00000602 00000582 02"));

  const auto read = sdo(
      {"read", "--via-manager", "--node-id", kToolNode, "--json", "2", "1018:1", "--type", "u32"});
  ASSERT_EQ(read.exit_code, 0) << read.err << tool_test::slurp(dir_ / "master.err");
  const Json json = json_of(read);
  EXPECT_EQ(json.get("hex")->string, "cdab0000");  // slave_channels.eds: 0000ABCDh
  const auto request = json.get("cob_id_client_to_server")->number;
  const auto response = json.get("cob_id_server_to_client")->number;
  EXPECT_GE(request, 0x681);
  EXPECT_LE(request, 0x688);
  EXPECT_GE(response, 0x681);
  EXPECT_LE(response, 0x688);
  EXPECT_NE(request, response);

  EXPECT_EQ(finish_holder(), 0) << holder_lines_;
  const auto events = master_events();
  const auto established = events_of(events, "sdo_connection_established", 120);
  ASSERT_EQ(established.size(), 1U);
  EXPECT_EQ(established[0]->get("connection")->get("server_node_id")->number, 2);
  EXPECT_EQ(established[0]->get("connection")->get("server_index")->number, 0x1201);
}

// §7.2.3 1F10h error code 03h: node 2 (slave.eds) has no server channel but its default SDO,
// which another SRD holds. The tool says why in the spec's words and exits 1.
TEST_F(SdoViaManagerInNetns, ARefusalIsReportedInTheSpecsWordsWithExit1) {
  REQUIRE_PYTHON_CAN();
  start_network_with_holder(master_data("slave.eds"));
  ASSERT_THAT(holder_lines_, HasSubstr("CONNECTED 1281 00000602 00000582 02"));

  const auto read = sdo({"read", "--via-manager", "--node-id", kToolNode, "2", "1018:1"});
  EXPECT_EQ(read.exit_code, 1) << read.err;
  EXPECT_THAT(read.err, HasSubstr("no more free server SDO entries on slave S"));
  EXPECT_EQ(read.out, "");
  EXPECT_EQ(finish_holder(), 0) << holder_lines_;
  // The tool de-registered after the refusal.
  const auto events = master_events();
  EXPECT_EQ(events_of(events, "sdo_connection_refused", 120).size(), 1U);
  EXPECT_EQ(events_of(events, "srd_deregistered", 120).size(), 1U);
  EXPECT_TRUE(events_of(events, "srd_lost", 120).empty());
}

// §7.2.4 1: no manager answers the Dynamic SDO Request: exit 3 after --manager-timeout.
TEST_F(SdoViaManagerInNetns, NoManagerOnTheBusIsAnIoErrorWithExit3) {
  devices_.emplace("cfgmgr",
                   std::vector<std::string>{"simulate", "--bus", kUrl, "--for", "30",
                                            master_data("slave.eds") + "@2"},
                   dir_ / "sim.out", dir_ / "sim.err");
  ASSERT_TRUE(devices_->started());
  ASSERT_TRUE(devices_->wait_until_simulating()) << devices_->output();
  const auto read = sdo(
      {"read", "--via-manager", "--node-id", kToolNode, "--manager-timeout", "1", "2", "1018:1"});
  EXPECT_EQ(read.exit_code, 3) << read.err;
  EXPECT_THAT(read.err, HasSubstr("no SDO manager answered"));
}

// A node-ID another node answers on is not the tool's to take (CiA 301: node-IDs are unique).
TEST_F(SdoViaManagerInNetns, ANodeIdInUseIsRefusedWithExit2) {
  start_network(master_data("slave.eds"));
  const auto read = sdo({"read", "--via-manager", "--node-id", "3", "2", "1018:1"});
  EXPECT_EQ(read.exit_code, 2) << read.err;
  EXPECT_THAT(read.err, HasSubstr("--node-id 3: node 3 answers on the bus"));
}

}  // namespace
