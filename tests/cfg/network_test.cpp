// The network description (cfg/network.hpp): CiA 306-3 project files, a master DCF alone, and
// the master's dictionary derived from the nodes' DCFs. The files are in tests/data/network
// (written for these tests; README.md there says what each holds).
#include "cfg/network.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include "cfg/bytes.hpp"
#include "cfg/value.hpp"
#include "test_paths.hpp"

namespace {
using namespace cfg::literals;

using ::testing::HasSubstr;

std::string data(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/network/" + name;
}

// A UNSIGNED32 entry of a description as its dictionary will hold it (ParameterValue, else
// DefaultValue).
std::uint32_t value_of(const cfg::DeviceDescription& d, std::uint16_t index, std::uint8_t sub) {
  const cfg::SubObject* entry = d.sub(index, sub);
  if (entry == nullptr || !entry->configured_value()) {
    ADD_FAILURE() << "no value at " << std::hex << index << " sub " << int{sub};
    return 0;
  }
  auto value = cfg::parse_value(cfg::DataType::Unsigned32, *entry->configured_value());
  EXPECT_TRUE(value.ok());
  return value ? static_cast<std::uint32_t>(value->as_unsigned()) : 0;
}

const cfg::Diagnostic* find_diagnostic(const cfg::Diagnostics& diagnostics,
                                       const std::string& text) {
  for (const auto& d : diagnostics.items()) {
    if (d.message.find(text) != std::string::npos) return &d;
  }
  return nullptr;
}

TEST(Network, LoadsTheFirstTopologyOfAProjectFile) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const cfg::Network& net = *load.network;
  EXPECT_EQ(net.name, "test cell");
  EXPECT_EQ(net.net, 1U);
  // Node5Present=0x00: named but not present (CiA 306-3), so not loaded.
  ASSERT_EQ(net.nodes.size(), 2U);
  EXPECT_EQ(net.nodes[0].node_id, 2_node);
  EXPECT_EQ(net.nodes[0].name, "io left");
  EXPECT_EQ(net.nodes[1].node_id, 3_node);
  EXPECT_EQ(net.nodes[1].name, "axis x");
  EXPECT_EQ(net.find(5_node), nullptr);
  EXPECT_FALSE(net.master_from_file);
  EXPECT_FALSE(net.master_node_id.has_value());
}

TEST(Network, DcfPathsAreRelativeToTheProjectFile) {
  // Loaded from another working directory: the project names "nodes/io_node2.dcf".
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(std::filesystem::temp_directory_path());
  const auto load = cfg::load_network(data("nodelist.cpj"));
  std::filesystem::current_path(cwd);
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  EXPECT_EQ(load.network->nodes[0].file, data("nodes/io_node2.dcf"));
  ASSERT_TRUE(load.network->nodes[0].dcf.has_value());
}

TEST(Network, WindowsSeparatorsInDcfNamesAreTriedAsSlashes) {
  // backslash.cpj: Node2DCFName=nodes\io_node2.dcf, as tools on Windows write it.
  const auto load = cfg::load_network(data("backslash.cpj"));
  ASSERT_TRUE(load.network.has_value()) << load.diagnostics.format();
  EXPECT_EQ(find_diagnostic(load.diagnostics, "io_node2.dcf"), nullptr);
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].file, data("nodes/io_node2.dcf"));
  EXPECT_EQ(load.network->eds_base_dir, data("eds"));
}

TEST(Network, ANodesCountThatDiffersFromThePresentNodesIsAWarning) {
  // backslash.cpj: Nodes=0x02 with one node present (line 4).
  const auto load = cfg::load_network(data("backslash.cpj"));
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "Nodes=0x02");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Warning);
  EXPECT_EQ(d->line, 4);
}

TEST(Network, APresentFlagThatIsNotZeroOrOneIsAnError) {
  // backslash.cpj: Node9Present=2 (line 8).
  const auto load = cfg::load_network(data("backslash.cpj"));
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "Node9Present=2");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Error);
  EXPECT_EQ(d->line, 8);
}

TEST(Network, NetOptionSelectsTopology2) {
  cfg::NetworkOptions options;
  options.net = 2;
  const auto load = cfg::load_network(data("nodelist.cpj"), options);
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  EXPECT_EQ(load.network->name, "second net");
  EXPECT_EQ(load.network->net, 2U);
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].node_id, 4_node);
}

