// cfg::check_network: the checks across the nodes of a network description. Files in
// tests/data/network_check (README there); the values and lines asserted are those files'.
#include "cfg/network_check.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "cfg/network.hpp"
#include "test_paths.hpp"

namespace {

using ::testing::HasSubstr;

std::string data(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/network_check/" + name;
}

// The diagnostics check_network adds to a network that loaded.
cfg::Diagnostics checked(const std::string& project) {
  cfg::NetworkLoad load = cfg::load_network(data(project));
  EXPECT_TRUE(load.network.has_value());
  cfg::Diagnostics out;
  if (load.network) cfg::check_network(*load.network, out);
  return out;
}

std::vector<cfg::Diagnostic> at(const cfg::Diagnostics& d, const std::string& file, int line) {
  std::vector<cfg::Diagnostic> out;
  for (const auto& item : d.items()) {
    if (item.file == data(file) && item.line == line) out.push_back(item);
  }
  return out;
}

// CiA 301 §7.2.2: a PDO has one producer. Node 3's 1800h sub 1 (line 105) = 0x182 is node 2's
// $NODEID+0x180 (sensor_node2.dcf line 104).
TEST(NetworkCheck, TwoTpdosWithOneCobIdAreAnErrorAtTheSecondsValue) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 105);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Error);
  EXPECT_THAT(found[0].message, HasSubstr("COB-ID clash"));
  EXPECT_THAT(found[0].message, HasSubstr("CAN-ID 0x182"));
  EXPECT_THAT(found[0].message, HasSubstr("node 2 (n2) TPDO 1"));
  EXPECT_THAT(found[0].message, HasSubstr(data("sensor_node2.dcf") + ":104"));
}

// Each node's download runs through the write rules of a CiA 301 device (write_acceptance.hpp),
// as a single DCF's does; a refusal is a warning in tolerant mode (the file is usable, the
// download will fail there). CiA 301 §7.5.2.38: 1A00h sub 1 = 0x20000008 (line 136) maps
// 2000h sub 0, whose PDOMapping=0: the device aborts 0604 0041.
TEST(NetworkCheck, MappingAnObjectWithPdoMapping0IsARefusedWrite) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 136);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Warning);
  EXPECT_THAT(found[0].message, HasSubstr("node 3 (n3): 1A00h sub 01h = 0x20000008"));
  EXPECT_THAT(found[0].message, HasSubstr("0604 0041"));
  EXPECT_THAT(found[0].message, HasSubstr("maps 2000h sub 00h, which is not mappable"));
}

// 1A00h sub 2 = 0x21000010 (line 145): "object does not exist" (0602 0000).
TEST(NetworkCheck, MappingAnObjectTheDcfDoesNotHaveIsARefusedWrite) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 145);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Warning);
  EXPECT_THAT(found[0].message, HasSubstr("0602 0000"));
  EXPECT_THAT(found[0].message, HasSubstr("maps 2100h, which the device does not have"));
}

// 0x60000008 (line 154): 8 bits of 6000h, an UNSIGNED16 (CiA 301 §7.1: 16 bits): 0604 0041.
TEST(NetworkCheck, AMappedLengthThatIsNotTheTypesSizeIsARefusedWrite) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 154);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Warning);
  EXPECT_THAT(found[0].message, HasSubstr("0604 0041"));
  EXPECT_THAT(found[0].message, HasSubstr("with 8 bits, but its type UNSIGNED16 has 16"));
}

// Node 4's RPDO 1 (0x182) is fed by node 2; nodes 2 and 4 have no other finding.
TEST(NetworkCheck, ACleanNetworkHasNoDiagnostics) {
  const cfg::Diagnostics d = checked("clean.cpj");
  EXPECT_TRUE(d.empty()) << d.format();
}

