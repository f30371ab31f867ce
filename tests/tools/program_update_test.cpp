// Software update in the boot from the tools (DSP 302 §9 program download, §4 figure 7
// "check and update software version", CiA 302-2 Table 1 statuses G, H, I): what a network
// description says per node (NodeXProgramFile=/NodeXProgramVersion=, our keys, CiA 306-3 has
// none; the master DCF's 1F53h/1F54h and 1F81h bits 5/6), `cfgmgr check` at file:line, the image
// trailer of `cfgmgr program-image`, and the command-line overrides of push. Files in
// tests/data/program (README there).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "push_test_support.hpp"
#include "tool_test_support.hpp"

namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::cfgmgr;
using tool_test::ScratchDir;

const tool_test::DataDir data("program");

// `cfgmgr check --no-schema ARGS` in a scratch directory.
tool_test::RunResult check(std::vector<std::string> args) {
  ScratchDir dir;
  args.insert(args.begin(), {"check", "--no-schema"});
  return cfgmgr(dir, args);
}

// --json's nodes[].program of `node` in the push report `file` (Null when it has none).
tool_test::Json program_of(const std::string& file, int node) {
  const auto report = push_test::parse_json(file);
  const auto nodes = push_test::nodes_of(report);
  const tool_test::Json* program = nodes.contains(node) ? nodes.at(node)->get("program") : nullptr;
  EXPECT_NE(program, nullptr) << "node " << node << " in " << tool_test::slurp(file);
  return program != nullptr ? *program : tool_test::Json{};
}

