// nmt::MasterConfig (nmt/master/master_config.hpp): the master's objects
// of CiA 302-2 §6 as types. The bit positions and units are the spec's (Tables 8-14 for 1F80h,
// Tables 19-25 and §6.3 bytes 1-3 for 1F81h, §6.1 102Ah in 100 us, §6.11 1F89h in ms, §6.13
// 1F90h), the heartbeat entry CiA 301's (node-ID in bits 16-23, time in ms in bits 0-15). The
// DCF path (from_dcf, then build) gives the dictionary NmtMaster::create gives, and a typed
// config of the same values gives it too.
#include "nmt/master/master_config.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using namespace cfg::literals;

std::uint64_t value(const NmtMaster& m, std::uint16_t index, std::uint8_t sub) {
  return m.dictionary().get_unsigned(index, sub).value_or(0xDEADBEEF);
}

NmtMaster built(const MasterConfig& config) {
  auto m = config.build();
  EXPECT_TRUE(m.ok()) << (m.ok() ? "" : m.error().message);
  return std::move(m).value();
}

std::string error_of(const MasterConfig& config) {
  auto s = config.validate();
  return s ? std::string("(valid)") : s.error().message;
}

TEST(MasterConfig, StartupFlagsAreTheBitsOf1F80hTables8To14) {
  const std::vector<std::pair<bool StartupFlags::*, std::uint32_t>> bits{
      {&StartupFlags::master, 1U << 0},               // Table 8
      {&StartupFlags::start_all_nodes, 1U << 1},      // Table 9
      {&StartupFlags::no_auto_operational, 1U << 2},  // Table 10
      {&StartupFlags::no_start_slaves, 1U << 3},      // Table 11
      {&StartupFlags::reset_all_nodes, 1U << 4},      // Table 12
      {&StartupFlags::flying_master, 1U << 5},        // Table 13
      {&StartupFlags::stop_all_nodes, 1U << 6},       // Table 14
  };
  for (const auto& [flag, bit] : bits) {
    StartupFlags f;
    f.master = false;
    f.*flag = true;
    EXPECT_EQ(f.value().value, bit);
    EXPECT_EQ(StartupFlags::from({bit}), f) << bit;
  }
  EXPECT_EQ(StartupFlags{}.value().value, 1U);  // the default: the NMT master, nothing else
}

TEST(MasterConfig, SlaveFlagsAreTheBitsOf1F81hTables19To25WithGuardingInBytes1To3) {
  const std::vector<std::pair<bool SlaveConfig::*, std::uint32_t>> bits{
      {&SlaveConfig::slave, 1U << 0},            // Table 19
      {&SlaveConfig::boot, 1U << 2},             // Table 20
      {&SlaveConfig::mandatory, 1U << 3},        // Table 21
      {&SlaveConfig::keep_alive, 1U << 4},       // Table 22
      {&SlaveConfig::verify_software, 1U << 5},  // Table 23
      {&SlaveConfig::update_software, 1U << 6},  // Table 24
      {&SlaveConfig::restore, 1U << 7},          // Table 25
  };
  for (const auto& [flag, bit] : bits) {
    SlaveConfig s(2_node);
    s.slave = false;
    s.boot = false;
    s.*flag = true;
    EXPECT_EQ(s.assignment().value, bit);
  }
  SlaveConfig guarded(2_node);
  guarded.guarding = GuardingConfig{500ms, 3};
  // §6.3: byte 1 retry factor, bytes 2-3 guard time in ms; bits 0 and 2 by default.
  EXPECT_EQ(guarded.assignment().value, 0x01F40305U);
}

