// Emergencies (CiA 301 §7.2.7) end to end over the UDP multicast bus in real time, against
// devices written with python-can alone (tests/io/python/emcy_slaves.py): `cfgmgr push` takes
// each EMCY from the COB-ID the node's DCF gives its 1014h (node 4: 0A4h, written invalid first
// as §7.5.2.17 requires, which the device enforces), counts them per node, and names them in
// words; `cfgmgr master --json-events` reports each one with its fields, the error reset that
// ends it, and a flood as five reports and one summary. Runs inside a private network namespace
// (tests/support/run_in_netns.sh) as the other UDP tool tests do; elsewhere it skips. The same
// on sim: is tests/tools/emcy_sim_test.cpp.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "multicast_netns.hpp"
#include "push_test_support.hpp"
#include "python_peer.hpp"
#include "tool_test_support.hpp"

namespace {

using ::testing::Contains;
using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::events_of;
using tool_test::Json;
using tool_test::ScratchDir;

constexpr const char* kPushPort = "43232";
constexpr const char* kMasterPort = "43233";  // 43234 is free for the next test file

struct PeerRun {
  tool_test::RunResult run;
  std::vector<std::string> lines;
  std::string all;
};

// Starts emcy_slaves.py for nodes 3 and 4 with `emcy` schedules, runs cfgmgr with `args`
// (its --bus added), ends the slaves and takes what they printed.
PeerRun run_against_slaves(const ScratchDir& dir, const char* port,
                           const std::vector<std::string>& emcy, std::vector<std::string> args) {
  std::vector<std::string> slave_args;
  for (const auto& e : emcy) slave_args.insert(slave_args.end(), {"--emcy", e});
  slave_args.insert(slave_args.end(), {test_support::kUdpTestGroup, port, "40", "3", "4"});
  test_support::PythonPeer slaves(test_support::python_script("emcy_slaves.py"), slave_args);
  PeerRun r;
  if (slaves.read_line() != "READY") return r;
  args.insert(args.end(), {"--bus", test_support::udp_test_url(port)});
  r.run = tool_test::cfgmgr(dir, args);
  {
    test_support::PythonPeer end({"send", test_support::kUdpTestGroup, port, "7FF#"});
    (void)end.finish();
  }
  r.lines = slaves.read_all();
  (void)slaves.finish();
  for (const auto& line : r.lines) r.all += line + "\n";
  return r;
}

TEST(EmcyUdp, EndToEndOverUdp) {
  tool_test::run_in_private_netns("EmcyUdpInNetns.*");
}

TEST(EmcyUdpInNetns, PushTakesEachEmcyFromItsNodesCobIdAndCountsIt) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  const std::string report = dir / "report.json";
  const std::string page = dir / "report.html";
  // Both raise an EMCY as the master writes their 2000h (during the boot); node 4 ends its
  // error 50 ms later with an error reset (0000h).
  const auto r = run_against_slaves(
      dir, kPushPort,
      {"3:write-2000:0:8130:11", "4:write-2000:0:2310:03:0102030405", "4:write-2000:50:0000:00"},
      {"push", tool_test::data_path("emcy/python.cpj"), "--json", report, "--report", page});
  const std::string context = r.run.out + r.run.err + "--- slaves:\n" + r.all;
  ASSERT_EQ(r.run.exit_code, 0) << context;
  // Node 4's 1014h went through "not valid" to 0A4h (UNSIGNED32 little-endian), and its EMCYs
  // went out there; node 3's stayed on 83h.
  const auto write_invalid = std::find(r.lines.begin(), r.lines.end(), "WRITE 4 1014 00 A4000080");
  const auto write_valid = std::find(r.lines.begin(), r.lines.end(), "WRITE 4 1014 00 A4000000");
  ASSERT_NE(write_invalid, r.lines.end()) << context;
  ASSERT_NE(write_valid, r.lines.end()) << context;
  EXPECT_LT(write_invalid, write_valid) << context;
  EXPECT_THAT(r.lines, Contains("EMCY 3 083 8130")) << context;
  EXPECT_THAT(r.lines, Contains("EMCY 4 0A4 2310")) << context;
  EXPECT_THAT(r.lines, Contains("EMCY 4 0A4 0000")) << context;
  // The words: CiA 301's code classes, CiA 401's for the I/O modules (1000h = 000F0191h).
  EXPECT_THAT(r.run.err, HasSubstr("node 3: emergency 8130h life guard error or heartbeat error; "
                                   "error register 11h (generic, communication); manufacturer "
                                   "bytes 00 00 00 00 00"))
      << context;
  EXPECT_THAT(r.run.err, HasSubstr("node 4: emergency 2310h current at outputs too high "
                                   "(overload) (CiA 401); current, device output side; error "
                                   "register 03h (generic, current); manufacturer bytes 01 02 03 "
                                   "04 05"))
      << context;
  EXPECT_THAT(r.run.err, HasSubstr("node 4: emergency ended: 0000h error reset or no error"))
      << context;
  const Json json = push_test::parse_json(report);
  const auto nodes = push_test::nodes_of(json);
  ASSERT_EQ(nodes.size(), 2U) << context;
  EXPECT_EQ(nodes.at(3)->get("emergencies")->number, 1) << context;
  EXPECT_EQ(nodes.at(4)->get("emergencies")->number, 1) << context;  // the reset is not counted
  // An EMCY is the device's report, not a boot error (CiA 302-2 §3.3 has none for it).
  EXPECT_EQ(nodes.at(3)->get("result")->string, "configured") << context;
  EXPECT_EQ(nodes.at(4)->get("result")->string, "configured") << context;
  // --report on a real bus in real time: each node's lane and row, its EMCY marked on the
  // timeline, no failed node (the page's DOM in a browser: push_report_test.cpp).
  const std::string html = tool_test::slurp(page);
  for (const char* node : {"3", "4"}) {
    EXPECT_THAT(html, HasSubstr(std::string("id=\"lane-") + node + "\"")) << html;
    EXPECT_THAT(html, HasSubstr(std::string("<tr id=\"row-") + node + "\" title=\"configured\""))
        << html;
  }
  std::size_t marks = 0;  // on the timeline, after the legend's key
  for (auto at = html.find("class=\"m-emergency\"", html.find("<svg class=\"timeline\""));
       at != std::string::npos; at = html.find("class=\"m-emergency\"", at + 1)) {
    ++marks;
  }
  EXPECT_EQ(marks, 3U) << html;  // 8130h of node 3, 2310h and its reset of node 4
  EXPECT_THAT(html, Not(HasSubstr("class=\"lane failed\""))) << html;
}

