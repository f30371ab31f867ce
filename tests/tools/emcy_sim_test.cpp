// Emergencies (CiA 301 §7.2.7) end to end on sim: with generated networks (generated_network.hpp):
// the devices raise EMCYs at simulated times (sim:?emcy=NODE@MS:CODE[:REGISTER], through their
// EmcyProducer), and `cfgmgr master` and `cfgmgr push` report them: the event lines, the
// --json-events fields, the count per node in push's table and --json, a boot error that says
// the node sent an EMCY during its boot (the push table's words and its stderr line). The words of
// the codes are CiA 301 Table 21's.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "generated_network.hpp"
#include "push_test_support.hpp"

namespace {

using push_test::nodes_of;
using push_test::parse_json;
using tool_test::cfgmgr;
using tool_test::events_of;
using tool_test::Json;
using tool_test::json_lines;
using tool_test::ScratchDir;

generated::NetworkSpec small_network() {
  generated::NetworkSpec spec;
  spec.nodes = 2;
  spec.values = 2;
  spec.pdos = 0;
  return spec;
}

TEST(EmcySim, MasterReportsEachEmergencyItsResetAndAFloodsCount) {
  ScratchDir dir;
  const std::string cpj = generated::write_network(dir.path() / "net", small_network());
  const std::string events = dir / "events.jsonl";
  // Node 1: one 8130h with the communication bit at 500 ms. Node 2: 8 x 2310h at 700 ms (5
  // reported, 3 counted: MasterOptions::emcy's bound), then its error reset at 1200 ms.
  std::string url = "sim:?emcy=1@500:8130:10";
  for (int i = 0; i < 8; ++i) url += "&emcy=2@700:2310:02";
  url += "&emcy=2@1200:0000";
  auto r = cfgmgr(dir, {"master", cpj, "--bus", url, "--run-for", "2", "--json-events", events});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("0.500  node 1: emergency 8130h life guard error or heartbeat error; error "
                       "register 11h (generic, communication); manufacturer bytes 00 00 00 00 00"),
            std::string::npos)
      << r.err;
  // The generated devices are CiA 401 modules (1000h 000F0191h): 2310h in the profile's words.
  EXPECT_NE(r.err.find("1.200  node 2: 3 more emergencies 2310h current at outputs too high "
                       "(overload) (CiA 401); current, device output side not reported (at most "
                       "5 per 1000 ms per node and code)"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("1.200  node 2: emergency ended: 0000h error reset or no error"),
            std::string::npos)
      << r.err;
  const auto lines = json_lines(events);
  const auto emcys = events_of(lines, "emergency");
  ASSERT_EQ(emcys.size(), 7U);  // 1 of node 1, 5 of node 2, node 2's reset
  const Json* first = emcys[0]->get("emergency");
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(emcys[0]->get("node_id")->number, 1);
  EXPECT_EQ(first->get("error_code")->number, 0x8130);
  EXPECT_EQ(first->get("error_code_hex")->string, "8130");
  EXPECT_EQ(first->get("error_register")->number, 0x11);
  EXPECT_EQ(first->get("manufacturer")->string, "0000000000");
  EXPECT_EQ(first->get("code_text")->string, "8130h life guard error or heartbeat error");
  EXPECT_EQ(first->get("register_text")->string, "generic, communication");
  EXPECT_FALSE(first->get("ends_error")->boolean);
  EXPECT_TRUE(emcys[6]->get("emergency")->get("ends_error")->boolean);
  const auto floods = events_of(lines, "emergency_flood");
  ASSERT_EQ(floods.size(), 1U);
  EXPECT_EQ(floods[0]->get("node_id")->number, 2);
  EXPECT_EQ(floods[0]->get("emergency")->get("suppressed")->number, 3);
}

TEST(EmcySim, AFloodWhoseWindowIsOpenWhenTheRunEndsIsSaidAtTheEnd) {
  ScratchDir dir;
  const std::string cpj = generated::write_network(dir.path() / "net", small_network());
  const std::string events = dir / "events.jsonl";
  // 8 x 2310h at 700 ms; the window (1000 ms) would end at 1.700 s, the run ends at 1.000 s.
  std::string url = "sim:?";
  for (int i = 0; i < 8; ++i) url += "emcy=2@700:2310:02&";
  url.pop_back();
  auto r = cfgmgr(dir, {"master", cpj, "--bus", url, "--run-for", "1", "--json-events", events});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("1.000  node 2: 3 more emergencies 2310h"), std::string::npos) << r.err;
  const auto floods = events_of(json_lines(events), "emergency_flood");
  ASSERT_EQ(floods.size(), 1U) << r.err;
  EXPECT_EQ(floods[0]->get("emergency")->get("suppressed")->number, 3);
}