TEST(MasterConfig, BuildsTheObjectsOfCiA302_2Section6WithoutBytesFromTheEmbedder) {
  MasterConfig config(1_node);
  config.startup.start_all_nodes = true;
  config.startup.stop_all_nodes = true;
  SlaveConfig& drive = config.add_slave(3_node);
  drive.mandatory = true;
  drive.keep_alive = true;
  drive.identity.device_type = 0x000F0192;
  drive.identity.vendor_id = 0x0000ABCD;
  drive.identity.product_code = 0x302;
  drive.identity.revision = 0x00010000;
  drive.identity.serial_number = 7;
  drive.heartbeat = 300ms;
  SlaveConfig& io = config.add_slave(5_node);
  io.guarding = GuardingConfig{200ms, 2};
  io.restore = true;
  io.restore_subindex = 2;
  config.boot_time = 10s;
  config.nmt_inhibit_time = 1500us;
  config.flying_master.priority = FlyingMasterConfig::Priority::High;
  config.flying_master.detect_cycle = 0ms;
  const NmtMaster m = built(config);

  EXPECT_EQ(value(m, 0x1F80, 0), 0x43U);  // bits 0, 1 and 6
  EXPECT_EQ(value(m, 0x1F81, 3), 0x1DU);  // slave, boot, mandatory, keep-alive
  EXPECT_EQ(value(m, 0x1F81, 5), 0x00C80285U);
  EXPECT_EQ(value(m, 0x1F81, 4), 0U);
  EXPECT_EQ(value(m, 0x1F84, 3), 0x000F0192U);
  EXPECT_EQ(value(m, 0x1F85, 3), 0x0000ABCDU);
  EXPECT_EQ(value(m, 0x1F86, 3), 0x302U);
  EXPECT_EQ(value(m, 0x1F87, 3), 0x00010000U);
  EXPECT_EQ(value(m, 0x1F88, 3), 7U);
  EXPECT_EQ(value(m, 0x1F85, 5), 0U);  // not checked
  EXPECT_EQ(value(m, 0x1F8A, 5), 2U);
  EXPECT_EQ(value(m, 0x1016, 1), 0x0003012CU);  // node 3, 300 ms
  EXPECT_EQ(value(m, 0x1016, 2), 0U);
  EXPECT_EQ(value(m, 0x1F89, 0), 10000U);  // ms
  EXPECT_EQ(value(m, 0x102A, 0), 15U);     // 100 us units
  EXPECT_EQ(value(m, 0x1F90, 1), 100U);    // Table 50 defaults, priority and sub 6 as set
  EXPECT_EQ(value(m, 0x1F90, 2), 500U);
  EXPECT_EQ(value(m, 0x1F90, 3), 0U);
  EXPECT_EQ(value(m, 0x1F90, 4), 1500U);
  EXPECT_EQ(value(m, 0x1F90, 5), 10U);
  EXPECT_EQ(value(m, 0x1F90, 6), 0U);
  EXPECT_EQ(m.node_id(), 1_node);
}

std::string master_dcf_text() {
  std::ifstream in(std::string(CANOPEN_TEST_DATA_DIR) + "/master/master.dcf");
  std::stringstream text;
  text << in.rdbuf();
  std::string lines = text.str();  // CRLF in the file: the replacements below say \n
  std::erase(lines, '\r');
  return lines;
}

void replace(std::string& text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
}

cfg::DeviceDescription parse(const std::string& text) {
  auto r = cfg::parse_device_description(text);
  EXPECT_TRUE(r.device.has_value()) << r.diagnostics.format();
  return r.device.value_or(cfg::DeviceDescription{});
}

// tests/data/master/master.dcf with 1F80h 0x43, slave 2 guarded, slave 3 mandatory with a
// heartbeat in 1016h sub 4, 1F89h 10 s and 102Ah 1.5 ms.
cfg::DeviceDescription changed_master_dcf() {
  std::string text = master_dcf_text();
  replace(text, "ParameterValue=0x00000001", "ParameterValue=0x00000043");
  replace(text, "[1F81Value]\nNrOfEntries=2\n2=0x00000005\n3=0x00000005",
          "[1F81Value]\nNrOfEntries=2\n2=0x00C80205\n3=0x0000000D");
  replace(text, "CompactSubObj=127\n\n[1017]",
          "CompactSubObj=127\n\n[1016Value]\nNrOfEntries=1\n4=0x0003012C\n\n[1017]");
  replace(text,
          "ParameterName=Boot time\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
          "DefaultValue=0",
          "ParameterName=Boot time\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
          "DefaultValue=10000");
  replace(text,
          "ParameterName=NMT inhibit time\nObjectType=0x7\nDataType=0x0006\nAccessType=rw\n"
          "DefaultValue=0",
          "ParameterName=NMT inhibit time\nObjectType=0x7\nDataType=0x0006\nAccessType=rw\n"
          "DefaultValue=15");
  return parse(text);
}

