// Our concise DCFs against the ones lely's dcfgen produced (corpus README, "Concise DCF vector
// sets"). dcfgen reads a YAML bus description plus each slave's EDS/DCF; so do we: each test
// reads the set's bus.yml with the bus.yml reader (cfg/bus_yml.hpp, through load_network), whose
// slaves are the EDS/DCF with the YAML's settings applied as ParameterValues. The comparison is
// semantic: the state a device is left in (the last value written to each entry), plus the
// PDO-safe order of our stream. Every place where our stream differs is listed in the test with
// the reason, and in tests/cfg/dcfgen-differences.md.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/download_order.hpp"
#include "cfg/network.hpp"
#include "cfg/value.hpp"
#include "concise_test_support.hpp"
#include "prerequisite.hpp"
#include "scratch_dir.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

using ::testing::ElementsAreArray;
using ::testing::IsEmpty;

std::string corpus(const std::string& relative) {
  return std::string(CANOPEN_CORPUS_DIR) + "/" + relative;
}

#define SKIP_WITHOUT_CORPUS()                                       \
  if (!std::filesystem::exists(corpus("MANIFEST.tsv"))) {           \
    PREREQUISITE_MISSING("corpus not found: ", CANOPEN_CORPUS_DIR); \
  }

DeviceDescription load(const std::string& relative) {
  ReadOptions options;
  options.file_name = relative;
  auto read = read_device_file(corpus(relative), options);
  EXPECT_TRUE(read.device.has_value()) << read.diagnostics.format();
  EXPECT_FALSE(read.diagnostics.has_errors()) << read.diagnostics.format();
  return read.device ? *read.device : DeviceDescription{};
}

std::vector<ObjectWrite> load_bin(const std::string& relative) {
  auto entries = decode_concise_dcf(test_support::read_bytes(corpus(relative)));
  EXPECT_TRUE(entries.ok()) << relative << ": " << entries.error().message;
  return entries.ok() ? *entries : std::vector<ObjectWrite>{};
}

// A corpus set's bus.yml and the device files it names, copied into a fresh directory under
// the names the bus.yml uses (the corpus prefixes some of them with the set's name), and read
// with the bus.yml reader (cfg/bus_yml.hpp): the configuration of each slave is the reader's,
// not a translation by hand.
Network load_bus_yml_set(const std::string& set, const std::string& yml,
                         const std::vector<std::pair<std::string, std::string>>& files,
                         NetworkOptions options = {}) {
  namespace fs = std::filesystem;
  // The test's own directory (CTest runs the tests of one set side by side), removed once the
  // network is read: a Network holds its files' contents, not their paths.
  const test_support::ScratchDir scratch;
  const fs::path dir = scratch.path() / set;
  fs::create_directories(dir);
  fs::copy_file(corpus(set + "/" + yml), dir / "bus.yml");
  for (const auto& [from, to] : files) {
    fs::create_directories((dir / to).parent_path());
    fs::copy_file(corpus(set + "/" + from), dir / to);
  }
  auto load = load_network((dir / "bus.yml").string(), options);
  EXPECT_TRUE(load.ok()) << load.diagnostics.format();
  return load.network ? std::move(*load.network) : Network{};
}

const NetworkNode& node_of(const Network& network, std::uint8_t id) {
  const NetworkNode* node = network.find(*NodeId::from(id));
  EXPECT_NE(node, nullptr) << "node " << int{id};
  static const NetworkNode none;
  return node != nullptr ? *node : none;
}

// A UNSIGNED32 entry of a master DCF as its dictionary holds it (ParameterValue, else
// DefaultValue); 0 when absent, as a CompactSubObj array's unset entries are.
std::uint32_t u32_of(const DeviceDescription& dcf, std::uint16_t index, std::uint8_t sub) {
  const SubObject* s = dcf.sub(index, sub);
  if (s == nullptr || !s->configured_value() || s->configured_value()->empty()) return 0;
  auto v = parse_value(DataType::Unsigned32, *s->configured_value());
  return v ? static_cast<std::uint32_t>(v->as_unsigned()) : 0xDEADBEEF;
}

std::vector<ObjectWrite> our_writes(const DeviceDescription& dcf, std::uint8_t node_id,
                                    ConciseSelection selection = ConciseSelection::Configured) {
  ConciseOptions options;
  options.node_id = node_id;
  options.selection = selection;
  options.file_name = "test";
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options, diagnostics);
  EXPECT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_FALSE(diagnostics.has_errors()) << diagnostics.format();
  return writes ? *writes : std::vector<ObjectWrite>{};
}