TEST(Network, AMissingTopologyIsAnErrorNamingTheNetworksThereAre) {
  cfg::NetworkOptions options;
  options.net = 3;
  const auto load = cfg::load_network(data("nodelist.cpj"), options);
  EXPECT_FALSE(load.network.has_value());
  ASSERT_EQ(load.diagnostics.size(), 1U);
  EXPECT_THAT(load.diagnostics.items()[0].message, HasSubstr("[Topology3]"));
  EXPECT_THAT(load.diagnostics.items()[0].message, HasSubstr("networks 1, 2"));
}

TEST(Network, AMissingDcfIsAnErrorAtTheLineThatNamesIt) {
  const auto load = cfg::load_network(data("missing.cpj"));
  EXPECT_FALSE(load.ok());
  EXPECT_FALSE(load.unreadable);  // the project file was read; its content names a missing file
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "absent.dcf");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->file, data("missing.cpj"));
  EXPECT_EQ(d->line, 8);  // Node2DCFName=nodes/absent.dcf
  EXPECT_EQ(d->severity, cfg::Severity::Error);
  EXPECT_THAT(d->message, HasSubstr("Node2DCFName"));
  // The other node is still loaded.
  ASSERT_TRUE(load.network.has_value());
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].node_id, 3_node);
}

TEST(Network, ReportsANodeIdClashBetweenProjectFileAndDcf) {
  const auto load = cfg::load_network(data("clash.cpj"));
  EXPECT_FALSE(load.ok());
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "node-ID clash");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->file, data("clash.cpj"));
  EXPECT_EQ(d->line, 8);  // Node6DCFName=nodes/io_node2.dcf
  EXPECT_THAT(d->message, HasSubstr("NodeID is 2"));
  EXPECT_THAT(d->message, HasSubstr("node-ID 6"));
}

TEST(Network, TheProjectFileGivesTheNodeIdOfTheWrites) {
  // $NODEID and the node-ID of the writes are the project's, even where the DCF clashes.
  const auto load = cfg::load_network(data("clash.cpj"));
  ASSERT_TRUE(load.network.has_value());
  EXPECT_NE(load.network->find(6_node), nullptr);
}

TEST(Network, NodeWritesAreTheDcfsConfiguredValues) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& writes = load.network->nodes[0].writes;
  // io_node2.dcf: 1017h ParameterValue=1000 (UNSIGNED16), 2000h ParameterValue=0x12.
  EXPECT_NE(std::find(writes.begin(), writes.end(), cfg::ObjectWrite{0x1017, 0, {0xE8, 0x03}}),
            writes.end());
  EXPECT_NE(std::find(writes.begin(), writes.end(), cfg::ObjectWrite{0x2000, 0, {0x12}}),
            writes.end());
}

// --- the derived master (rules in cfg/network.hpp)
// ------------------------------------------------

TEST(Network, DerivedMasterMakesEveryPresentNodeAMandatoryBootedSlave) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& m = load.network->master;
  ASSERT_TRUE(m.commissioning && m.commissioning->canopen_manager.value_or(false));
  // CiA 302-2 §6.2 Table 8: bit 0, NMT master.
  EXPECT_EQ(value_of(m, 0x1F80, 0), 0x00000001U);
  // CiA 302-2 §6.3: bit 0 slave, bit 2 boot, bit 3 mandatory = 0Dh; heartbeat nodes: no guarding.
  EXPECT_EQ(value_of(m, 0x1F81, 0), 0x7FU);
  EXPECT_EQ(value_of(m, 0x1F81, 2), 0x0000000DU);
  EXPECT_EQ(value_of(m, 0x1F81, 3), 0x0000000DU);
  EXPECT_EQ(value_of(m, 0x1F81, 5), 0U);  // not present
  EXPECT_EQ(value_of(m, 0x1F81, 127), 0U);
}

TEST(Network, DerivedMasterTakesGuardingFrom100Ch100DhIntoSlaveAssignment) {
  cfg::NetworkOptions options;
  options.net = 2;
  const auto load = cfg::load_network(data("nodelist.cpj"), options);
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  // guarded_node4.dcf: 100Ch = 100 ms, 100Dh = 3, 1017h = 0. CiA 302-2 §6.3: bytes 2-3 guard
  // time (0064h), byte 1 retry factor (03h), byte 0 = 0Dh.
  EXPECT_EQ(value_of(load.network->master, 0x1F81, 4), 0x0064030DU);
  const cfg::SlaveAssignment a{value_of(load.network->master, 0x1F81, 4)};
  EXPECT_EQ(a.guard_time_ms(), 100);
  EXPECT_EQ(a.retry_factor(), 3);
  // No heartbeat: no consumer entry.
  EXPECT_EQ(value_of(load.network->master, 0x1016, 1), 0U);
}