// The 1016h entries in use, wherever they stand.
std::multiset<std::uint64_t> heartbeat_entries(const NmtMaster& m) {
  std::multiset<std::uint64_t> in_use;
  for (std::uint8_t sub = 1; sub <= 127; ++sub) {
    if (const auto v = value(m, 0x1016, sub); v != 0) in_use.insert(v);
  }
  return in_use;
}

// Every value build() owns (master_config.hpp); the 1016h entries in the same sub-indices when
// `same_1016_layout`, else the same entries anywhere.
void expect_same_master_objects(const NmtMaster& a, const NmtMaster& b, bool same_1016_layout) {
  std::vector<std::pair<std::uint16_t, std::uint8_t>> entries{
      {0x1F80, 0}, {0x1F89, 0}, {0x102A, 0}, {0x1016, 0}};
  entries.emplace_back(0x1017, 0);
  for (std::uint8_t sub = 1; sub <= 6; ++sub) entries.emplace_back(0x1F90, sub);
  for (std::uint8_t n = 1; n <= 127; ++n) {
    for (int index : {0x1F81, 0x1F84, 0x1F85, 0x1F86, 0x1F87, 0x1F88, 0x1F8A, 0x1F26, 0x1F27}) {
      entries.emplace_back(static_cast<std::uint16_t>(index), n);
    }
    if (same_1016_layout) entries.emplace_back(0x1016, n);
  }
  EXPECT_EQ(heartbeat_entries(a), heartbeat_entries(b));
  for (const auto& [index, sub] : entries) {
    EXPECT_EQ(value(a, index, sub), value(b, index, sub)) << std::hex << index << " sub " << +sub;
  }
}

TEST(MasterConfig, TheDcfPathAndATypedConfigOfTheSameValuesGiveTheSameDictionary) {
  const cfg::DeviceDescription dcf = changed_master_dcf();
  auto direct = NmtMaster::create(dcf, 1_node);
  ASSERT_TRUE(direct.ok()) << direct.error().message;
  ASSERT_EQ(value(direct.value(), 0x1016, 4), 0x0003012CU);  // the DCF says what we think

  auto read = MasterConfig::from_dcf(dcf, 1_node);
  ASSERT_TRUE(read.ok()) << read.error().message;
  const MasterConfig& from_dcf = read.value();
  EXPECT_EQ(from_dcf.startup.value().value, 0x43U);
  ASSERT_EQ(from_dcf.slaves.size(), 2U);
  const SlaveConfig* two = from_dcf.slave(2_node);
  const SlaveConfig* three = from_dcf.slave(3_node);
  ASSERT_TRUE(two && three);
  EXPECT_EQ(two->guarding, (GuardingConfig{200ms, 2}));
  EXPECT_FALSE(two->mandatory);
  EXPECT_TRUE(three->mandatory);
  EXPECT_EQ(three->heartbeat, Duration{300ms});
  EXPECT_EQ(three->identity.vendor_id, 0x0000ABCDU);
  EXPECT_EQ(three->identity.product_code, std::nullopt);
  EXPECT_EQ(from_dcf.boot_time, Duration{10s});
  EXPECT_EQ(from_dcf.nmt_inhibit_time, Duration{1500us});
  expect_same_master_objects(built(from_dcf), direct.value(), true);

  // The same in code, on the same DCF (its other objects), but the values typed.
  MasterConfig typed(1_node);
  typed.dcf = parse(master_dcf_text());
  typed.startup.start_all_nodes = true;
  typed.startup.stop_all_nodes = true;
  for (unsigned n : {2U, 3U}) {
    SlaveConfig& s = typed.add_slave(*cfg::NodeId::from(n));
    s.identity.device_type = 0x000F0191;
    s.identity.vendor_id = 0x0000ABCD;
  }
  typed.add_slave(2_node).guarding = GuardingConfig{200ms, 2};
  typed.add_slave(3_node).mandatory = true;
  typed.add_slave(3_node).heartbeat = 300ms;
  typed.boot_time = 10s;
  typed.nmt_inhibit_time = 1500us;
  const NmtMaster from_code = built(typed);
  expect_same_master_objects(from_code, direct.value(), false);
  EXPECT_EQ(value(from_code, 0x1016, 1), 0x0003012CU);  // the first free entry
}