std::string entry_text(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%04Xsub%X =", index, sub);
  std::string out = buf;
  for (auto b : d) {
    std::snprintf(buf, sizeof buf, " %02X", b);
    out += buf;
  }
  return out;
}

// The state a stream leaves a device in: the last value written to each entry.
std::map<std::pair<std::uint16_t, std::uint8_t>, std::vector<std::uint8_t>> final_state(
    const std::vector<ObjectWrite>& writes) {
  std::map<std::pair<std::uint16_t, std::uint8_t>, std::vector<std::uint8_t>> state;
  for (const auto& w : writes) state[{w.index, w.sub_index}] = w.data;
  return state;
}

// "ours only: ...", "dcfgen only: ...", "differs: ... (dcfgen: ...)", in entry order.
std::vector<std::string> differences(const std::vector<ObjectWrite>& ours,
                                     const std::vector<ObjectWrite>& dcfgen) {
  auto a = final_state(ours);
  auto b = final_state(dcfgen);
  std::vector<std::string> out;
  for (const auto& [key, data] : a) {
    auto it = b.find(key);
    if (it == b.end()) {
      out.push_back("ours only: " + entry_text(key.first, key.second, data));
    } else if (it->second != data) {
      out.push_back("differs: " + entry_text(key.first, key.second, data) +
                    " (dcfgen:" + entry_text(key.first, key.second, it->second).substr(10) + ")");
    }
  }
  for (const auto& [key, data] : b) {
    if (a.count(key) == 0) out.push_back("dcfgen only: " + entry_text(key.first, key.second, data));
  }
  return out;
}

