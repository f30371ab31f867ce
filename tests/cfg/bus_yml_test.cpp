// The bus.yml reader (cfg/bus_yml.hpp) on files written for these tests (tests/data/bus_yml,
// README.md there), in both layouts; values from lely dcfgen's rules (dcfgen/cli.py,
// master.dcf.em) applied by hand to samples/drive.eds and samples/io_module.eds. The corpus's
// bus.yml files against dcfgen's own output are in dcfgen_vectors_test.cpp.
#include "cfg/bus_yml.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <string>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/value.hpp"
#include "test_paths.hpp"

namespace {
using namespace cfg::literals;

using ::testing::HasSubstr;

std::string data(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/bus_yml/" + name;
}

// The value a node's download leaves in an entry (its last write), as an unsigned number.
std::optional<std::uint64_t> after_download(const cfg::NetworkNode& node, std::uint16_t index,
                                            std::uint8_t sub) {
  std::optional<std::uint64_t> out;
  for (const auto& w : node.writes) {
    if (w.index == index && w.sub_index == sub) out = cfg::load_le(w.data, w.data.size());
  }
  return out;
}

// A UNSIGNED32 entry of the master's dictionary (ParameterValue, else DefaultValue; 0 absent).
std::uint32_t master_value(const cfg::Network& network, std::uint16_t index, std::uint8_t sub) {
  const cfg::SubObject* s = network.master.sub(index, sub);
  if (s == nullptr || !s->configured_value()) return 0;
  auto v = cfg::parse_value(cfg::DataType::Unsigned32, *s->configured_value());
  return v ? static_cast<std::uint32_t>(v->as_unsigned()) : 0xDEADBEEF;
}

const cfg::Diagnostic* find_diagnostic(const cfg::Diagnostics& diagnostics,
                                       const std::string& text) {
  for (const auto& d : diagnostics.items()) {
    if (d.message.find(text) != std::string::npos) return &d;
  }
  return nullptr;
}

// The one error of a bad file: at `line` of the file, containing `text`; no network usable.
void expect_error_at(const std::string& file, int line, const std::string& text,
                     const cfg::NetworkOptions& options = {}) {
  const auto load = cfg::load_network(data(file), options);
  EXPECT_FALSE(load.ok());
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, text);
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Error) << d->message;
  EXPECT_EQ(d->file, data(file));
  EXPECT_EQ(d->line, line) << d->message;
}

TEST(BusYml, YmlAndYamlFilesAreBusDescriptions) {
  EXPECT_TRUE(cfg::is_bus_yml_path("config/bus.yml"));
  EXPECT_TRUE(cfg::is_bus_yml_path("master.YAML"));
  EXPECT_FALSE(cfg::is_bus_yml_path("nodelist.cpj"));
  EXPECT_FALSE(cfg::is_bus_yml_path("master.dcf"));
}