// Without node 2 nothing transmits node 4's RPDO 1 COB-ID (0x182): a note, not an error.
TEST(NetworkCheck, AnRpdoThatNoTpdoFeedsIsOnlyANote) {
  cfg::NetworkLoad load = cfg::load_network(data("clean.cpj"));
  ASSERT_TRUE(load.network.has_value());
  auto& nodes = load.network->nodes;
  nodes.erase(std::remove_if(nodes.begin(), nodes.end(),
                             [](const cfg::NetworkNode& n) { return n.node_id.value() == 2; }),
              nodes.end());
  cfg::Diagnostics d;
  cfg::check_network(*load.network, d);
  ASSERT_EQ(d.size(), 1U) << d.format();
  EXPECT_EQ(d.items()[0].severity, cfg::Severity::Note);
  EXPECT_EQ(d.items()[0].file, data("actuator_node4.dcf"));
  EXPECT_THAT(d.items()[0].message, HasSubstr("RPDO 1 (1400h sub 01h) receives CAN-ID 0x182"));
}

// A node given by a concise DCF alone has no DCF to check mappings against, but its COB-IDs
// count: a stream configuring node 3's TPDO 1 at 0x182 clashes with node 2's.
TEST(NetworkCheck, ANodeWithoutDcfIsCheckedOnItsWrites) {
  cfg::NetworkLoad load = cfg::load_network(data("clean.cpj"));
  ASSERT_TRUE(load.network.has_value());
  cfg::NetworkNode concise;
  concise.node_id = *cfg::NodeId::from(3);
  concise.file = "node3.bin";
  concise.writes = {{0x1800, 1, {0x82, 0x01, 0x00, 0x00}}};
  load.network->nodes.push_back(concise);
  cfg::Diagnostics d;
  cfg::check_network(*load.network, d);
  ASSERT_EQ(d.size(), 1U) << d.format();
  EXPECT_EQ(d.items()[0].file, "node3.bin");
  EXPECT_EQ(d.items()[0].line, 0);
  EXPECT_THAT(d.items()[0].message, HasSubstr("COB-ID clash"));
}