// DSP 302 §9: "Sub-Index i ... Stores the expected application software date/time of the slave
// that has Node-ID i" (1F53h days since 1984-01-01, 1F54h ms after midnight).
TEST(MasterConfig, TheExpectedProgramVersionIs1F53hAnd1F54hSubNodeBothWays) {
  MasterConfig config(1_node);
  SlaveConfig& drive = config.add_slave(3_node);
  drive.verify_software = true;
  drive.program_version = cfg::ProgramVersion{15671, 29'700'000};
  config.add_slave(4_node);
  const NmtMaster m = built(config);
  EXPECT_EQ(value(m, 0x1F53, 3), 15671U);
  EXPECT_EQ(value(m, 0x1F54, 3), 29'700'000U);
  EXPECT_EQ(value(m, 0x1F53, 4), 0U) << "unset: not configured";
  EXPECT_EQ(value(m, 0x1F54, 4), 0U);

  const MasterConfig back = MasterConfig::from_dictionary(m.dictionary(), 1_node);
  ASSERT_NE(back.slave(3_node), nullptr);
  EXPECT_EQ(back.slave(3_node)->program_version, (cfg::ProgramVersion{15671, 29'700'000}));
  ASSERT_NE(back.slave(4_node), nullptr);
  EXPECT_EQ(back.slave(4_node)->program_version, std::nullopt);

  // Table 1 G's "not configured" cannot be an expected version.
  config.add_slave(3_node).program_version = cfg::ProgramVersion{};
  EXPECT_EQ(error_of(config),
            "slave 3: program version 0, 0 means 'not configured' in 1F53h/1F54h; leave it "
            "unset");
}

TEST(MasterConfig, ASlaveRemovedInCodeFromADcfConfigIsNoLongerAssigned) {
  auto read = MasterConfig::from_dcf(changed_master_dcf(), 1_node);
  ASSERT_TRUE(read.ok()) << read.error().message;
  MasterConfig config = std::move(read).value();
  std::erase_if(config.slaves, [](const SlaveConfig& s) { return s.node == 3_node; });
  const NmtMaster m = built(config);
  EXPECT_EQ(value(m, 0x1F81, 3), 0U);
  EXPECT_EQ(value(m, 0x1F85, 3), 0U);
  EXPECT_EQ(value(m, 0x1016, 4), 0U);  // its heartbeat entry is cleared
  EXPECT_EQ(value(m, 0x1F81, 2), 0x00C80205U);
}

TEST(MasterConfig, ADcfWithFewerHeartbeatEntriesThanConfiguredFailsSayingSo) {
  std::string text = master_dcf_text();
  replace(text, "CompactSubObj=127\n\n[1017]", "CompactSubObj=1\n\n[1017]");
  MasterConfig config(1_node);
  config.dcf = parse(text);
  config.add_slave(2_node).heartbeat = 100ms;
  config.add_slave(3_node).heartbeat = 100ms;
  auto m = config.build();
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().message,
            "1016h has 1 entries: no room for the heartbeat of node 3 (2 wanted); give 1016h "
            "more entries in the master DCF (SubNumber or CompactSubObj) or consume fewer "
            "heartbeats");
}

