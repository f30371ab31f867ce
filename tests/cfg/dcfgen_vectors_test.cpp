// Our concise DCFs against the ones lely's dcfgen produced (corpus README, "Concise DCF vector
// sets"). dcfgen reads a YAML bus description plus each slave's EDS/DCF; we read a DCF. So each
// test below reads the slave's EDS/DCF from the corpus and applies the YAML's settings as
// ParameterValues, hand-translated line by line (the comments quote the YAML). The comparison is
// semantic: the state a device is left in (the last value written to each entry), plus the
// PDO-safe order of our stream. Every place where our stream differs is listed in the test with
// the reason, and in tests/cfg/dcfgen-differences.md.
//
// Hand-translation rules (lely dcfgen semantics of its YAML keys):
// - rpdo/tpdo N `enabled: true`, `cob_id: auto` (or no cob_id): COB-ID = CiA 301 pre-defined
//   connection set, RPDO N: 200h + 100h*(N-1) + node-ID, TPDO N: 180h + 100h*(N-1) + node-ID.
//   `enabled: false`: the same COB-ID with bit 31 set (PDO not valid).
// - `transmission: T`: communication sub-index 2 = T.
// - `mapping: [{index, sub_index}...]`: mapping sub-index 0 = number of entries, sub-index k =
//   index << 16 | sub_index << 8 | bit length of the entry's data type in the EDS.
// - `sdo: [{index, sub_index, value}...]`: ParameterValue = value.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/download_order.hpp"
#include "concise_test_support.hpp"
#include "prerequisite.hpp"
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

std::string hex32(std::uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08X", v);
  return buf;
}

// YAML `sdo:` entry or any other setting: the value becomes the entry's ParameterValue.
void set(DeviceDescription& dcf, std::uint16_t index, std::uint8_t sub, const std::string& value) {
  SubObject* s = dcf.sub(index, sub);
  ASSERT_NE(s, nullptr) << std::hex << index << "sub" << int{sub} << " not in the device file";
  s->parameter_value = value;
}

// YAML `mapping:` entry: index << 16 | sub-index << 8 | bit length of the data type.
std::string mapping_entry(const DeviceDescription& dcf, std::uint16_t index, std::uint8_t sub) {
  const SubObject* s = dcf.sub(index, sub);
  EXPECT_NE(s, nullptr) << std::hex << index << "sub" << int{sub} << " not in the device file";
  if (s == nullptr || !s->basic_type()) return "0";
  const unsigned bits = data_type_info(*s->basic_type()).size_bytes * 8u;
  return hex32(static_cast<std::uint32_t>(index) << 16 | static_cast<std::uint32_t>(sub) << 8 |
               bits);
}

using Mapping = std::vector<std::pair<std::uint16_t, std::uint8_t>>;
struct Pdo {
  bool enabled = true;
  std::optional<int> transmission;
  Mapping mapping;
};
Pdo mapped(Mapping mapping, std::optional<int> transmission = std::nullopt) {
  return {true, transmission, std::move(mapping)};
}
Pdo transmission_only(int transmission) {
  return {true, transmission, {}};
}
Pdo disabled() {
  return {false, std::nullopt, {}};
}