TEST(Network, DerivedMasterExpectsTheIdentityOfEachDcf) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& m = load.network->master;
  // io_node2.dcf: 1000h = 0x00030191, 1018h sub 1-3 = 0xABC, 0x401, 0x00010002.
  EXPECT_EQ(value_of(m, 0x1F84, 2), 0x00030191U);
  EXPECT_EQ(value_of(m, 0x1F85, 2), 0x00000ABCU);
  EXPECT_EQ(value_of(m, 0x1F86, 2), 0x00000401U);
  EXPECT_EQ(value_of(m, 0x1F87, 2), 0x00010002U);
  // drive_node3.dcf: 1018h has sub 1 only; product and revision from [DeviceInfo].
  EXPECT_EQ(value_of(m, 0x1F84, 3), 0x00020192U);
  EXPECT_EQ(value_of(m, 0x1F85, 3), 0x00000ABCU);
  EXPECT_EQ(value_of(m, 0x1F86, 3), 0x00000402U);
  EXPECT_EQ(value_of(m, 0x1F87, 3), 0x00020004U);
  // A serial number belongs to one device: not expected.
  EXPECT_EQ(m.object(0x1F88), nullptr) << "1F88h is left to the engine's default (0)";
}

TEST(Network, DerivedMasterConsumesTheHeartbeatOfEachProducer) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& m = load.network->master;
  // CiA 301 §7.5.2.26: node-ID in bits 16-23, time in ms in bits 0-15. Node 2 produces every
  // 1000 ms -> 2 x 1000 + 100 = 2100 ms; node 3 every 500 ms -> 1100 ms.
  EXPECT_EQ(value_of(m, 0x1016, 1), 0x00020834U);
  EXPECT_EQ(value_of(m, 0x1016, 2), 0x0003044CU);
  EXPECT_EQ(value_of(m, 0x1016, 3), 0U);
  EXPECT_EQ(cfg::heartbeat_consumer_time_ms(0), 0);
  EXPECT_EQ(cfg::heartbeat_consumer_time_ms(60000), 0xFFFF);
}

TEST(Network, DerivedMasterExpectsTheStampOfEachConfiguration) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& net = *load.network;
  for (const auto& node : net.nodes) {
    const auto stamp = cfg::configuration_stamp(cfg::encode_concise_dcf(node.writes));
    EXPECT_EQ(value_of(net.master, 0x1F26, node.node_id), stamp.days);
    EXPECT_EQ(value_of(net.master, 0x1F27, node.node_id), stamp.ms);
    // DSP 302 §6.3: days since 1 January 1984, ms after midnight.
    EXPECT_GE(stamp.days, 5844U);
    EXPECT_LT(stamp.days, 5844U + 18263U);
    EXPECT_LT(stamp.ms, 86'400'000U);
  }
  // Nodes that are not there: 0, "do not verify".
  EXPECT_EQ(value_of(net.master, 0x1F26, 4), 0U);
}

TEST(Network, ConfigurationStampIsFnv1aMappedToADateAndTime) {
  // FNV-1a 64 of "" is CBF29CE484222325h and of "a" AF63DC4C8601EC8Ch (the published test
  // vectors); days = 5844 + high word mod 18263, ms = low word mod 86 400 000.
  EXPECT_EQ(cfg::configuration_stamp({}), (cfg::ConfigurationStamp{16203, 56829733}));
  const std::uint8_t a[] = {'a'};
  EXPECT_EQ(cfg::configuration_stamp(a), (cfg::ConfigurationStamp{10281, 1873036}));
}

