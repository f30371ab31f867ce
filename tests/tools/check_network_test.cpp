// cfgmgr check NETWORK end to end: a CiA 306-3 project file is checked as a whole (load_network's
// diagnostics and cfg::check_network's). Files in tests/data/network_check (README there); the
// lines asserted are those files'.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tool_test_support.hpp"

namespace {

using ::testing::HasSubstr;
using tool_test::cfgmgr;
using tool_test::Json;
using tool_test::JsonParser;
using tool_test::RunResult;
using tool_test::ScratchDir;

const tool_test::DataDir data("network_check");

TEST(CheckNetwork, ProjectFileFindingsArePrintedLikeACompilerAndExit1) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"check", data("clash.cpj")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  // The missing DCF at the project file's line that names it (clash.cpj line 13).
  EXPECT_THAT(r.err, HasSubstr(data("clash.cpj") + ":13: error: [Topology] Node5DCFName"));
  // Two TPDOs with CAN-ID 182h (CiA 301 §7.2.2: one producer per PDO).
  EXPECT_THAT(r.err, HasSubstr(data("sensor_node3.dcf") + ":105: error: COB-ID clash"));
  // 2000h has PDOMapping=0 (CiA 306), 2100h is not in node 3's DCF: the device refuses the
  // writes (0604 0041, 0602 0000), warnings in tolerant mode.
  EXPECT_THAT(r.err, HasSubstr(data("sensor_node3.dcf") +
                               ":136: warning: node 3 (n3): 1A00h sub 01h = 0x20000008: the "
                               "download will be refused with SDO abort 0604 0041: TPDO 1 maps "
                               "2000h sub 00h, which is not mappable"));
  EXPECT_THAT(r.err, HasSubstr(data("sensor_node3.dcf") + ":145: warning:"));
  EXPECT_THAT(r.out, HasSubstr(data("clash.cpj") + ": 2 errors, 3 warnings, 3 nodes"));
}

TEST(CheckNetwork, ACleanNetworkExits0) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"check", data("clean.cpj")});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_THAT(r.out, HasSubstr("0 errors, 0 warnings, 2 nodes"));
}

TEST(CheckNetwork, JsonReportsTheNetworkAndItsDiagnostics) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"check", "--json", data("clash.cpj")});
  EXPECT_EQ(r.exit_code, 1);
  JsonParser parser(r.out);
  const auto json = parser.parse();
  ASSERT_TRUE(json) << parser.error() << "\n" << r.out;
  EXPECT_FALSE(json->get("ok")->boolean);
  const Json& file = json->get("files")->array.at(0);
  EXPECT_TRUE(file.get("network")->boolean);
  EXPECT_EQ(file.get("nodes")->number, 3);
  EXPECT_EQ(file.get("errors")->number, 2);
  bool clash = false;
  for (const Json& d : file.get("diagnostics")->array) {
    if (d.get("file")->string == data("sensor_node3.dcf") && d.get("line")->number == 105) {
      clash = d.get("severity")->string == "error";
    }
  }
  EXPECT_TRUE(clash) << r.out;
}

// A file with a [Topology] section is a project file whatever its name; a master DCF needs
// --network (tests/data/network/master.dcf names node 2's DCF and node 3's concise DCF).
TEST(CheckNetwork, DetectsProjectFilesByContentAndMasterDcfsByOption) {
  ScratchDir dir;
  std::filesystem::copy_file(data("clean.cpj"), dir / "cell.txt");
  for (const char* f : {"sensor_node2.dcf", "actuator_node4.dcf"}) {
    std::filesystem::copy_file(data(f), dir / f);
  }
  const auto by_content = cfgmgr(dir, {"check", dir / "cell.txt"});
  EXPECT_EQ(by_content.exit_code, 0) << by_content.err;
  EXPECT_THAT(by_content.out, HasSubstr("2 nodes"));
  const auto master =
      cfgmgr(dir, {"check", "--network", tool_test::data_path("network/master.dcf")});
  EXPECT_EQ(master.exit_code, 0) << master.err;
  EXPECT_THAT(master.out, HasSubstr("0 errors, 0 warnings, 2 nodes"));
}

TEST(CheckNetwork, AMissingProjectFileExits3) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"check", dir / "absent.cpj"});
  EXPECT_EQ(r.exit_code, 3);
}

}  // namespace
