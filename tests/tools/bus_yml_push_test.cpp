// cfgmgr with a lely dcfgen / ros2_canopen bus.yml as the network (cfg/bus_yml.hpp), end to
// end on sim: push configures every slave with the reader's configuration and a second push
// (state kept) downloads nothing; check names bad input at its line; push of bad input exits 1
// before the bus. The files are tests/data/bus_yml (README.md there).
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "prerequisite.hpp"
#include "push_test_support.hpp"

namespace {

using push_test::cfgmgr;
using push_test::nodes_of;
using push_test::parse_json;
using tool_test::DataDir;
using tool_test::Json;
using tool_test::ScratchDir;

const DataDir data("bus_yml");

TEST(BusYmlPush, PushConfiguresEverySlaveAndASecondPushDownloadsNothing) {
  ScratchDir dir;
  const std::string bus = "sim:?state=" + (dir / "state");
  auto first = cfgmgr(dir, {"push", data("lely.yml"), "--bus", bus, "--json", dir / "first.json"});
  ASSERT_EQ(first.exit_code, 0) << first.err.substr(0, 4000);
  const Json json = parse_json(dir / "first.json");
  EXPECT_TRUE(json.get("ok")->boolean);
  const auto nodes = nodes_of(json);
  ASSERT_EQ(nodes.size(), 3U);
  for (const auto& [id, n] : nodes) {
    SCOPED_TRACE("node " + std::to_string(id));
    EXPECT_EQ(n->get("result")->string, "configured");
    EXPECT_GT(n->get("entries")->number, 0);
  }
  // Node 2 (io): TPDO 1 (invalid, transmission, inhibit time, mapping 0/1/2/count, valid),
  // TPDO 2 disabled, 1017h: 10 writes, as the reader makes them (bus_yml_test.cpp).
  EXPECT_EQ(nodes.at(2)->get("entries")->number, 10);
  EXPECT_EQ(nodes.at(2)->get("name")->string, "io");

  // The devices saved (1010h) and keep 1020h = 1F26h/1F27h: nothing is downloaded again
  // (CiA 302-2 §3.5 c).
  auto second =
      cfgmgr(dir, {"push", data("lely.yml"), "--bus", bus, "--json", dir / "second.json"});
  ASSERT_EQ(second.exit_code, 0) << second.err.substr(0, 4000);
  const Json again = parse_json(dir / "second.json");
  ASSERT_EQ(nodes_of(again).size(), 3U);
  for (const auto& [id, n] : nodes_of(again)) {
    SCOPED_TRACE("node " + std::to_string(id));
    EXPECT_EQ(n->get("result")->string, "skipped");
    EXPECT_EQ(n->get("entries")->number, 0);
  }
}

// dcfgen's software_version/software_file (1F81h bits 5/6, 1F55h, 1F58h): the master checks the
// slave's 1F56h sub 1 against 1F55h and, when it differs, downloads the image (CiA 302-3, as
// lely's master does). sim_device.eds reports 1F56h sub 1 = 0 and has no 1F57h (the flash
// status is optional: the program is started and 1F56h decides); a simulated device reports the
// CRC-32 of the image it holds, so the expected identification is the image's CRC-32.
TEST(BusYmlPush, SoftwareVersionAndFileUpdateTheSlaveByIdentificationAndASecondPushUpdatesNothing) {
  ScratchDir dir;
  std::vector<std::uint8_t> image(700);
  for (std::size_t i = 0; i < image.size(); ++i) image[i] = static_cast<std::uint8_t>(i * 7);
  tool_test::write_file(dir / "drive_v2.img", image);
  const std::uint32_t id = cfg::crc32(image);
  tool_test::write_file(dir / "bus.yml",
                        std::string("master:\n  node_id: 1\n\ndrive:\n  dcf: \"") +
                            tool_test::data_path("sim_device.eds") +
                            "\"\n  node_id: 5\n  software_version: " + cfg::hex(id, 8) +
                            "\n  software_file: \"drive_v2.img\"\n");
  const std::string bus = "sim:?state=" + (dir / "state");
  // verify reads 1F56h sub 1 against 1F55h, as the master checks it (not 1F52h).
  auto before = cfgmgr(dir, {"verify", dir / "bus.yml", "--bus", bus});
  EXPECT_EQ(before.exit_code, 4) << before.out << before.err;
  EXPECT_NE(before.out.find("1F56h sub 01h"), std::string::npos) << before.out;
  auto first = cfgmgr(dir, {"push", dir / "bus.yml", "--bus", bus, "--json", dir / "first.json"});
  ASSERT_EQ(first.exit_code, 0) << first.out << first.err.substr(0, 4000);
  EXPECT_NE(first.out.find("node 5 (drive): program updated: 700 bytes in "), std::string::npos)
      << first.out;
  EXPECT_NE(first.out.find("before software identification 0x00000000, after " + cfg::hex(id, 8) +
                           " (1F56h sub 1)"),
            std::string::npos)
      << first.out;
  const Json report = parse_json(dir / "first.json");
  const auto nodes = nodes_of(report);
  ASSERT_EQ(nodes.size(), 1U);
  const auto* program = nodes.at(5)->get("program");
  ASSERT_NE(program, nullptr);
  EXPECT_TRUE(program->get("updated")->boolean);
  EXPECT_EQ(program->get("bytes")->number, 700);
  EXPECT_EQ(program->get("identification_before")->number, 0);
  EXPECT_EQ(program->get("identification_after")->number, id);
  EXPECT_TRUE(program->get("before")->is(Json::Kind::Null));

  // The device keeps its program (sim:?state=): 1F56h now equals 1F55h, nothing to update.
  auto second = cfgmgr(dir, {"push", dir / "bus.yml", "--bus", bus, "--json", dir / "second.json"});
  ASSERT_EQ(second.exit_code, 0) << second.err.substr(0, 4000);
  EXPECT_EQ(second.out.find("program updated"), std::string::npos) << second.out;
  const Json second_report = parse_json(dir / "second.json");
  const auto again = nodes_of(second_report);
  ASSERT_EQ(again.size(), 1U);
  EXPECT_TRUE(again.at(5)->get("program")->is(Json::Kind::Null));
  auto after = cfgmgr(dir, {"verify", dir / "bus.yml", "--bus", bus});
  EXPECT_EQ(after.exit_code, 0) << after.out << after.err;

  // A version on the command line for a node checked by its identification would never be
  // looked at: refused.
  auto both = cfgmgr(
      dir, {"push", dir / "bus.yml", "--bus", "sim:", "--program-version", "5=2026-11-27T08:15"});
  EXPECT_NE(both.exit_code, 0);
  EXPECT_NE(both.err.find("checked by its software identification (1F55h"), std::string::npos)
      << both.err;

  // build carries the image: DIR/drive.img, named by 1F58h sub 5 of DIR/master.dcf, which a
  // push of the built master DCF reads back and downloads to a fresh device.
  auto built = cfgmgr(dir, {"build", dir / "bus.yml", "-o", dir / "out"});
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_EQ(tool_test::slurp(dir / "out/drive.img"), std::string(image.begin(), image.end()));
  const std::string master = tool_test::slurp(dir / "out/master.dcf");
  EXPECT_NE(master.find("[1F58sub5]"), std::string::npos);
  EXPECT_NE(master.find("UploadFile=drive.img"), std::string::npos);
  auto from_build = cfgmgr(dir, {"push", dir / "out/master.dcf", "--bus",
                                 "sim:?device=" + tool_test::data_path("sim_device.eds") + "@5"});
  ASSERT_EQ(from_build.exit_code, 0) << from_build.out << from_build.err;
  EXPECT_NE(from_build.out.find("program updated: 700 bytes in "), std::string::npos)
      << from_build.out;
}

// Slave keys that are no plain file name, or that another slave's nodeN.bin would also give,
// keep our nodeN.bin: no file is written twice and 1F22h names one file per node.
TEST(BusYmlPush, BuildKeepsNodeNNamesWhereSlaveKeysWouldCollideOrAreNoFileNames) {
  ScratchDir dir;
  const std::string eds = tool_test::data_path("sim_device.eds");
  tool_test::write_file(dir / "bus.yml", "master:\n  node_id: 1\nnode3:\n  dcf: \"" + eds +
                                             "\"\n  node_id: 2\n\"odd name\":\n  dcf: \"" + eds +
                                             "\"\n  node_id: 3\n");
  auto r = cfgmgr(dir, {"build", dir / "bus.yml", "-o", dir / "out"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "out/node2.bin"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out/node3.bin"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out/odd name.bin"));
  const std::string master = tool_test::slurp(dir / "out/master.dcf");
  EXPECT_NE(master.find("UploadFile=node2.bin"), std::string::npos);
  EXPECT_NE(master.find("UploadFile=node3.bin"), std::string::npos);
}

TEST(BusYmlPush, BuildWritesAMasterDcfThatReadsBackAsTheNetwork) {
  ScratchDir dir;
  const std::string out = dir / "out";
  auto r = cfgmgr(dir, {"build", data("lely.yml"), "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // dcfgen's names: master.dcf and <slave>.bin, the slave's key in the bus.yml.
  for (const char* file : {"master.dcf", "io.bin", "axis_x.bin", "axis_y.bin"}) {
    EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(out) / file)) << file;
  }
  const std::string master = tool_test::slurp(out + "/master.dcf");
  EXPECT_NE(master.find("UploadFile=io.bin"), std::string::npos);
  EXPECT_NE(master.find("UploadFile=axis_x.bin"), std::string::npos);
  // The master DCF (1006h, 1F80h, 1F89h, 102Ah from the bus.yml) names the three concise DCFs
  // and checks clean as a network.
  auto check = cfgmgr(dir, {"check", "--network", out + "/master.dcf"});
  EXPECT_EQ(check.exit_code, 0) << check.err;
  EXPECT_NE(check.out.find("0 errors, 0 warnings, 3 nodes"), std::string::npos) << check.out;
}

TEST(BusYmlPush, TheRos2LayoutPushesWithItsDefaults) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"push", data("ros2.yml"), "--bus", "sim:", "--json", dir / "r.json"});
  ASSERT_EQ(r.exit_code, 0) << r.err.substr(0, 4000);
  const Json json = parse_json(dir / "r.json");
  const auto nodes = nodes_of(json);
  ASSERT_EQ(nodes.size(), 2U);
  EXPECT_EQ(nodes.at(5)->get("result")->string, "configured");
  EXPECT_EQ(nodes.at(6)->get("result")->string, "configured");
}