// CiA 301 PDO rules checked on a stream applied to a device whose PDOs may be valid: a mapping
// entry is written only while the mapping is deactivated (sub-index 0 last written 0) and the
// PDO is invalid (COB-ID last written with bit 31 set). Returns the entries that break it.
std::vector<std::string> pdo_rule_violations(const std::vector<ObjectWrite>& writes) {
  std::map<std::uint16_t, std::uint8_t> count;  // mapping index -> last sub 0 written
  std::map<std::uint16_t, bool> invalid;        // comm index -> last COB-ID had bit 31
  std::vector<std::string> out;
  for (const auto& w : writes) {
    auto pdo = pdo_indices_of(w.index);
    if (!pdo) continue;
    if (w.index == pdo->comm_index && w.sub_index == 1 && w.data.size() == 4) {
      invalid[w.index] = (w.data[3] & 0x80) != 0;
    } else if (w.index == pdo->mapping_index && w.sub_index == 0 && w.data.size() == 1) {
      count[w.index] = w.data[0];
    } else if (w.index == pdo->mapping_index) {
      const bool deactivated = count.count(w.index) != 0 && count[w.index] == 0;
      const bool pdo_invalid = invalid.count(pdo->comm_index) != 0 && invalid[pdo->comm_index];
      if (!deactivated || !pdo_invalid) out.push_back(entry_text(w.index, w.sub_index, w.data));
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// canopen-binding-kingpigeon: gen_master.yml slave_2 + slaves_dcf/m150c.dcf -> slave_2.bin

TEST(DcfgenVectors, KingPigeonM150Slave2) {
  SKIP_WITHOUT_CORPUS();
  // slave_2: node_id 2; rpdo 1 {enabled: true, transmission: 0x01} (cob_id and mapping as in
  // the DCF); sdo 1800h/1802h sub 5 = 0, 1016h sub 1 = 0x14000, 1017h = 0x4000;
  // heartbeat_consumer/heartbeat_producer: false.
  const Network network = load_bus_yml_set("canopen-binding-kingpigeon", "gen_master.yml",
                                           {{"m150c.dcf", "slaves_dcf/m150c.dcf"}});
  const auto& ours = node_of(network, 2).writes;
  const auto dcfgen = load_bin("canopen-binding-kingpigeon/slave_2.bin");
  EXPECT_THAT(pdo_rule_violations(ours), IsEmpty());
  // We disable TPDO1/TPDO3 around their event-timer writes (DSP 302 §6.2 step 1 for any
  // communication parameter) and so write their COB-ID back at the end; dcfgen writes sub-index 5
  // of a valid PDO directly. Same values, one more entry each.
  EXPECT_THAT(differences(ours, dcfgen),
              ElementsAreArray(std::vector<std::string>{
                  "ours only: 1800sub1 = 82 01 00 00",  // $NodeID + 0x180
                  "ours only: 1802sub1 = 82 03 00 00",  // $NodeID + 0x380
              }));
}

// ---------------------------------------------------------------------------------------------
// starnus-ros2_canopen-build: cia402__bus.yml + cia402_slave.eds -> cia402_device_{1,2}.bin
// (lely's flat layout as cogen.py wrote it, with YAML anchors: rpdo: &id001 ... rpdo: *id001)

Network starnus_cia402() {
  return load_bus_yml_set("starnus-ros2_canopen-build", "cia402__bus.yml",
                          {{"cia402__cia402_slave.eds", "cia402_slave.eds"}});
}

// The differences are the same for both nodes: dcfgen leaves out PDO settings equal to the EDS
// default (TPDO transmission type 1, TPDO3/4 already disabled in this EDS); we write what the
// configuration says, so a device whose stored state differs from its EDS still ends up right.
// The ChangedOnly selection gives dcfgen's set exactly (next test).
std::vector<std::string> starnus_cia402_differences(unsigned node) {
  char tpdo3[64];
  char tpdo4[64];
  std::snprintf(tpdo3, sizeof tpdo3, "ours only: 1802sub1 = %02X 03 00 80", 0x80 + node);
  std::snprintf(tpdo4, sizeof tpdo4, "ours only: 1803sub1 = %02X 04 00 80", 0x80 + node);
  return {"ours only: 1800sub2 = 01", "ours only: 1801sub2 = 01", tpdo3, tpdo4};
}

TEST(DcfgenVectors, Ros2CanopenCia402Device1And2) {
  SKIP_WITHOUT_CORPUS();
  const Network network = starnus_cia402();
  EXPECT_EQ(network.nodes.size(), 6u);  // cia402_device_1..6, node-IDs 2..7
  for (auto [node, bin] : {std::pair<std::uint8_t, const char*>{2, "cia402__cia402_device_1.bin"},
                           {3, "cia402__cia402_device_2.bin"}}) {
    const auto& ours = node_of(network, node).writes;
    const auto dcfgen = load_bin(std::string("starnus-ros2_canopen-build/") + bin);
    EXPECT_THAT(pdo_rule_violations(ours), IsEmpty()) << bin;
    EXPECT_THAT(differences(ours, dcfgen), ElementsAreArray(starnus_cia402_differences(node)))
        << bin;
    // dcfgen never disables these PDOs before remapping them: it trusts the EDS default (bit 31
    // set). On a device that had them valid (stored configuration), its mapping writes break the
    // CiA 301 rule; ours do not.
    EXPECT_THAT(pdo_rule_violations(dcfgen).size(), 8u) << bin;
  }
}

TEST(DcfgenVectors, Ros2CanopenCia402ChangedOnlyMatchesDcfgenState) {
  SKIP_WITHOUT_CORPUS();
  const Network network = starnus_cia402();
  const NetworkNode& node = node_of(network, 2);
  ASSERT_TRUE(node.dcf.has_value());
  const auto ours = our_writes(*node.dcf, 2, ConciseSelection::ChangedOnly);
  const auto dcfgen = load_bin("starnus-ros2_canopen-build/cia402__cia402_device_1.bin");
  // ChangedOnly leaves out the two mapping entries equal to the EDS default (RPDO1 entry 1 =
  // 6040h, TPDO1 entry 1 = 6041h); dcfgen writes whole mappings. A device at its defaults ends
  // in the same state: setting sub-index 0 to 0 and back does not clear the entries (CiA 301).
  EXPECT_THAT(differences(ours, dcfgen),
              ElementsAreArray(std::vector<std::string>{"dcfgen only: 1600sub1 = 10 00 40 60",
                                                        "dcfgen only: 1A00sub1 = 10 00 41 60"}));
  EXPECT_THAT(pdo_rule_violations(ours), IsEmpty());
}

TEST(DcfgenVectors, Ros2CanopenCia402MasterAsDcfgenWroteIt) {
  SKIP_WITHOUT_CORPUS();
  const Network network = starnus_cia402();
  const DeviceDescription dcfgen = load("starnus-ros2_canopen-build/cia402__master.dcf");
  ASSERT_TRUE(network.master_node_id.has_value());
  EXPECT_EQ(network.master_node_id->value(), 1);  // master: node_id: 1
  // sync_period: 10000 (us) -> 1006h; the start flags -> 1F80h = 1 (NMT master, the rest
  // default).
  for (std::uint16_t index : {std::uint16_t{0x1006}, std::uint16_t{0x1F80}}) {
    EXPECT_EQ(u32_of(network.master, index, 0), u32_of(dcfgen, index, 0)) << std::hex << index;
  }
  // 1F81h (slave, boot; not mandatory: dcfgen's default), 1F84h-1F86h (the EDS's identity),
  // 1F87h (revision_number: 0), 1016h (no slave produces a heartbeat: no entries).
  for (std::uint8_t node = 1; node <= 127; ++node) {
    for (int index : {0x1F81, 0x1F84, 0x1F85, 0x1F86, 0x1F87, 0x1F88, 0x1016}) {
      EXPECT_EQ(u32_of(network.master, static_cast<std::uint16_t>(index), node),
                u32_of(dcfgen, static_cast<std::uint16_t>(index), node))
          << std::hex << index << " sub " << std::dec << int{node};
    }
  }
}

// ---------------------------------------------------------------------------------------------
// starnus-ros2_canopen-build: robot_control__bus.yml + cia402_slave.eds -> joint_{1,2}.bin

void expect_robot_control_joints(const Network& network, const std::string& set,
                                 const std::string& prefix) {
  // position_mode, switching_state, driver, package, period: ros2_canopen settings, not
  // device configuration (the reader names them in one note).
  for (auto [node, bin] :
       {std::pair<std::uint8_t, const char*>{2, "joint_1.bin"}, {3, "joint_2.bin"}}) {
    const auto& ours = node_of(network, node).writes;
    const auto dcfgen = load_bin(set + "/" + prefix + bin);
    EXPECT_THAT(differences(ours, dcfgen), IsEmpty()) << bin;
    EXPECT_THAT(pdo_rule_violations(ours), IsEmpty()) << bin;
    EXPECT_THAT(pdo_rule_violations(dcfgen), IsEmpty()) << bin;
    // Same stream up to order: dcfgen writes the sdo list in YAML order (..., 6083h, 6060h), we
    // write index order (6060h first) after the PDOs.
    EXPECT_EQ(ours.size(), dcfgen.size()) << bin;
    EXPECT_EQ(pdo_safe_order(dcfgen), ours) << bin;
  }
}

TEST(DcfgenVectors, Ros2CanopenRobotControlJoints) {
  SKIP_WITHOUT_CORPUS();
  expect_robot_control_joints(
      load_bus_yml_set("starnus-ros2_canopen-build", "robot_control__bus.yml",
                       {{"robot_control__cia402_slave.eds", "cia402_slave.eds"}}),
      "starnus-ros2_canopen-build", "robot_control__");
}

// ---------------------------------------------------------------------------------------------
// ros2_canopen-dcfgen: ros2_canopen's own test configurations as it ships them, with the
// dcf_path placeholder "@BUS_CONFIG_PATH@" (not read: the EDS is found beside the bus.yml).

TEST(DcfgenVectors, Ros2CanopenShippedRobotControlJoints) {
  SKIP_WITHOUT_CORPUS();
  expect_robot_control_joints(
      load_bus_yml_set("ros2_canopen-dcfgen", "robot_control/bus.yml",
                       {{"robot_control/cia402_slave.eds", "cia402_slave.eds"}}),
      "ros2_canopen-dcfgen", "robot_control/");
}

TEST(DcfgenVectors, Ros2CanopenShippedCia402DefaultsAndNodes) {
  SKIP_WITHOUT_CORPUS();
  // The defaults/nodes layout: cia402_device_1 {node_id: 2, namespace} gets every key of
  // defaults (dcf, the sdo list, tpdo 1-4, rpdo 1-2 with 607Ah and 60FFh).
  const Network network = load_bus_yml_set("ros2_canopen-dcfgen", "cia402/bus.yml",
                                           {{"cia402/cia402_slave.eds", "cia402_slave.eds"}});
  ASSERT_EQ(network.nodes.size(), 1u);
  const auto& ours = node_of(network, 2).writes;
  const auto dcfgen = load_bin("ros2_canopen-dcfgen/cia402/cia402_device_1.bin");
  EXPECT_THAT(pdo_rule_violations(ours), IsEmpty());
  // The same differences as the starnus build of the same configuration (above).
  EXPECT_THAT(differences(ours, dcfgen), ElementsAreArray(starnus_cia402_differences(2)));
}

// ---------------------------------------------------------------------------------------------
// ros_canopen-motion_controller_driver: pilz.yaml + pilz.eds -> prbt_joint_1.bin

TEST(DcfgenVectors, PilzPrbtJoint1) {
  SKIP_WITHOUT_CORPUS();
  // prbt_joint_1: node_id 3; tpdo 1 {6041h, 6061h, 6064h}, 2 {606Bh, 606Ch}; rpdo 1 {6040h,
  // 60C1h sub 1, 6042h}, 2 {607Ah, 6081h}; all enabled, cob_id as in the EDS.
  const Network network = load_bus_yml_set("ros_canopen-motion_controller_driver", "pilz.yaml",
                                           {{"pilz.eds", "pilz.eds"}});
  const auto& ours = node_of(network, 3).writes;
  const auto dcfgen = load_bin("ros_canopen-motion_controller_driver/prbt_joint_1.bin");
  EXPECT_THAT(pdo_rule_violations(ours), IsEmpty());
  EXPECT_THAT(pdo_rule_violations(dcfgen), IsEmpty());
  // pilz.eds is a DCF in all but name: 29 ParameterValues. A DCF's ParameterValues are its
  // configuration, so we download those the YAML does not override; dcfgen ignores them and
  // writes only what the YAML says.
  EXPECT_THAT(differences(ours, dcfgen),
              ElementsAreArray(std::vector<std::string>{
                  "ours only: 1017sub0 = 64 00",        // [1017] ParameterValue=100
                  "ours only: 1400sub2 = 01",           // [1400sub2] ParameterValue=0x1
                  "ours only: 1401sub2 = 01",           // [1401sub2] ParameterValue=0x1
                  "ours only: 1800sub2 = 01",           // [1800sub2] ParameterValue=0x1
                  "ours only: 1802sub1 = 83 03 00 00",  // [1802sub1] ParameterValue=$NODEID+0x380
                  "ours only: 1802sub2 = 01",           // [1802sub2] ParameterValue=0x1
                  "ours only: 1A02sub0 = 02",           // [1A02sub0] ParameterValue=2
                  "ours only: 1A02sub1 = 20 00 64 60",  // [1A02sub1] ParameterValue=0x60640020
                  "ours only: 1A02sub2 = 20 00 6C 60",  // [1A02sub2] ParameterValue=0x606c0020
                  "ours only: 2060sub2 = 00",     // [2060sub2] ParameterValue=0 (sub 1, 3: ro)
                  "ours only: 6060sub0 = 07",     // [6060] ParameterValue=7
                  "ours only: 60C0sub0 = 00 00",  // [60C0] ParameterValue=0
                  "ours only: 60C2sub1 = 0A",     // [60C2sub1] ParameterValue=10
              }));
}

// ---------------------------------------------------------------------------------------------
// odrive-cia402-profile: master.yaml + odrive-canopen-cia402.dcf -> master.dcf, master.bin.
// The only concise DCF of this set is the master's own: dcfgen puts the expected revision and
// serial numbers of slaves 2..5 (1F87h/1F88h, CiA 302-2 §6) into master.bin. They come from
// the slave DCF's 1018h sub 3/sub 4, which the YAML does not override.

TEST(DcfgenVectors, OdriveMasterExpectedIdentity) {
  SKIP_WITHOUT_CORPUS();
  const Network network =
      load_bus_yml_set("odrive-cia402-profile", "master.yaml",
                       {{"odrive-canopen-cia402.dcf", "odrive-canopen-cia402.dcf"}});
  ASSERT_EQ(network.nodes.size(), 4u);  // motor_1..motor_4: node_id 2..5
  const auto dcfgen = load_bin("odrive-cia402-profile/master.bin");
  // Every value master.bin holds is the value our master's dictionary has.
  ASSERT_FALSE(dcfgen.empty());
  for (const auto& w : dcfgen) {
    ASSERT_EQ(w.data.size(), 4u) << entry_text(w.index, w.sub_index, w.data);
    EXPECT_EQ(u32_of(network.master, w.index, w.sub_index), load_le(w.data, 4))
        << entry_text(w.index, w.sub_index, w.data);
  }
  // mandatory: true -> 1F81h bit 3 (with bits 0 and 2: slave, boot), as dcfgen's master.dcf.
  const DeviceDescription master = load("odrive-cia402-profile/master.dcf");
  for (std::uint8_t node = 2; node <= 5; ++node) {
    EXPECT_EQ(u32_of(network.master, 0x1F81, node), u32_of(master, 0x1F81, node)) << int{node};
    EXPECT_EQ(u32_of(network.master, 0x1F81, node), 0x0Du) << int{node};
  }
  ASSERT_TRUE(network.master.commissioning.has_value());
  EXPECT_EQ(network.master.commissioning->baudrate_kbps, 500);  // master: baudrate: 500
}

}  // namespace
}  // namespace cfg