// YAML rpdo/tpdo N (N from 1) with cob_id auto.
void configure_pdo(DeviceDescription& dcf, bool receive, int n, const Pdo& pdo) {
  const auto comm = static_cast<std::uint16_t>((receive ? 0x1400 : 0x1800) + n - 1);
  const unsigned base = (receive ? 0x200u : 0x180u) + 0x100u * static_cast<unsigned>(n - 1);
  set(dcf, comm, 1, "$NODEID+" + hex32(base | (pdo.enabled ? 0u : kCobIdInvalidBit)));
  if (pdo.transmission) set(dcf, comm, 2, std::to_string(*pdo.transmission));
  if (pdo.mapping.empty()) return;
  const auto map = static_cast<std::uint16_t>(comm + 0x200);
  set(dcf, map, 0, std::to_string(pdo.mapping.size()));
  for (std::size_t k = 0; k < pdo.mapping.size(); ++k) {
    set(dcf, map, static_cast<std::uint8_t>(k + 1),
        mapping_entry(dcf, pdo.mapping[k].first, pdo.mapping[k].second));
  }
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
  DeviceDescription dcf = load("canopen-binding-kingpigeon/m150c.dcf");
  // slave_2: node_id: 2
  // rpdo: 1: {enabled: true, transmission: 0x01}   (cob_id auto, mapping as in the DCF)
  configure_pdo(dcf, true, 1, transmission_only(0x01));
  // sdo:
  set(dcf, 0x1800, 5, "0");        // - {index: 0x1800, sub_index: 0x05, value: 0}
  set(dcf, 0x1802, 5, "0");        // - {index: 0x1802, sub_index: 0x05, value: 0}
  set(dcf, 0x1016, 1, "0x14000");  // - {index: 0x1016, sub_index: 0x01, value: 0x14000}
  set(dcf, 0x1017, 0, "0x4000");   // - {index: 0x1017, sub_index: 0x00, value: 0x4000}
  // heartbeat_consumer/heartbeat_producer: false configure the master, not this stream.

  const auto ours = our_writes(dcf, 2);
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

DeviceDescription starnus_cia402_dcf() {
  DeviceDescription dcf = load("starnus-ros2_canopen-build/cia402__cia402_slave.eds");
  // rpdo: 1: {cob_id: auto, enabled: true, mapping: [{24640, 0}, {24672, 0}]}  (6040h, 6060h)
  configure_pdo(dcf, true, 1, mapped({{0x6040, 0}, {0x6060, 0}}));
  //       2: {cob_id: auto, enabled: true, mapping: [{24698, 0}, {24831, 0}]}  (607Ah, 60FFh)
  configure_pdo(dcf, true, 2, mapped({{0x607A, 0}, {0x60FF, 0}}));
  // tpdo: 1: {..., mapping: [{24641, 0}, {24673, 0}], transmission: 1}  (6041h, 6061h)
  configure_pdo(dcf, false, 1, mapped({{0x6041, 0}, {0x6061, 0}}, 1));
  //       2: {..., mapping: [{24676, 0}, {24684, 0}], transmission: 1}  (6064h, 606Ch)
  configure_pdo(dcf, false, 2, mapped({{0x6064, 0}, {0x606C, 0}}, 1));
  //       3: {enabled: false}, 4: {enabled: false}
  configure_pdo(dcf, false, 3, disabled());
  configure_pdo(dcf, false, 4, disabled());
  // sdo: {24770, 1, 50}, {24770, 2, -3}, {24705, 0, 1000}, {24707, 0, 2000}
  set(dcf, 0x60C2, 1, "50");
  set(dcf, 0x60C2, 2, "-3");
  set(dcf, 0x6081, 0, "1000");
  set(dcf, 0x6083, 0, "2000");
  return dcf;
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
  const DeviceDescription dcf = starnus_cia402_dcf();
  for (auto [node, bin] : {std::pair<std::uint8_t, const char*>{2, "cia402__cia402_device_1.bin"},
                           {3, "cia402__cia402_device_2.bin"}}) {
    const auto ours = our_writes(dcf, node);
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
  const auto ours = our_writes(starnus_cia402_dcf(), 2, ConciseSelection::ChangedOnly);
  const auto dcfgen = load_bin("starnus-ros2_canopen-build/cia402__cia402_device_1.bin");
  // ChangedOnly leaves out the two mapping entries equal to the EDS default (RPDO1 entry 1 =
  // 6040h, TPDO1 entry 1 = 6041h); dcfgen writes whole mappings. A device at its defaults ends
  // in the same state: setting sub-index 0 to 0 and back does not clear the entries (CiA 301).
  EXPECT_THAT(differences(ours, dcfgen),
              ElementsAreArray(std::vector<std::string>{"dcfgen only: 1600sub1 = 10 00 40 60",
                                                        "dcfgen only: 1A00sub1 = 10 00 41 60"}));
  EXPECT_THAT(pdo_rule_violations(ours), IsEmpty());
}

// ---------------------------------------------------------------------------------------------
// starnus-ros2_canopen-build: robot_control__bus.yml + cia402_slave.eds -> joint_{1,2}.bin

TEST(DcfgenVectors, Ros2CanopenRobotControlJoints) {
  SKIP_WITHOUT_CORPUS();
  DeviceDescription dcf = load("starnus-ros2_canopen-build/robot_control__cia402_slave.eds");
  // tpdo: 1: {enabled: true, cob_id: "auto", transmission: 0x01,
  //           mapping: [{0x6041, 0}, {0x6061, 0}]}
  configure_pdo(dcf, false, 1, mapped({{0x6041, 0}, {0x6061, 0}}, 0x01));
  //       2: {..., transmission: 0x01, mapping: [{0x6064, 0}, {0x606c, 0}]}
  configure_pdo(dcf, false, 2, mapped({{0x6064, 0}, {0x606C, 0}}, 0x01));
  // rpdo: 1: {enabled: true, cob_id: "auto", mapping: [{0x6040, 0}, {0x6060, 0}]}
  configure_pdo(dcf, true, 1, mapped({{0x6040, 0}, {0x6060, 0}}));
  //       2: {enabled: true, cob_id: "auto", mapping: [{0x607A, 0}]}
  configure_pdo(dcf, true, 2, mapped({{0x607A, 0}}));
  // sdo: {0x60C2, 1, 50}, {0x60C2, 2, -3}, {0x6081, 0, 1000}, {0x6083, 0, 2000}, {0x6060, 0, 7}
  set(dcf, 0x60C2, 1, "50");
  set(dcf, 0x60C2, 2, "-3");
  set(dcf, 0x6081, 0, "1000");
  set(dcf, 0x6083, 0, "2000");
  set(dcf, 0x6060, 0, "7");
  // position_mode, switching_state, driver, package, period: ros2_canopen settings, not
  // device configuration.
  for (auto [node, bin] : {std::pair<std::uint8_t, const char*>{2, "robot_control__joint_1.bin"},
                           {3, "robot_control__joint_2.bin"}}) {
    const auto ours = our_writes(dcf, node);
    const auto dcfgen = load_bin(std::string("starnus-ros2_canopen-build/") + bin);
    EXPECT_THAT(differences(ours, dcfgen), IsEmpty()) << bin;
    EXPECT_THAT(pdo_rule_violations(ours), IsEmpty()) << bin;
    EXPECT_THAT(pdo_rule_violations(dcfgen), IsEmpty()) << bin;
    // Same stream up to order: dcfgen writes the sdo list in YAML order (..., 6083h, 6060h), we
    // write index order (6060h first) after the PDOs.
    EXPECT_EQ(ours.size(), dcfgen.size()) << bin;
    EXPECT_EQ(pdo_safe_order(dcfgen), ours) << bin;
  }
}

// ---------------------------------------------------------------------------------------------
// ros_canopen-motion_controller_driver: pilz.yaml + pilz.eds -> prbt_joint_1.bin

TEST(DcfgenVectors, PilzPrbtJoint1) {
  SKIP_WITHOUT_CORPUS();
  DeviceDescription dcf = load("ros_canopen-motion_controller_driver/pilz.eds");
  // prbt_joint_1: node_id: 3
  // tpdo: 1: {enabled: true, mapping: [{0x6041, 0}, {0x6061, 0}, {0x6064, 0}]}
  configure_pdo(dcf, false, 1, mapped({{0x6041, 0}, {0x6061, 0}, {0x6064, 0}}));
  //       2: {enabled: true, mapping: [{0x606b, 0}, {0x606c, 0}]}
  configure_pdo(dcf, false, 2, mapped({{0x606B, 0}, {0x606C, 0}}));
  // rpdo: 1: {enabled: true, mapping: [{0x6040, 0}, {0x60c1, 1}, {0x6042, 0}]}
  configure_pdo(dcf, true, 1, mapped({{0x6040, 0}, {0x60C1, 1}, {0x6042, 0}}));
  //       2: {enabled: true, mapping: [{0x607a, 0}, {0x6081, 0}]}
  configure_pdo(dcf, true, 2, mapped({{0x607A, 0}, {0x6081, 0}}));

  const auto ours = our_writes(dcf, 3);
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
  const DeviceDescription slave = load("odrive-cia402-profile/odrive-canopen-cia402.dcf");
  const SubObject* revision = slave.sub(0x1018, 3);
  const SubObject* serial = slave.sub(0x1018, 4);
  ASSERT_NE(revision, nullptr);
  ASSERT_NE(serial, nullptr);
  ASSERT_TRUE(revision->configured_value().has_value());
  ASSERT_TRUE(serial->configured_value().has_value());

  DeviceDescription master = load("odrive-cia402-profile/master.dcf");
  // motor_1..motor_4: node_id 2..5, dcf odrive-canopen-cia402.dcf.
  for (std::uint8_t node = 2; node <= 5; ++node) {
    set(master, 0x1F87, node, *revision->configured_value());
    set(master, 0x1F88, node, *serial->configured_value());
  }
  const auto ours = our_writes(master, 1);
  const auto dcfgen = load_bin("odrive-cia402-profile/master.bin");
  // Everything master.bin holds, ours holds with the same value. The rest of ours is master.dcf's
  // own ParameterValues (heartbeat consumers, slave assignments, remote PDO mappings, ...),
  // which dcfgen's master reads from master.dcf instead of from a concise stream.
  for (const auto& line : differences(ours, dcfgen)) {
    EXPECT_EQ(line.rfind("ours only: ", 0), 0u) << line;
  }
  const auto state = final_state(ours);
  for (const auto& w : dcfgen) {
    auto it = state.find({w.index, w.sub_index});
    ASSERT_NE(it, state.end()) << entry_text(w.index, w.sub_index, w.data);
    EXPECT_EQ(it->second, w.data) << entry_text(w.index, w.sub_index, w.data);
  }
  // No PDO rule check here: master.dcf gives its own RPDO mappings as CompactSubObj, whose
  // sub-index 0 is read-only, so the mapping cannot be deactivated by SDO at all (dcfgen's
  // master loads master.dcf into its own dictionary, where CiA 301's SDO rules do not apply).
}

}  // namespace
}  // namespace cfg