TEST(BusYmlPush, CheckNamesBadInputAtItsLineAndExits1) {
  ScratchDir dir;
  for (const auto& [file, where] : std::vector<std::pair<std::string, std::string>>{
           {"truncated.yml", "truncated.yml:8: error: not valid YAML"},
           {"no_dcf.yml", "no_dcf.yml:3: error: io: no dcf"},
           {"missing_object.yml", "missing_object.yml:10: error: io.tpdo.1: mapping: 7123h"},
           {"node_id_clash.yml", "node_id_clash.yml:8: error: io_b.node_id: node-ID clash"},
           {"cob_id_clash.yml", "cob_id_clash.yml:12: error: io_b.tpdo.1: COB-ID 0x183"}}) {
    SCOPED_TRACE(file);
    const auto r = cfgmgr(dir, {"check", data(file)});
    EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
    EXPECT_NE(r.err.find(where), std::string::npos) << r.err;
  }
}

TEST(BusYmlPush, PushOfBadInputSendsNothing) {
  ScratchDir dir;
  const std::string log = dir / "bus.log";
  const auto r = cfgmgr(dir, {"push", data("cob_id_clash.yml"), "--bus", "sim:", "--candump", log});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("cob_id_clash.yml:12: error"), std::string::npos) << r.err;
  EXPECT_TRUE(!std::filesystem::exists(log) || tool_test::slurp(log).empty());
}