TEST(MasterConfig, ValidateNamesTheSlaveAndTheValueInWords) {
  MasterConfig config(1_node);
  EXPECT_EQ(error_of(config), "(valid)");

  config.add_slave(1_node);
  EXPECT_EQ(error_of(config),
            "slave 1: is the master's own node-ID; remove it or give the master another");
  config.slaves.clear();

  config.slaves.emplace_back(2_node);
  config.slaves.emplace_back(2_node);
  EXPECT_EQ(error_of(config),
            "slave 2: listed twice; keep one entry per node (add_slave gives the one there)");
  config.slaves.pop_back();

  config.add_slave(2_node).heartbeat = 70s;
  EXPECT_EQ(error_of(config),
            "slave 2: heartbeat time 70000 ms is above 65535 ms (1016h: 1..65535 ms); give "
            "whole ms in that range, or leave it unset");
  config.add_slave(2_node).heartbeat = 1500us;
  EXPECT_EQ(error_of(config),
            "slave 2: heartbeat time 1500 us is not a whole number of "
            "milliseconds (1016h: 1..65535 ms); give whole ms in that range, or leave it unset");
  config.add_slave(2_node).heartbeat = 0ms;
  EXPECT_EQ(error_of(config),
            "slave 2: heartbeat time 0 ms is below 1 ms (1016h: 1..65535 ms); give whole ms in "
            "that range, or leave it unset");
  config.add_slave(2_node).heartbeat.reset();

  config.add_slave(2_node).guarding = GuardingConfig{100ms, 0};
  EXPECT_EQ(error_of(config),
            "slave 2: retry factor 0 disables guarding (1F81h byte 1: 1..255); "
            "leave guarding unset instead");
  config.add_slave(2_node).guarding = GuardingConfig{0ms, 3};
  EXPECT_EQ(error_of(config),
            "slave 2: guard time 0 ms is below 1 ms (1F81h bytes 2-3: 1..65535 ms); give whole "
            "ms in that range, or leave guarding unset");
  config.add_slave(2_node).guarding.reset();

  config.add_slave(2_node).identity.vendor_id = 0;
  EXPECT_EQ(error_of(config),
            "slave 2: expected vendor-ID 0 means 'not checked' in 1F85h sub 02h; leave it unset");
  config.add_slave(2_node).identity.vendor_id.reset();

  config.nmt_inhibit_time = 150us;
  EXPECT_EQ(error_of(config),
            "NMT inhibit time (102Ah) 150 us is not a multiple of 100 us up to 6553500 us; round "
            "it to one");
  config.nmt_inhibit_time = 6553600us;
  EXPECT_NE(error_of(config), "(valid)");
  config.nmt_inhibit_time = 6553500us;
  EXPECT_EQ(error_of(config), "(valid)");

  // §6.13: priority time slot > 127 x device time slot.
  config.flying_master.device_time_slot = 12ms;
  EXPECT_EQ(error_of(config),
            "flying master priority time slot 1500 ms must exceed 127 x the "
            "device time slot 12 ms (CiA 302-2 §6.13); lengthen the one or shorten the other");
  config.flying_master.device_time_slot = 11ms;
  EXPECT_EQ(error_of(config), "(valid)");

  config.boot_time = 1500us;
  auto m = config.build();
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().message,
            "boot time (1F89h) 1500 us is not a whole number of milliseconds; give whole ms up to "
            "4294967295 (0: retried without end)");
}

// CiA 306 lets a DCF list only some sub-indices of an ARRAY (1F81h with SubNumber=3: subs 0-2),
// and the master reads an absent 1F81h/1F84h-1F88h entry as 0 (CiA 302-2 §6.3: not a slave, not
// checked). The DCF path builds such a master, with the listed values and 0 elsewhere.
TEST(MasterConfig, ADcfListingOnlySome1F81hSubIndicesBuildsWithTheOthersZero) {
  std::ifstream in(std::string(CANOPEN_TEST_DATA_DIR) + "/network/master_wrong_vendor.dcf");
  std::stringstream text;
  text << in.rdbuf();
  const cfg::DeviceDescription dcf = parse(text.str());
  ASSERT_NE(dcf.sub(0x1F81, 2), nullptr);
  ASSERT_EQ(dcf.sub(0x1F81, 3), nullptr);  // the file lists subs 0-2 only
  auto read = MasterConfig::from_dcf(dcf, 1_node);
  ASSERT_TRUE(read.ok()) << read.error().message;
  const NmtMaster m = built(read.value());
  auto direct = NmtMaster::create(dcf, 1_node);
  ASSERT_TRUE(direct.ok()) << direct.error().message;
  EXPECT_EQ(value(m, 0x1F81, 2), 0x0000000DU);  // the file's ParameterValue (slave, bits 0, 2, 3)
  EXPECT_EQ(value(direct.value(), 0x1F81, 2), 0x0000000DU);
  // Sub 3 stays absent (no entry to fill), as on the direct path: the master reads it as 0.
  EXPECT_FALSE(m.dictionary().get_unsigned(0x1F81, 3).has_value());
  EXPECT_FALSE(direct.value().dictionary().get_unsigned(0x1F81, 3).has_value());
}