TEST(BusYml, LelyLayoutGivesOneNodePerSlaveKeyAndSkipsDotKeys) {
  const auto load = cfg::load_network(data("lely.yml"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const cfg::Network& net = *load.network;
  ASSERT_EQ(net.nodes.size(), 3U);  // io, axis_x, axis_y; not .axis
  EXPECT_EQ(net.nodes[0].node_id, 2_node);
  EXPECT_EQ(net.nodes[0].name, "io");
  EXPECT_EQ(net.nodes[1].name, "axis_x");
  EXPECT_EQ(net.nodes[2].name, "axis_y");
  ASSERT_TRUE(net.master_node_id.has_value());
  EXPECT_EQ(*net.master_node_id, 1_node);
  EXPECT_FALSE(net.master_from_file);
  ASSERT_TRUE(net.master.commissioning.has_value());
  EXPECT_EQ(net.master.commissioning->baudrate_kbps, 250);
}

TEST(BusYml, PdoSettingsBecomeTheSlavesConfiguration) {
  const auto load = cfg::load_network(data("lely.yml"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const cfg::NetworkNode& io = *load.network->find(2_node);
  // tpdo 1: cob_id 0x1A2, transmission 0xFF, inhibit_time 50, mapping 6000h sub 1/2 (UNSIGNED8:
  // 8 bits each, CiA 301 §7.5.2.38).
  EXPECT_EQ(after_download(io, 0x1800, 1), 0x1A2U);
  EXPECT_EQ(after_download(io, 0x1800, 2), 0xFFU);
  EXPECT_EQ(after_download(io, 0x1800, 3), 50U);
  EXPECT_EQ(after_download(io, 0x1A00, 0), 2U);
  EXPECT_EQ(after_download(io, 0x1A00, 1), 0x60000108U);
  EXPECT_EQ(after_download(io, 0x1A00, 2), 0x60000208U);
  // tpdo 2: enabled: false: the pre-defined COB-ID 280h + node-ID, bit 31 set.
  EXPECT_EQ(after_download(io, 0x1801, 1), 0x80000282U);
  // heartbeat_producer: 500, then sdo 1017h = 250: the later write wins, as on the device.
  EXPECT_EQ(after_download(io, 0x1017, 0), 250U);

  // axis_x, from the .axis anchor (merge key): tpdo 1 cob_id auto = 180h + 3, event timer 20,
  // 6041h (UNSIGNED16) and 6064h (INTEGER32); rpdo 1 cob_id auto = 200h + 3, 6040h and 607Ah.
  const cfg::NetworkNode& x = *load.network->find(3_node);
  EXPECT_EQ(after_download(x, 0x1800, 1), 0x183U);
  EXPECT_EQ(after_download(x, 0x1800, 2), 1U);
  EXPECT_EQ(after_download(x, 0x1800, 5), 20U);
  EXPECT_EQ(after_download(x, 0x1A00, 1), 0x60410010U);
  EXPECT_EQ(after_download(x, 0x1A00, 2), 0x60640020U);
  EXPECT_EQ(after_download(x, 0x1400, 1), 0x203U);
  EXPECT_EQ(after_download(x, 0x1600, 1), 0x60400010U);
  EXPECT_EQ(after_download(x, 0x1600, 2), 0x607A0020U);
  EXPECT_EQ(after_download(x, 0x1017, 0), 200U);
  // axis_y: the same PDOs for node 4.
  EXPECT_EQ(after_download(*load.network->find(4_node), 0x1800, 1), 0x184U);
}

TEST(BusYml, TheMastersObjectsFollowDcfgen) {
  const auto load = cfg::load_network(data("lely.yml"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const cfg::Network& net = *load.network;
  // master.dcf.em: 1F80h = 1 (NMT master) | 10h (reset_all_nodes: true).
  EXPECT_EQ(master_value(net, 0x1F80, 0), 0x11U);
  EXPECT_EQ(master_value(net, 0x1017, 0), 100U);    // heartbeat_producer
  EXPECT_EQ(master_value(net, 0x1006, 0), 10000U);  // sync_period (us)
  EXPECT_EQ(master_value(net, 0x1F89, 0), 5000U);   // boot_time (ms)
  EXPECT_EQ(master_value(net, 0x102A, 0), 10U);     // nmt_inhibit_time (100 us)
  // 1F81h: io slave | boot | keep alive (reset_communication: false) = 15h; axis_x mandatory
  // (from the anchor) = 0Dh; axis_y overrides the anchor's mandatory = 05h.
  EXPECT_EQ(master_value(net, 0x1F81, 2), 0x15U);
  EXPECT_EQ(master_value(net, 0x1F81, 3), 0x0DU);
  EXPECT_EQ(master_value(net, 0x1F81, 4), 0x05U);
  // 1016h: a slave's heartbeat_producer x heartbeat_multiplier (options: 2.0): io 500 ms ->
  // 1000 ms, axis_x 200 -> 400 ms; axis_y produces none.
  EXPECT_EQ(master_value(net, 0x1016, 1), 0x000203E8U);
  EXPECT_EQ(master_value(net, 0x1016, 2), 0x00030190U);
  EXPECT_EQ(master_value(net, 0x1016, 3), 0U);
}

TEST(BusYml, TheRosKeysAreNamedOnceAsNotUsed) {
  const auto load = cfg::load_network(data("lely.yml"));
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "not used by cfgmgr");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Note);
  EXPECT_EQ(d->line, 18);  // .axis: driver
  EXPECT_THAT(d->message, HasSubstr(": driver"));
  EXPECT_EQ(load.diagnostics.count(cfg::Severity::Warning), 0U) << load.diagnostics.format();
}

TEST(BusYml, Ros2LayoutGivesEachNodeTheDefaultsItDoesNotSet) {
  const auto load = cfg::load_network(data("ros2.yml"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  const cfg::Network& net = *load.network;
  ASSERT_EQ(net.nodes.size(), 2U);
  EXPECT_EQ(*net.master_node_id, 0x7F_node);
  const cfg::NetworkNode& a = *net.find(5_node);
  EXPECT_EQ(a.name, "axis_1");
  EXPECT_EQ(after_download(a, 0x1017, 0), 100U);  // defaults.heartbeat_producer
  EXPECT_EQ(after_download(a, 0x6060, 0), 8U);    // defaults.sdo
  EXPECT_EQ(after_download(a, 0x1800, 1), 0x185U);
  EXPECT_EQ(after_download(a, 0x1A00, 1), 0x60410010U);
  // axis_2 sets heartbeat_producer itself: the node's value wins (cogen.py would let the
  // default's 100 overwrite it), with a warning at the node's key.
  const cfg::NetworkNode& b = *net.find(6_node);
  EXPECT_EQ(after_download(b, 0x1017, 0), 250U);
  EXPECT_EQ(after_download(b, 0x1800, 1), 0x186U);
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "nodes.axis_2.heartbeat_producer");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Warning);
  EXPECT_EQ(d->line, 32);
  EXPECT_THAT(d->message, HasSubstr("defaults.heartbeat_producer (line 15)"));
  // 1016h: 100 x 3.0 (dcfgen's default multiplier) and 250 x 3.0.
  EXPECT_EQ(master_value(net, 0x1016, 1), 0x0005012CU);
  EXPECT_EQ(master_value(net, 0x1016, 2), 0x000602EEU);
}

TEST(BusYml, ACmakePlaceholderInDcfPathIsANoteOnly) {
  const auto load = cfg::load_network(data("ros2.yml"));
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "@BUS_CONFIG_PATH@");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Note);
  EXPECT_EQ(d->line, 3);
}

TEST(BusYml, ACmakePlaceholderInAPathIsAnErrorUntilItIsGiven) {
  expect_error_at("placeholder.yml", 4, "holds the CMake placeholder @IO_DIR@");
  cfg::NetworkOptions options;
  options.placeholders["IO_DIR"] = std::string(CANOPEN_TEST_DATA_DIR) + "/../../samples";
  const auto load = cfg::load_network(data("placeholder.yml"), options);
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  EXPECT_EQ(load.network->nodes.size(), 1U);
}

TEST(BusYml, TruncatedYamlIsAnErrorAtTheParsersLine) {
  expect_error_at("truncated.yml", 8, "not valid YAML");
}

TEST(BusYml, ASlaveWithoutDcfIsAnErrorAtItsKey) {
  expect_error_at("no_dcf.yml", 3, "io: no dcf");
}

TEST(BusYml, MappingAnObjectTheEdsLacksIsAnErrorAtTheEntry) {
  expect_error_at("missing_object.yml", 10, "io.tpdo.1: mapping: 7123h sub 00h is not in");
}

TEST(BusYml, ANodeIdGivenTwiceIsAnErrorAtTheSecond) {
  expect_error_at("node_id_clash.yml", 8, "node-ID clash: 2 is also the node-ID of io_a (line 5)");
}

TEST(BusYml, TwoTpdosOnOneCanIdAreAnErrorAtTheSecondCobId) {
  // io_a tpdo 1 cob_id 0x183; io_b (node 3) tpdo 1 cob_id auto = 180h + 3.
  expect_error_at("cob_id_clash.yml", 12,
                  "COB-ID 0x183 is also the COB-ID of io_a TPDO 1 (line 7)");
}

TEST(BusYml, AWrongTypeIsAnErrorAndAnUnknownKeyAWarning) {
  expect_error_at("wrong_type.yml", 5, "io.node_id: expected an integer");
  const auto load = cfg::load_network(data("wrong_type.yml"));
  const cfg::Diagnostic* d = find_diagnostic(load.diagnostics, "io.mandatroy: unknown key");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Warning);
  EXPECT_EQ(d->line, 6);
}

TEST(BusYml, FlowCollectionsNestedDeeperThan64AreRefusedBeforeParsing) {
  // yaml-cpp parses [ ] and { } by recursion: 100000 of them would exhaust the stack.
  const std::string path = ::testing::TempDir() + "/deep.yml";
  {
    std::ofstream out(path);
    out << "master: {node_id: 1}\nio: " << std::string(100000, '[') << "\n";
  }
  const auto load = cfg::load_network(path);
  EXPECT_FALSE(load.ok());
  ASSERT_NE(find_diagnostic(load.diagnostics, "nested more than 64 deep"), nullptr)
      << load.diagnostics.format();
}

TEST(BusYml, AFileThatIsNotThereIsUnreadable) {
  const auto load = cfg::load_network(data("absent.yml"));
  EXPECT_TRUE(load.unreadable);
  EXPECT_FALSE(load.ok());
}

}  // namespace