TEST(CheckProgram, ACleanDescriptionWithImageAndVersionExits0) {
  const auto r = check({data("program.cpj")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, HasSubstr("0 errors, 0 warnings, 1 node"));
}

TEST(CheckProgram, AMissingImageIsAnErrorAtTheLineThatNamesIt) {
  const auto r = check({data("missing_image.cpj")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_THAT(r.err,
              HasSubstr(data("missing_image.cpj") + ":7: error: [Topology] Node3ProgramFile '" +
                        data("absent.img") + "': cannot open the file"));
  // Said once: no second finding about bit 6 without an image for the same key.
  EXPECT_THAT(r.out, HasSubstr("1 error, 0 warnings"));
}

TEST(CheckProgram, AnUnreadableImageIsAnError) {
  const auto r = check({data("unreadable_image.cpj")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_THAT(r.err,
              HasSubstr(data("unreadable_image.cpj") + ":7: error: [Topology] Node3ProgramFile '" +
                        data("nodes") + "': is a directory"));
}

TEST(CheckProgram, AnEmptyImageIsAnError) {
  const auto r = check({data("empty_image.cpj")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr(data("empty_image.cpj") + ":6: error:"));
  EXPECT_THAT(r.err, HasSubstr("the file is empty"));
}

TEST(CheckProgram, AnImageWithoutAVersionIsAnErrorThatNamesTheTrailersVersion) {
  const auto r = check({data("no_version.cpj")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  // DSP 302 §9: the master compares 1F52h with 1F53h/1F54h; with no expected version there is
  // nothing to compare. drive_v2.img's trailer: day 15671 (2026-11-27), 29 700 000 ms (08:15).
  EXPECT_THAT(r.err,
              HasSubstr(data("no_version.cpj") + ":6: error: node 3: program image '" +
                        data("drive_v2.img") + "' without a version: give Node3ProgramVersion="));
  EXPECT_THAT(r.err, HasSubstr("the image's trailer says 2026-11-27 08:15:00.000 (1F52h 15671, "
                               "29700000)"));
}

TEST(CheckProgram, AVersionBeforeDay0Of1984IsAnErrorAtItsLine) {
  const auto r = check({data("bad_version.cpj")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr(data("bad_version.cpj") +
                               ":7: error: [Topology] Node3ProgramVersion=1983-12-31:"));
  EXPECT_THAT(r.out, HasSubstr("1 error, 0 warnings"));
}

TEST(CheckProgram, Bit5WithoutExpectedDateAndTimeIsStatusGsCaseAtThe1F81hLine) {
  const auto r = check({"--network", data("master_bit5.dcf")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  // master_bit5.dcf line 191: 1F81h sub 3 ParameterValue=0x0000002D, no 1F53h/1F54h (CiA 302-2
  // Table 1, G: "the expected version date and time values were not configured").
  EXPECT_THAT(r.err, HasSubstr(data("master_bit5.dcf") +
                               ":191: error: 1F81h sub 3 (node 3) has bit 5 (verify the "
                               "application software version) but 1F53h and 1F54h sub 3 give no "
                               "expected version, nor 1F55h sub 3 an expected software "
                               "identification: the boot ends with status G"));
}

TEST(CheckProgram, ATrailerVersionDifferentFromTheExpectedOneIsAWarning) {
  const auto r = check({data("trailer_differs.cpj")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr(data("trailer_differs.cpj") +
                               ":6: warning: node 3: program image '" + data("drive_v2.img") +
                               "' carries version 2026-11-27 08:15:00.000 (1F52h 15671, "
                               "29700000) in its trailer, but the expected version is 2026-11-28 "
                               "00:00:00.000 (1F52h 15672, 0)"));
}

TEST(ProgramImage, AppendsTheTrailerOfDaysSince1984MillisecondsAndCPV1) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"program-image", data("drive_v2.payload"), "--version",
                              "2026-11-27T08:15", "-o", dir / "out.img"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // drive_v2.img was made independently (tests/data/program/README.md): the payload, then
  // 15671 (3D37h) and 29 700 000 (01C52FA0h) little endian, then "CPV1".
  const std::string made = tool_test::slurp(dir / "out.img");
  EXPECT_EQ(made, tool_test::slurp(data("drive_v2.img")));
  EXPECT_EQ(made.substr(made.size() - 12), std::string("\x37\x3D\x00\x00\xA0\x2F\xC5\x01"
                                                       "CPV1",
                                                       12));
}

TEST(ProgramImage, ReportsTheVersionAnImageCarries) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"program-image", data("drive_v2.img")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("1012 bytes, version 2026-11-27 08:15:00.000 (1F52h 15671, "
                               "29700000)"));
  const auto none = cfgmgr(dir, {"program-image", data("drive_v2.payload")});
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_THAT(none.err, HasSubstr("no version trailer"));
}

TEST(ProgramImage, ABadVersionIsAUsageError) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"program-image", data("drive_v2.payload"), "--version", "2026-13-01",
                              "-o", dir / "out.img"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--version 2026-13-01"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out.img"));
}

TEST(BuildProgram, TheDerivedMasterExpectsTheVersionAndMayUpdate) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"build", data("program.cpj"), "-o", dir / "out"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string master = tool_test::slurp(dir / "out/master.dcf");
  // DSP 302 §9: 1F53h/1F54h sub 3 = days since 1984-01-01 and ms after midnight; §5.2: 1F81h
  // sub 3 = 0Dh (slave, boot, mandatory) | 20h (verify version) | 40h (update allowed).
  const auto value_of = [&master](const std::string& section) {
    const auto at = master.find("[" + section + "]");
    if (at == std::string::npos) return std::string("(no section)");
    const auto key = master.find("ParameterValue=", at);
    const auto next = master.find("\n[", at);
    if (key == std::string::npos || key > next) return std::string("(no value)");
    return master.substr(key + 15, 10);
  };
  EXPECT_EQ(value_of("1F53sub3"), "0x00003D37");
  EXPECT_EQ(value_of("1F54sub3"), "0x01C52FA0");
  EXPECT_EQ(value_of("1F81sub3"), "0x0000006D");
}

TEST(BuildProgram, AVersionWithoutImageAsksForTheCheckButNoUpdate) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"build", data("version_only.cpj"), "-o", dir / "out"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string master = tool_test::slurp(dir / "out/master.dcf");
  const auto at = master.find("[1F81sub3]");
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(master.substr(master.find("ParameterValue=", at) + 15, 10), "0x0000002D");
}

TEST(PushProgram, AMatchingVersionUpdatesNothing) {
  ScratchDir dir;
  // drive_node3.dcf's 1F52h is 2025-08-01 07:30 (day 15188, 27 000 000 ms): DSP 302 §4 figure 7,
  // the version matches, no program download, the boot goes on to the configuration.
  const auto r = cfgmgr(dir, {"push", data("program.cpj"), "--bus", "sim:", "--program-version",
                              "3=2025-08-01T07:30", "-v"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("configured"));
  EXPECT_THAT(r.err, HasSubstr("node 3: check software version"));
  EXPECT_THAT(r.err, Not(HasSubstr("node 3: software update")));
}

// Issue 33: master_bit5.dcf's 1F81h sub 3 (line 191) clears bit 6, automatic software update
// not allowed (CiA 302-2 Table 24). --program 3=IMAGE is refused before the bus, naming both;
// before, the image was downloaded all the same.
TEST(PushProgram, AnImageForANodeWhoseMasterDcfForbidsTheUpdateIsRefusedBeforeTheBus) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"push", data("master_bit5.dcf"), "--bus", "sim:", "--program",
                              "3=" + data("drive_v2.img"), "--candump", dir / "bus.log"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("master_bit5.dcf:191: 1F81h sub 3 = 0x0000002D clears bit 6 "
                               "(automatic software update not allowed"));
  EXPECT_FALSE(std::filesystem::exists(dir / "bus.log")) << "nothing was sent";
}

TEST(PushProgram, MalformedOverridesAreUsageErrors) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"push", data("program.cpj"), "--bus", "sim:", "--program", "3"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--program 3: expected NODE=FILE"));
  const auto v = cfgmgr(
      dir, {"push", data("program.cpj"), "--bus", "sim:", "--program-version", "3=yesterday"});
  EXPECT_EQ(v.exit_code, 2);
  EXPECT_THAT(v.err, HasSubstr("--program-version 3=yesterday:"));
}

TEST(PushProgram, AnOverrideForANodeNotInTheNetworkOrAMissingFileIsAnError) {
  ScratchDir dir;
  const auto r =
      cfgmgr(dir, {"push", data("program.cpj"), "--bus", "sim:", "--program", "9=x.img"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("--program: error: node 9: node 9 is not in"));
  const auto m =
      cfgmgr(dir, {"push", data("program.cpj"), "--bus", "sim:", "--program", "3=absent.img"});
  EXPECT_EQ(m.exit_code, 1);
  EXPECT_THAT(m.err, HasSubstr("--program: error: node 3: 'absent.img': cannot open the file"));
}

// --- end to end on sim: (the simulated devices report the trailer's version once started) --------

TEST(PushProgramSim, AWrongVersionGetsTheImageAndTheBootGoesOn) {
  ScratchDir dir;
  // drive_node3.dcf reports 2025-08-01 07:30 in 1F52h; program.cpj expects 2026-11-27 08:15:
  // DSP 302 §4 figure 7, the image is downloaded, started, 1F52h read again, then configured.
  const auto r =
      cfgmgr(dir, {"push", data("program.cpj"), "--bus", "sim:", "--json", dir / "r.json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("3  drive  configured"));
  EXPECT_THAT(r.out, HasSubstr("node 3 (drive): program updated: 1012 bytes in "));
  EXPECT_THAT(r.out, HasSubstr("after 2026-11-27 08:15:00.000 (1F52h 15671, 29700000)"));
  const tool_test::Json program = program_of(dir / "r.json", 3);
  ASSERT_TRUE(program.is(tool_test::Json::Kind::Object)) << tool_test::slurp(dir / "r.json");
  EXPECT_TRUE(program.get("updated")->boolean);
  EXPECT_EQ(program.get("bytes")->number, 1012);
  EXPECT_GT(program.get("seconds")->number, 0);
  EXPECT_EQ(program.get("before")->get("date_days")->number, 15188);
  EXPECT_EQ(program.get("before")->get("time_ms")->number, 27000000);
  EXPECT_EQ(program.get("after")->get("date_days")->number, 15671);
  EXPECT_EQ(program.get("after")->get("time_ms")->number, 29700000);
  EXPECT_TRUE(program.get("clear_refused")->is(tool_test::Json::Kind::Null));
  EXPECT_THAT(r.out + r.err, Not(HasSubstr("refused")));
}

// dsp302_node3.dcf's 1F51h sub 1 takes 0..2 (DSP 302 v3.2.1 §9): the device refuses clear (3)
// with 0609 0031 (CiA 301: value of parameter written too high). The download goes on, and the
// refusal is reported: as it happens, in the report, and in --json.
TEST(PushProgramSim, ADeviceRefusingClearGetsTheImageAndTheReportSaysSo) {
  ScratchDir dir;
  const auto r =
      cfgmgr(dir, {"push", data("dsp302.cpj"), "--bus", "sim:", "--json", dir / "r.json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("node 3: program clear (1F51h sub 01h = 3) refused: 0x06090031 "
                               "(value of parameter written too high (download only)); the "
                               "download goes on"));
  EXPECT_THAT(r.out, HasSubstr("node 3 (drive): program updated: 1012 bytes in "));
  EXPECT_THAT(r.out, HasSubstr("; clear (1F51h = 3) refused: 0x06090031 (value of parameter "
                               "written too high (download only))\n"));
  const tool_test::Json program = program_of(dir / "r.json", 3);
  ASSERT_TRUE(program.is(tool_test::Json::Kind::Object)) << tool_test::slurp(dir / "r.json");
  EXPECT_TRUE(program.get("updated")->boolean);
  ASSERT_TRUE(program.get("clear_refused")->is(tool_test::Json::Kind::String));
  EXPECT_EQ(program.get("clear_refused")->string,
            "0x06090031 (value of parameter written too high (download only))");
}

TEST(PushProgramSim, ASecondPushUpdatesNothing) {
  ScratchDir dir;
  // sim:?state=DIR keeps each device's program memory: the second run finds 1F52h = 1F53h/1F54h.
  const std::string bus = "sim:?state=" + (dir / "state");
  std::filesystem::create_directories(dir / "state");
  const auto first = cfgmgr(dir, {"push", data("program.cpj"), "--bus", bus});
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_THAT(first.out, HasSubstr("program updated"));
  const auto second =
      cfgmgr(dir, {"push", data("program.cpj"), "--bus", bus, "--json", dir / "r.json"});
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_THAT(second.out, Not(HasSubstr("program updated")));
  const auto report = push_test::parse_json(dir / "r.json");
  const auto nodes = push_test::nodes_of(report);
  ASSERT_TRUE(nodes.contains(3));
  EXPECT_TRUE(nodes.at(3)->get("program")->is(tool_test::Json::Kind::Null));
  EXPECT_EQ(nodes.at(3)->get("result")->string, "skipped");
}

TEST(PushProgramSim, AVersionThatDiffersWithoutBit6IsStatusH) {
  ScratchDir dir;
  // version_only.cpj: 1F81h bit 5 without bit 6 (no image). CiA 302-2 Table 1, H.
  const auto r = cfgmgr(dir, {"push", data("version_only.cpj"), "--bus",
                              "sim:", "--program-version", "3=2026-11-27T08:15"});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_THAT(r.out, HasSubstr("error H"));
  EXPECT_THAT(r.out, HasSubstr("1F52h reports 2025-08-01 07:30:00.000"));
}

TEST(PushProgramSim, AnImageCarryingAnotherVersionEndsWithStatusI) {
  ScratchDir dir;
  // trailer_differs.cpj expects 2026-11-28; the image makes the device report 2026-11-27.
  const auto r = cfgmgr(dir, {"push", data("trailer_differs.cpj"), "--bus", "sim:"});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_THAT(r.out, HasSubstr("error I"));
  EXPECT_THAT(r.out, HasSubstr("after the program download 1F52h reports 2026-11-27 08:15"));
}

TEST(PushProgramSim, CommandLineOverridesTheDescriptionsImageAndVersion) {
  ScratchDir dir;
  // version_only.cpj has no image: --program gives one, --program-version the version it has.
  const auto r =
      cfgmgr(dir, {"push", data("version_only.cpj"), "--bus", "sim:", "--program",
                   "3=" + data("drive_v2.img"), "--program-version", "3=15671,29700000"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("program updated: 1012 bytes"));
}

TEST(VerifyProgramSim, ListsANodeWhose1F52hDiffersFromItsExpectedVersion) {
  ScratchDir dir;
  // Before any update the device reports 2025-08-01 07:30 (15188, 27 000 000 ms).
  const auto r = cfgmgr(dir, {"verify", data("program.cpj"), "--bus", "sim:"});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  EXPECT_THAT(r.out, HasSubstr("1F52h sub 01h Verify application software / Application "
                               "software date: expected 15671 (0x00003D37), device has 15188"));
  EXPECT_THAT(r.out, HasSubstr("1F52h sub 02h"));
  const auto same = cfgmgr(dir, {"verify", data("version_only.cpj"), "--bus", "sim:"});
  EXPECT_EQ(same.exit_code, 0) << same.out;
}

TEST(MasterProgramSim, ReportsTheUpdateAsItHappens) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"master", data("program.cpj"), "--bus", "sim:"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("node 3: program updated: 1012 bytes in "));
  EXPECT_THAT(r.err, HasSubstr("now 2026-11-27 08:15:00.000"));
}

TEST(MasterProgramSim, ReportsARefusedClearAsItHappensAndInItsJsonEvents) {
  ScratchDir dir;
  const auto r = cfgmgr(
      dir, {"master", data("dsp302.cpj"), "--bus", "sim:", "--json-events", dir / "events.jsonl"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("node 3: program clear (1F51h sub 01h = 3) refused: 0x06090031"));
  EXPECT_THAT(r.err, HasSubstr("node 3: program updated: 1012 bytes in "));
  const std::string events = tool_test::slurp(dir / "events.jsonl");
  EXPECT_THAT(
      events,
      HasSubstr("\"event\": \"program_clear_refused\", \"node_id\": 3, "
                "\"abort\": \"0x06090031 (value of parameter written too high (download only))\""));
}

}  // namespace