// CiA 301 1017h (the master's own heartbeat) and DSP 302 §6.6 1F26h/1F27h (the configuration
// date and time expected in a slave's 1020h) as typed fields: read from the DCF, built, changed.
TEST(MasterConfig, ProducerHeartbeatAndExpectedConfigurationAreReadFromTheDcfAndBuilt) {
  std::string text = master_dcf_text();
  replace(text,
          "ParameterName=Producer heartbeat time\nObjectType=0x7\nDataType=0x0006\nAccessType=rw\n"
          "DefaultValue=0",
          "ParameterName=Producer heartbeat time\nObjectType=0x7\nDataType=0x0006\nAccessType=rw\n"
          "DefaultValue=500");
  replace(text, "CompactSubObj=127\n\n[1F27]",
          "CompactSubObj=127\n\n[1F26Value]\nNrOfEntries=1\n3=0x00002A4B\n\n[1F27]");
  replace(text, "CompactSubObj=127\n\n[1F53]",
          "CompactSubObj=127\n\n[1F27Value]\nNrOfEntries=1\n3=0x02160EC0\n\n[1F53]");
  const cfg::DeviceDescription dcf = parse(text);
  auto read = MasterConfig::from_dcf(dcf, 1_node);
  ASSERT_TRUE(read.ok()) << read.error().message;
  MasterConfig config = read.value();
  EXPECT_EQ(config.heartbeat_producer, Duration{500ms});
  ASSERT_NE(config.slave(3_node), nullptr);
  EXPECT_EQ(config.slave(3_node)->expected_configuration,
            (cfg::ConfigurationStamp{0x2A4B, 0x02160EC0}));
  ASSERT_NE(config.slave(2_node), nullptr);
  EXPECT_TRUE(config.slave(2_node)->expected_configuration.is_zero());
  auto direct = NmtMaster::create(dcf, 1_node);
  ASSERT_TRUE(direct.ok()) << direct.error().message;
  expect_same_master_objects(built(config), direct.value(), true);

  config.heartbeat_producer = 250ms;
  config.add_slave(2_node).expected_configuration = {1, 2};
  config.add_slave(3_node).expected_configuration = {};
  const NmtMaster m = built(config);
  EXPECT_EQ(value(m, 0x1017, 0), 250U);
  EXPECT_EQ(value(m, 0x1F26, 2), 1U);
  EXPECT_EQ(value(m, 0x1F27, 2), 2U);
  EXPECT_EQ(value(m, 0x1F26, 3), 0U);  // 0: not verified
  EXPECT_EQ(value(m, 0x1F27, 3), 0U);
  EXPECT_EQ(value(m, 0x1F26, 4), 0U);  // no slave

  config.heartbeat_producer = 70s;
  EXPECT_EQ(error_of(config),
            "producer heartbeat time (1017h) 70000 ms is above 65535 ms; give whole ms up to "
            "65535 (0: no heartbeat)");
}

// A value for a sub-index the DCF does not list: the error says what to change.
TEST(MasterConfig, ASlaveBeyondTheDcfsSubIndicesFailsSayingWhatToDo) {
  std::ifstream in(std::string(CANOPEN_TEST_DATA_DIR) + "/network/master_wrong_vendor.dcf");
  std::stringstream text;
  text << in.rdbuf();
  auto read = MasterConfig::from_dcf(parse(text.str()), 1_node);
  ASSERT_TRUE(read.ok()) << read.error().message;
  MasterConfig config = read.value();
  config.add_slave(5_node);  // 1F81h bits 0 and 2 (Tables 19, 20): 5
  auto m = config.build();
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.error().message,
            "the master DCF has no 1F81h sub 05h for the value 5; list that sub-index in the "
            "master DCF (raise the object's SubNumber) or leave the value 0");
}

}  // namespace
}  // namespace nmt