TEST(Network, AChangedValueChangesTheExpectedConfigurationDateAndTime) {
  const auto load = cfg::load_network(data("nodelist.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  std::vector<cfg::NetworkNode> nodes = load.network->nodes;
  const auto before = cfg::derive_master(nodes);
  // 2000h of node 2 from 0x12 to 0x13: one bit of one downloaded value.
  for (auto& w : nodes[0].writes) {
    if (w.index == 0x2000) w.data = {0x13};
  }
  const auto after = cfg::derive_master(nodes);
  EXPECT_NE(value_of(before, 0x1F26, 2), value_of(after, 0x1F26, 2));
  EXPECT_NE(value_of(before, 0x1F27, 2), value_of(after, 0x1F27, 2));
  // Node 3 did not change.
  EXPECT_EQ(value_of(before, 0x1F26, 3), value_of(after, 0x1F26, 3));
  EXPECT_EQ(value_of(before, 0x1F27, 3), value_of(after, 0x1F27, 3));
}

// --- the master's own DCF
// -------------------------------------------------------------------------

TEST(Network, AMasterDcfInTheProjectRulesTheBoot) {
  const auto load = cfg::load_network(data("wrong_identity.cpj"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& net = *load.network;
  EXPECT_TRUE(net.master_from_file);
  EXPECT_EQ(net.master_file, data("master_wrong_vendor.dcf"));
  ASSERT_TRUE(net.master_node_id.has_value());
  EXPECT_EQ(*net.master_node_id, 1_node);
  // The master is no slave; its 1F85h is taken as written.
  ASSERT_EQ(net.nodes.size(), 1U);
  EXPECT_EQ(net.nodes[0].node_id, 2_node);
  EXPECT_EQ(value_of(net.master, 0x1F85, 2), 0x00000BADU);
}

TEST(Network, AMasterDcfAloneNamesNodeFilesWithDownloadFile) {
  const auto load = cfg::load_network(data("master.dcf"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const auto& net = *load.network;
  EXPECT_TRUE(net.master_from_file);
  ASSERT_TRUE(net.master_node_id.has_value());
  EXPECT_EQ(*net.master_node_id, 1_node);
  ASSERT_EQ(net.nodes.size(), 2U);
  // 1F20h sub 2: a DCF.
  EXPECT_EQ(net.nodes[0].node_id, 2_node);
  EXPECT_TRUE(net.nodes[0].dcf.has_value());
  EXPECT_EQ(net.nodes[0].file, data("nodes/io_node2.dcf"));
  // 1F22h sub 3: tests/data/concise/heartbeat_1000.bin, one entry 1017h sub 0 = 1000 (DSP 302
  // §6.2 layout).
  EXPECT_EQ(net.nodes[1].node_id, 3_node);
  EXPECT_FALSE(net.nodes[1].dcf.has_value());
  EXPECT_EQ(net.nodes[1].writes, (std::vector<cfg::ObjectWrite>{{0x1017, 0, {0xE8, 0x03}}}));
  EXPECT_EQ(value_of(net.master, 0x1F81, 3), 0x00000005U);
}

TEST(Network, ASlaveDcfAloneIsNoNetworkDescription) {
  const auto load = cfg::load_network(data("nodes/io_node2.dcf"));
  EXPECT_FALSE(load.network.has_value());
  EXPECT_NE(find_diagnostic(load.diagnostics, "CANopenManager=1"), nullptr)
      << load.diagnostics.format();
}

TEST(Network, AnUnreadableDescriptionIsAnIoError) {
  const auto load = cfg::load_network(data("no_such_file.cpj"));
  EXPECT_FALSE(load.network.has_value());
  EXPECT_TRUE(load.unreadable);
  ASSERT_EQ(load.diagnostics.size(), 1U);
  EXPECT_EQ(load.diagnostics.items()[0].file, data("no_such_file.cpj"));
}

TEST(Network, TheSampleCellProjectLoadsWithoutDiagnostics) {
  const auto load = cfg::load_network(std::string(CANOPEN_SAMPLES_DIR) + "/network/nodelist.cpj");
  EXPECT_TRUE(load.diagnostics.empty()) << load.diagnostics.format();
  ASSERT_TRUE(load.ok());
  const auto& net = *load.network;
  EXPECT_EQ(net.name, "sample cell");
  ASSERT_EQ(net.nodes.size(), 3U);
  // samples/network/io_module_node4.dcf: 1000h 0x000F0191, 1018h sub 1 0x7E57C0DE, sub 2
  // 0x00000401, sub 3 0x00010002; 1017h ParameterValue=1000 -> consumer 2100 ms.
  EXPECT_EQ(value_of(net.master, 0x1F84, 4), 0x000F0191U);
  EXPECT_EQ(value_of(net.master, 0x1F85, 4), 0x7E57C0DEU);
  EXPECT_EQ(value_of(net.master, 0x1F86, 4), 0x00000401U);
  EXPECT_EQ(value_of(net.master, 0x1F87, 4), 0x00010002U);
  EXPECT_EQ(value_of(net.master, 0x1016, 3), 0x00040834U);
}

}  // namespace