TEST(EmcyUdpInNetns, MasterReportsEachEmcyItsEndAndAFloodOnce) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  const std::string events = dir / "events.jsonl";
  // Node 3: 5000h (device hardware) with manufacturer bytes 100 ms after its NMT start, its
  // reset 300 ms later. Node 4: twelve 6100h at once, 200 ms after its start: five reported,
  // seven in one summary when the window of MasterOptions::emcy (5 per 1000 ms) ends.
  std::vector<std::string> emcy{"3:start:100:5000:81:DEADBEEF01", "3:start:400:0000:00"};
  for (int i = 0; i < 12; ++i) emcy.emplace_back("4:start:200:6100:01");
  const auto r = run_against_slaves(dir, kMasterPort, emcy,
                                    {"master", tool_test::data_path("emcy/python.cpj"), "--run-for",
                                     "3", "--json-events", events});
  const std::string context = r.run.out + r.run.err + "--- slaves:\n" + r.all;
  ASSERT_EQ(r.run.exit_code, 0) << context;
  ASSERT_EQ(std::count(r.lines.begin(), r.lines.end(), "EMCY 4 0A4 6100"), 12) << context;
  const auto lines = tool_test::json_lines(events);
  const auto emcys = events_of(lines, "emergency");
  std::vector<const Json*> of3, of4;
  for (const Json* e : emcys) (e->get("node_id")->number == 3 ? of3 : of4).push_back(e);
  ASSERT_EQ(of3.size(), 2U) << context;
  const Json* first = of3[0]->get("emergency");
  EXPECT_EQ(first->get("error_code")->number, 0x5000);
  EXPECT_EQ(first->get("error_register")->number, 0x81);
  EXPECT_EQ(first->get("manufacturer")->string, "DEADBEEF01");
  EXPECT_EQ(first->get("register_text")->string, "generic, manufacturer specific");
  EXPECT_FALSE(first->get("ends_error")->boolean);
  EXPECT_EQ(of3[1]->get("emergency")->get("error_code")->number, 0);
  EXPECT_TRUE(of3[1]->get("emergency")->get("ends_error")->boolean);
  ASSERT_EQ(of4.size(), 5U) << context;
  const auto floods = events_of(lines, "emergency_flood");
  ASSERT_EQ(floods.size(), 1U) << context;
  EXPECT_EQ(floods[0]->get("node_id")->number, 4);
  EXPECT_EQ(floods[0]->get("emergency")->get("suppressed")->number, 7);
  EXPECT_EQ(floods[0]->get("emergency")->get("error_code")->number, 0x6100);
}

}  // namespace