TEST(EmcySim, PushCountsTheEmergenciesOfAFloodStillOpenWhenItEnds) {
  ScratchDir dir;
  const std::string cpj = generated::write_network(dir.path() / "net", small_network());
  const std::string report = dir / "report.json";
  // 9 EMCYs of node 1 at 5 ms: 5 reported, 4 counted; push ends long before the window does.
  std::string url = "sim:?";
  for (int i = 0; i < 9; ++i) url += "emcy=1@5:5000&";
  url.pop_back();
  auto r = cfgmgr(dir, {"push", cpj, "--bus", url, "--json", report});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  const auto nodes = nodes_of(json);
  ASSERT_EQ(nodes.size(), 2U) << r.err;
  EXPECT_EQ(nodes.at(1)->get("emergencies")->number, 9);
  EXPECT_NE(r.err.find("node 1: 4 more emergencies 5000h"), std::string::npos) << r.err;
}

TEST(EmcySim, TheCobIdIsThe1014hOfTheNodesDcf) {
  ScratchDir dir;
  auto spec = small_network();
  spec.emcy_cob_id[1] = 0x0A1;  // the device sends its EMCY on 0A1h, not 81h
  const std::string cpj = generated::write_network(dir.path() / "net", spec);
  const std::string events = dir / "events.jsonl";
  auto r = cfgmgr(dir, {"master", cpj, "--bus", "sim:?emcy=1@500:1000", "--run-for", "1",
                        "--json-events", events});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto lines = json_lines(events);
  const auto emcys = events_of(lines, "emergency");
  ASSERT_EQ(emcys.size(), 1U) << r.err;
  EXPECT_EQ(emcys[0]->get("node_id")->number, 1);
  EXPECT_EQ(emcys[0]->get("emergency")->get("code_text")->string, "1000h generic error");
}

TEST(EmcySim, PushCountsEmergenciesPerNodeAndABootErrorSaysTheOneDuringTheBoot) {
  ScratchDir dir;
  auto spec = small_network();
  // Node 2 is expected with another device type: boot error C (CiA 302-2 Table 1).
  spec.master_dcf = true;
  auto other = spec.identity;
  other.device_type = 0x000F0192;
  spec.expected[2] = other;
  const std::string cpj = generated::write_network(dir.path() / "net", spec);
  const std::string report = dir / "report.json";
  // SDO answers 20 ms late: the EMCYs at 5 ms come while the master identifies the nodes.
  auto r = cfgmgr(
      dir, {"push", cpj, "--bus", "sim:?latency_ms=20&emcy=1@5:5000&emcy=1@6:6100&emcy=2@5:8130:10",
            "--json", report});
  EXPECT_EQ(r.exit_code, 4) << r.err;  // a mandatory node failed
  const Json json = parse_json(report);
  const auto nodes = nodes_of(json);
  ASSERT_EQ(nodes.size(), 2U) << r.err;
  EXPECT_EQ(nodes.at(1)->get("emergencies")->number, 2);
  EXPECT_EQ(nodes.at(2)->get("emergencies")->number, 1);
  EXPECT_EQ(nodes.at(2)->get("status")->string, "C");
  const std::string message = nodes.at(2)->get("message")->string;
  EXPECT_NE(message.find("; the node sent emergency 8130h life guard error or heartbeat error "
                         "during its boot"),
            std::string::npos)
      << message;
  // The table: the emcy column holds the count.
  std::istringstream table(r.out);
  std::string header, row1, row2;
  std::getline(table, header);
  std::getline(table, row1);
  std::getline(table, row2);
  EXPECT_NE(header.find("  entries  emcy  time"), std::string::npos) << r.out;
  EXPECT_NE(row1.find("     2  "), std::string::npos) << r.out;
  EXPECT_NE(row2.find("     1  "), std::string::npos) << r.out;
  // The line of the boot error on stderr says it too.
  EXPECT_NE(r.err.find("node 2: boot error C: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("during its boot"), std::string::npos) << r.err;
}

TEST(EmcySim, AMalformedEmcyParameterIsAUsageError) {
  ScratchDir dir;
  const std::string cpj = generated::write_network(dir.path() / "net", small_network());
  auto r = cfgmgr(dir, {"master", cpj, "--bus", "sim:?emcy=1@x:8130"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("emcy=1@x:8130: expected NODE@MS:CODE[:REGISTER]"), std::string::npos)
      << r.err;
}

}  // namespace
