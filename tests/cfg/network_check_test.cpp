// cfg::check_network: the checks across the nodes of a network description. Files in
// tests/data/network_check (README there); the values and lines asserted are those files'.
#include "cfg/network_check.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "cfg/network.hpp"

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

// CiA 301 §7.5.2.38: 1A00h sub 1 = 0x20000008 maps 2000h sub 0, whose PDOMapping=0 (line 156
// is its section): the device would abort 0604 0041.
TEST(NetworkCheck, MappingAnObjectWithPdoMapping0IsAnError) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 136);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Error);
  EXPECT_THAT(found[0].message, HasSubstr("maps 2000h sub 00h, which is not mappable"));
  EXPECT_THAT(found[0].message, HasSubstr("0604 0041"));
}

TEST(NetworkCheck, MappingAnObjectTheDcfDoesNotHaveIsAnError) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 145);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Error);
  EXPECT_THAT(found[0].message, HasSubstr("maps 2100h sub 00h, which the DCF does not have"));
}

// 0x60000008: 8 bits of 6000h, an UNSIGNED16 (CiA 301 §7.1: 16 bits).
TEST(NetworkCheck, AMappedLengthThatIsNotTheTypesSizeIsAWarning) {
  const cfg::Diagnostics d = checked("clash.cpj");
  const auto found = at(d, "sensor_node3.dcf", 154);
  ASSERT_EQ(found.size(), 1U) << d.format();
  EXPECT_EQ(found[0].severity, cfg::Severity::Warning);
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

}  // namespace