TEST(BusYmlPush, DefineFillsACmakePlaceholder) {
  ScratchDir dir;
  const auto without = cfgmgr(dir, {"check", data("placeholder.yml")});
  EXPECT_EQ(without.exit_code, 1);
  EXPECT_NE(without.err.find("--define IO_DIR="), std::string::npos) << without.err;
  const auto with = cfgmgr(dir, {"check", data("placeholder.yml"), "--define",
                                 "IO_DIR=" + std::string(CANOPEN_SAMPLES_DIR)});
  EXPECT_EQ(with.exit_code, 0) << with.err;
}

// Corpus tier: ros2_canopen's cia402 network as the starnus build had it (six drives of one EDS,
// lely's flat layout with YAML anchors): push configures every slave.
TEST(BusYmlPush, CorpusRos2CanopenCia402ConfiguresEverySlave) {
  namespace fs = std::filesystem;
  const fs::path set = fs::path(CANOPEN_CORPUS_DIR) / "starnus-ros2_canopen-build";
  if (!fs::exists(set)) PREREQUISITE_MISSING("corpus not found at ", set.string());
  ScratchDir dir;
  fs::copy_file(set / "cia402__bus.yml", dir.path() / "bus.yml");
  fs::copy_file(set / "cia402__cia402_slave.eds", dir.path() / "cia402_slave.eds");
  auto r = cfgmgr(dir, {"push", dir / "bus.yml", "--bus", "sim:", "--json", dir / "r.json"});
  ASSERT_EQ(r.exit_code, 0) << r.err.substr(0, 4000);
  const Json json = parse_json(dir / "r.json");
  const auto nodes = nodes_of(json);
  ASSERT_EQ(nodes.size(), 6U);  // node-IDs 2..7
  for (const auto& [id, n] : nodes) {
    SCOPED_TRACE("node " + std::to_string(id));
    EXPECT_EQ(n->get("result")->string, "configured");
    EXPECT_GT(n->get("entries")->number, 20);
  }
}

}  // namespace