// `project` with a node 3 given by a concise DCF alone, whose writes set TPDO 1 (1800h sub 1)
// and RPDO 1 (1400h sub 1) to these COB-IDs (0: not written).
cfg::Diagnostics checked_with_node3(const std::string& project, std::uint32_t tpdo,
                                    std::uint32_t rpdo = 0) {
  cfg::NetworkLoad load = cfg::load_network(data(project));
  EXPECT_TRUE(load.network.has_value()) << load.diagnostics.format();
  cfg::Diagnostics d;
  if (!load.network) return d;
  cfg::NetworkNode concise;
  concise.node_id = *cfg::NodeId::from(3);
  concise.file = "node3.bin";
  const auto le = [](std::uint32_t v) {
    return std::vector<std::uint8_t>{
        static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
        static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
  };
  if (tpdo != 0) concise.writes.push_back({0x1800, 1, le(tpdo)});
  if (rpdo != 0) concise.writes.push_back({0x1400, 1, le(rpdo)});
  load.network->nodes.push_back(concise);
  cfg::check_network(*load.network, d);
  return d;
}

std::vector<cfg::Diagnostic> of_severity(const cfg::Diagnostics& d, cfg::Severity severity) {
  std::vector<cfg::Diagnostic> out;
  for (const auto& item : d.items()) {
    if (item.severity == severity) out.push_back(item);
  }
  return out;
}

// pool.cpj: nodes 2 and 4 of clean.cpj and a master at node 1 (manager_node1.dcf) producing
// SYNC on 80h, EMCY on 81h, with an SDO manager pool 681h-684h: nothing overlaps.
TEST(NetworkCheck, AManagerWhoseIdentifiersNoPdoUsesHasNoDiagnostics) {
  const cfg::Diagnostics d = checked("pool.cpj");
  EXPECT_TRUE(d.empty()) << d.format();
}

// CiA 301 §7.3.5, restricted CAN-IDs: 581h-5FFh (default SDO, server to client) and
// 701h-77Fh (NMT error control) are for no PDO, transmitted or received.
TEST(NetworkCheck, PdosOnRestrictedCanIdsAreErrors_Cia301_7_3_5) {
  const cfg::Diagnostics d = checked_with_node3("clean.cpj", 0x5FF, 0x701);
  const auto errors = of_severity(d, cfg::Severity::Error);
  ASSERT_EQ(errors.size(), 2U) << d.format();
  EXPECT_EQ(errors[0].file, "node3.bin");
  EXPECT_THAT(errors[0].message,
              HasSubstr("TPDO 1 (1800h sub 01h) transmits CAN-ID 0x5FF, which CiA 301 restricts "
                        "(581h-5FFh: default SDO, server to client)"));
  EXPECT_THAT(errors[1].message,
              HasSubstr("RPDO 1 (1400h sub 01h) receives CAN-ID 0x701, which CiA 301 restricts "
                        "(701h-77Fh: NMT error control)"));
  // 6E0h, the Dynamic SDO Request of DSP 302 §7.2.1, is in the restricted 6E0h-6FFh.
  EXPECT_THAT(checked_with_node3("clean.cpj", 0x6E0).format(), HasSubstr("6E0h-6FFh"));
  // 180h is the last restricted identifier below the PDO range; 181h is free.
  EXPECT_THAT(checked_with_node3("clean.cpj", 0x180).format(), HasSubstr("101h-180h"));
  EXPECT_TRUE(of_severity(checked_with_node3("clean.cpj", 0x183), cfg::Severity::Error).empty());
}

// CiA 301 §7.2.2: one producer per identifier. Node 3's TPDO on 81h would transmit on the
// master's EMCY COB-ID (1014h = $NODEID+0x80, manager_node1.dcf line 100), on 80h on its SYNC
// (1005h = 40000080h, line 93: the master produces SYNC).
TEST(NetworkCheck, ATpdoOnAnotherObjectsIdentifierIsAnError) {
  const cfg::Diagnostics emcy = checked_with_node3("pool.cpj", 0x81);
  ASSERT_EQ(emcy.size(), 1U) << emcy.format();
  EXPECT_EQ(emcy.items()[0].severity, cfg::Severity::Error);
  EXPECT_THAT(emcy.items()[0].message,
              HasSubstr("transmits CAN-ID 0x081, the EMCY COB-ID (1014h) of the master (" +
                        data("manager_node1.dcf") + ":100)"));
  const cfg::Diagnostics sync = checked_with_node3("pool.cpj", 0x80);
  ASSERT_EQ(sync.size(), 1U) << sync.format();
  EXPECT_THAT(sync.items()[0].message, HasSubstr("the SYNC COB-ID (1005h) of the master (" +
                                                 data("manager_node1.dcf") + ":93)"));
}

// DSP 302 §7.2.3: 1F02h holds the COB-IDs the SDO manager hands out for dynamic SDO channels.
// A TPDO on one (683h, sub 3 at line 137) is an error; an RPDO on one (684h) takes SDO frames
// for PDOs: a warning (and the note that no TPDO transmits it).
TEST(NetworkCheck, APdoOnTheSdoManagersPoolIsFlagged_Dsp302_7_2_3) {
  const cfg::Diagnostics d = checked_with_node3("pool.cpj", 0x683, 0x684);
  const auto errors = of_severity(d, cfg::Severity::Error);
  ASSERT_EQ(errors.size(), 1U) << d.format();
  EXPECT_THAT(errors[0].message, HasSubstr("1F02h sub 03h"));
  EXPECT_THAT(errors[0].message, HasSubstr(data("manager_node1.dcf") + ":137"));
  const auto warnings = of_severity(d, cfg::Severity::Warning);
  ASSERT_EQ(warnings.size(), 1U) << d.format();
  EXPECT_THAT(warnings[0].message, HasSubstr("receives CAN-ID 0x684"));
  EXPECT_THAT(warnings[0].message, HasSubstr("1F02h sub 04h"));
}

// The pool's COB-IDs become SDO channels, configurable objects as PDOs are (CiA 301 §7.3.5):
// manager_bad_pool.dcf's 1F02h sub 2 = 5FFh (line 129) is an error at its line.
TEST(NetworkCheck, APoolEntryOnARestrictedCanIdIsAnError) {
  const cfg::Diagnostics d = checked("bad_pool.cpj");
  const auto found = at(d, "manager_bad_pool.dcf", 129);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Error);
  EXPECT_THAT(found[0].message, HasSubstr("1F02h sub 02h"));
  EXPECT_THAT(found[0].message, HasSubstr("581h-5FFh"));
  EXPECT_EQ(d.size(), 1U) << d.format();
}

}  // namespace
