// cfgmgr scan end to end on the simulated bus (sim:?device=FILE@NODES): a live network read into a
// project (OUT/nodelist.cpj, OUT/nodeN.dcf), issue 32 and `cfgmgr scan --help`. The devices are
// the sample network's DCFs (samples/network), whose ParameterValues are what a simulated device
// holds, and the vendor library is samples/ (drive.eds, io_module.eds). Every expected value is
// read from those files here (libcfg's reader, parse_value at the node-ID), and the entries a scan
// reads are entries_to_scan of the EDS (cfg/device_scan.hpp); decoy libraries are EDS files the
// tests write into their scratch directory.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <ostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/device_scan.hpp"
#include "cfg/hex.hpp"
#include "cfg/network.hpp"
#include "cfg/object_address.hpp"
#include "cfg/value.hpp"
#include "multicast_netns.hpp"
#include "tool_test_support.hpp"

namespace cfg {
// Values in failure messages: "1000 (0x000003E8)", not the object's bytes.
inline void PrintTo(const Value& value, std::ostream* os) {
  *os << describe_value(value);
}
}  // namespace cfg

namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::cfgmgr;
using tool_test::Json;
using tool_test::parse_json_file;
using tool_test::sample_network;
using tool_test::ScratchDir;

const std::string kSamples = CANOPEN_SAMPLES_DIR;
const std::string kDriveEds = kSamples + "/drive.eds";
const std::string kIoEds = kSamples + "/io_module.eds";
const std::string kDrive3 = sample_network("drive_node3.dcf");
const std::string kIo2 = sample_network("io_module_node2.dcf");
// An LSS device (LSS_Supported=1) of the tests' data, for a device without node-ID.
const std::string kLssIo = tool_test::data_path("lss/lss_io.eds");

std::string sim(const std::vector<std::string>& devices) {
  std::string url = "sim:";
  for (std::size_t i = 0; i < devices.size(); ++i)
    url += (i ? "&device=" : "?device=") + devices[i];
  return url;
}

cfg::DeviceDescription load(const std::string& path) {
  auto read = cfg::read_device_file(path);
  EXPECT_TRUE(read.ok()) << path << " does not read without errors";
  return read.device ? std::move(*read.device) : cfg::DeviceDescription{};
}

// The value an entry holds by the file (ParameterValue, else DefaultValue) at node `node`;
// nullopt when the file gives none or it is not of a basic type.
std::optional<cfg::Value> value_at(const cfg::DeviceDescription& d, cfg::ObjectAddress a,
                                   std::uint8_t node) {
  const cfg::SubObject* sub = d.sub(a.index, a.sub_index);
  if (sub == nullptr || !sub->configured_value() || !sub->basic_type()) return std::nullopt;
  auto v = cfg::parse_value(*sub->basic_type(), *sub->configured_value(), node);
  if (!v) return std::nullopt;
  return v.value();
}

std::uint32_t number_at(const cfg::DeviceDescription& d, std::uint16_t index, std::uint8_t sub) {
  const auto v = value_at(d, {index, sub}, 1);
  EXPECT_TRUE(v) << cfg::to_string(cfg::ObjectAddress{index, sub});
  return v ? static_cast<std::uint32_t>(v->as_unsigned()) : 0;
}

// The entries a scan reads whose value on the original device differs from the EDS's factory
// default: what a verify of the scanned project against a factory device must name.
std::set<std::uint32_t> differing_from_defaults(const cfg::DeviceDescription& original,
                                                const cfg::DeviceDescription& eds,
                                                std::uint8_t node) {
  std::set<std::uint32_t> out;
  for (const auto a : cfg::entries_to_scan(eds)) {
    const auto held = value_at(original, a, node);
    if (held && held != value_at(eds, a, node)) out.insert(a.key());
  }
  return out;
}

const Json* node_in(const Json& report, double node_id) {
  const Json* nodes = report.get("nodes");
  if (nodes == nullptr) return nullptr;
  for (const auto& n : nodes->array) {
    if (n.get("node_id") != nullptr && n.get("node_id")->number == node_id) return &n;
  }
  return nullptr;
}

// drive.eds as another file: its identity changed in [DeviceInfo] and in 1018h's DefaultValue
// (a library file matches by either).
void write_variant(const std::string& path, std::optional<std::uint32_t> product,
                   std::optional<std::uint32_t> revision) {
  cfg::DeviceDescription eds = load(kDriveEds);
  if (product) {
    eds.device_info.set("ProductNumber", cfg::hex(*product, 8));
    eds.sub(0x1018, 2)->default_value = cfg::hex(*product, 8);
  }
  if (revision) {
    eds.device_info.set("RevisionNumber", cfg::hex(*revision, 8));
    eds.sub(0x1018, 3)->default_value = cfg::hex(*revision, 8);
  }
  cfg::WriteOptions options;
  options.kind = cfg::FileKind::Eds;
  tool_test::write_file(path, cfg::write_device_description(eds, options));
}

// ------------------------------------------------------------------- the round trip ----------

// The scanned project configures every value the originals hold: verify against devices built
// from the original DCFs finds no difference (exit 0); against factory devices (the EDSs) it
// names exactly the entries whose original value differs from the EDS default (exit 4).
TEST(Scan, TheScannedProjectVerifiesAgainstTheOriginalsAndNamesWhatFactoryDevicesLack) {
  ScratchDir dir;
  const std::string bus = sim({kDrive3 + "@3", kIo2 + "@2"});
  const auto scan = cfgmgr(dir, {"scan", "--bus", bus, "--eds-dir", kSamples, "-o", dir / "out"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err << scan.out;

  const auto same = cfgmgr(dir, {"verify", dir / "out/nodelist.cpj", "--bus", bus});
  EXPECT_EQ(same.exit_code, 0) << same.out << same.err;

  const auto factory =
      cfgmgr(dir, {"verify", dir / "out/nodelist.cpj", "--bus",
                   sim({kDriveEds + "@3", kIoEds + "@2"}), "--json", dir / "factory.json"});
  EXPECT_EQ(factory.exit_code, 4) << factory.out << factory.err;
  const auto json = parse_json_file(dir / "factory.json");
  ASSERT_TRUE(json);
  std::map<int, std::set<std::uint32_t>> named;
  for (const auto& d : json->get("differences")->array) {
    named[static_cast<int>(d.get("node_id")->number)].insert(
        cfg::ObjectAddress{static_cast<std::uint16_t>(d.get("index")->number),
                           static_cast<std::uint8_t>(d.get("sub_index")->number)}
            .key());
  }
  const auto drive = differing_from_defaults(load(kDrive3), load(kDriveEds), 3);
  const auto io = differing_from_defaults(load(kIo2), load(kIoEds), 2);
  ASSERT_FALSE(drive.empty());
  ASSERT_FALSE(io.empty());
  EXPECT_EQ(named[3], drive);
  EXPECT_EQ(named[2], io);
  EXPECT_EQ(named.size(), 2U);
}

// The device swap in two commands (issue 32): the scanned project pushed onto replacements at
// factory defaults (the EDSs; sim:?state=DIR keeps what they saved) leaves them as the originals
// were: verify finds no difference, and a scan of the replacements reads, entry by entry, the
// values the originals' DCFs hold.
TEST(Scan, APushOntoFactoryDevicesMakesThemHoldWhatTheOriginalsHeld) {
  ScratchDir dir;
  const auto scan = cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3", kIo2 + "@2"}), "--eds-dir",
                                 kSamples, "-o", dir / "before"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  const std::string replacements =
      sim({kDriveEds + "@3", kIoEds + "@2"}) + "&state=" + dir / "state";
  const auto push = cfgmgr(dir, {"push", dir / "before/nodelist.cpj", "--bus", replacements});
  ASSERT_EQ(push.exit_code, 0) << push.out << push.err;
  const auto verify = cfgmgr(dir, {"verify", dir / "before/nodelist.cpj", "--bus", replacements});
  EXPECT_EQ(verify.exit_code, 0) << verify.out << verify.err;

  const auto rescan =
      cfgmgr(dir, {"scan", "--bus", replacements, "--eds-dir", kSamples, "-o", dir / "after"});
  ASSERT_EQ(rescan.exit_code, 0) << rescan.err;
  struct Case {
    std::string file;
    std::string eds;
    std::uint8_t node;
  };
  for (const Case& c : {Case{kDrive3, kDriveEds, 3}, Case{kIo2, kIoEds, 2}}) {
    SCOPED_TRACE(c.file);
    const auto original = load(c.file);
    const auto after = load(dir / ("after/node" + std::to_string(c.node) + ".dcf"));
    std::size_t compared = 0;
    for (const auto a : cfg::entries_to_scan(load(c.eds))) {
      const auto held = value_at(original, a, c.node);
      if (!held) continue;  // the file gives no value
      EXPECT_EQ(value_at(after, a, c.node), held) << cfg::to_string(a);
      ++compared;
    }
    EXPECT_GT(compared, 10U);
  }
}

// ------------------------------------------------------------------- the as-found DCF --------

// Entry by entry, nodeN.dcf holds what the device holds: each entry the scan reads has the
// original's value (decoded at node N); a COB-ID whose default follows the node-ID ($NODEID) and
// equals it is left at $NODEID, one that differs is recorded; NodeID=N; the serial number
// (1018h sub 4) is not recorded, though the device has one (LSS_SerialNumber) and --json says it.
TEST(Scan, TheAsFoundDcfHoldsTheOriginalsValuesEntryByEntry) {
  struct Case {
    std::string file;
    std::string eds;
    std::uint8_t node;
  };
  for (const Case& c : {Case{kDrive3, kDriveEds, 3}, Case{kIo2, kIoEds, 2}}) {
    SCOPED_TRACE(c.file);
    ScratchDir dir;
    cfg::DeviceDescription original = load(c.file);
    ASSERT_TRUE(original.commissioning);
    constexpr std::uint32_t kSerial = 0x00C0FFEE;
    original.commissioning->lss_serial_number = kSerial;
    tool_test::write_file(dir / "device.dcf", cfg::write_device_description(original, {}));

    const std::string n = std::to_string(c.node);
    const auto scan = cfgmgr(dir, {"scan", "--bus", sim({dir / "device.dcf@" + n}), "--eds-dir",
                                   kSamples, "-o", dir / "out", "--json", dir / "scan.json"});
    ASSERT_EQ(scan.exit_code, 0) << scan.err;
    const auto json = parse_json_file(dir / "scan.json");
    ASSERT_TRUE(json);
    const Json* node = node_in(*json, c.node);
    ASSERT_NE(node, nullptr);
    EXPECT_EQ(node->get("identity")->get("serial_number")->number, kSerial);

    const auto scanned = load(dir / ("out/node" + n + ".dcf"));
    EXPECT_EQ(scanned.node_id().value_or(0), c.node);
    const auto eds = load(c.eds);
    std::size_t compared = 0;
    std::size_t at_node_id = 0;
    for (const auto a : cfg::entries_to_scan(eds)) {
      SCOPED_TRACE(cfg::to_string(a));
      const cfg::SubObject* sub = scanned.sub(a.index, a.sub_index);
      ASSERT_NE(sub, nullptr);
      const auto held = value_at(original, a, c.node);
      const cfg::SubObject* eds_sub = eds.sub(a.index, a.sub_index);
      const bool follows_node_id =
          eds_sub->default_value && cfg::mentions_node_id(*eds_sub->default_value);
      if (follows_node_id && held == value_at(eds, a, c.node)) {
        EXPECT_FALSE(sub->parameter_value) << *sub->parameter_value;
        ASSERT_TRUE(sub->default_value);
        EXPECT_TRUE(cfg::mentions_node_id(*sub->default_value)) << *sub->default_value;
        ++at_node_id;
        continue;
      }
      ASSERT_TRUE(sub->parameter_value);
      if (!held) continue;  // the file gives no value: whatever the device holds
      EXPECT_EQ(value_at(scanned, a, c.node), held) << *sub->parameter_value;
      ++compared;
    }
    EXPECT_GT(compared, 10U);
    EXPECT_GE(at_node_id, 4U);  // 1200h sub 1/2, an RPDO and a TPDO COB-ID at least

    const cfg::SubObject* serial = scanned.sub(0x1018, 4);
    EXPECT_TRUE(serial == nullptr || !serial->parameter_value);
    EXPECT_THAT(tool_test::slurp(dir / ("out/node" + n + ".dcf")), Not(HasSubstr("C0FFEE")));
    // The identity the master checks on a replacement: 1000h and 1018h sub 1-3 as found.
    for (const auto a : {cfg::ObjectAddress{0x1000, 0}, cfg::ObjectAddress{0x1018, 1},
                         cfg::ObjectAddress{0x1018, 2}, cfg::ObjectAddress{0x1018, 3}}) {
      EXPECT_EQ(value_at(scanned, a, c.node), value_at(original, a, c.node)) << cfg::to_string(a);
    }
  }
}

// The same file simulated at node 12: node12.dcf, NodeID=12, and the SDO and PDO COB-IDs that
// follow from the node-ID are those of node 12 (the file's are of node 3).
TEST(Scan, AtAnotherNodeIdTheCobIdsFollowThatNode) {
  ScratchDir dir;
  const std::string bus = sim({kDrive3 + "@12"});
  const auto scan = cfgmgr(dir, {"scan", "--bus", bus, "--eds-dir", kSamples, "-o", dir / "out"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  ASSERT_TRUE(std::filesystem::exists(dir / "out/node12.dcf"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out/node3.dcf"));
  const auto scanned = load(dir / "out/node12.dcf");
  EXPECT_EQ(scanned.node_id().value_or(0), 12);
  const auto eds = load(kDriveEds);
  for (const auto a :
       {cfg::ObjectAddress{0x1014, 0}, cfg::ObjectAddress{0x1200, 1}, cfg::ObjectAddress{0x1200, 2},
        cfg::ObjectAddress{0x1400, 1}, cfg::ObjectAddress{0x1401, 1}, cfg::ObjectAddress{0x1800, 1},
        cfg::ObjectAddress{0x1801, 1}}) {
    SCOPED_TRACE(cfg::to_string(a));
    const auto cob = value_at(scanned, a, 12);
    ASSERT_TRUE(cob);
    EXPECT_EQ(cob, value_at(eds, a, 12));
    EXPECT_EQ(cob->as_unsigned() & 0x7F, 12U);
  }
  auto project = cfg::load_network(dir / "out/nodelist.cpj");
  ASSERT_TRUE(project.ok());
  ASSERT_EQ(project.network->nodes.size(), 1U);
  EXPECT_EQ(project.network->nodes[0].node_id.value(), 12);
  const auto verify = cfgmgr(dir, {"verify", dir / "out/nodelist.cpj", "--bus", bus});
  EXPECT_EQ(verify.exit_code, 0) << verify.out << verify.err;
}

// ------------------------------------------------------------------- --json ------------------

TEST(Scan, JsonGivesEachDeviceItsIdentityEdsAndCounts) {
  ScratchDir dir;
  const auto scan = cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3", kIo2 + "@2"}), "--eds-dir",
                                 kSamples, "-o", dir / "out", "--json", dir / "scan.json"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  EXPECT_EQ(json->get("asked")->number, 127);
  EXPECT_EQ(json->get("absent")->number, 127 - 2);
  ASSERT_EQ(json->get("nodes")->array.size(), 2U);
  EXPECT_TRUE(json->get("unconfigured")->array.empty());
  struct Case {
    std::string file;
    std::string eds;
    int node;
  };
  for (const Case& c : {Case{kIo2, kIoEds, 2}, Case{kDrive3, kDriveEds, 3}}) {
    SCOPED_TRACE(c.file);
    const Json* node = node_in(*json, c.node);
    ASSERT_NE(node, nullptr);
    const auto original = load(c.file);
    const Json& identity = *node->get("identity");
    EXPECT_EQ(identity.get("device_type")->number, number_at(original, 0x1000, 0));
    EXPECT_EQ(identity.get("vendor_id")->number, number_at(original, 0x1018, 1));
    EXPECT_EQ(identity.get("product_code")->number, number_at(original, 0x1018, 2));
    EXPECT_EQ(identity.get("revision")->number, number_at(original, 0x1018, 3));
    ASSERT_TRUE(node->get("eds")->is(Json::Kind::String));
    EXPECT_TRUE(std::filesystem::equivalent(node->get("eds")->string, c.eds))
        << node->get("eds")->string;
    EXPECT_TRUE(node->get("revision_exact")->boolean);
    EXPECT_EQ(node->get("dcf")->string, "node" + std::to_string(c.node) + ".dcf");
    EXPECT_EQ(node->get("entries_read")->number,
              static_cast<double>(cfg::entries_to_scan(load(c.eds)).size()));
    EXPECT_EQ(node->get("entries_skipped")->number, 0);
    EXPECT_GT(node->get("seconds")->number, 0);
  }
}

// --node 3: only node 3 is asked, though another device is on the bus.
TEST(Scan, NodeReadsOnlyThatNode) {
  ScratchDir dir;
  const auto scan =
      cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3", kIo2 + "@2"}), "--eds-dir", kSamples,
                   "--node", "3", "-o", dir / "out", "--json", dir / "scan.json"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  EXPECT_EQ(json->get("asked")->number, 1);
  EXPECT_EQ(json->get("absent")->number, 0);
  ASSERT_EQ(json->get("nodes")->array.size(), 1U);
  EXPECT_NE(node_in(*json, 3), nullptr);
  EXPECT_TRUE(std::filesystem::exists(dir / "out/node3.dcf"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out/node2.dcf"));
  auto project = cfg::load_network(dir / "out/nodelist.cpj");
  ASSERT_TRUE(project.ok());
  ASSERT_EQ(project.network->nodes.size(), 1U);
  EXPECT_EQ(project.network->nodes[0].node_id.value(), 3);
}

// A device without node-ID (LSS_Supported=1, unconfigured=5) is listed by its LSS address
// (1018h sub 1-4 of its file) under "unconfigured", not as a node.
TEST(Scan, ADeviceWithoutNodeIdIsListedByItsLssAddress) {
  ScratchDir dir;
  const auto lss = load(kLssIo);
  ASSERT_EQ(lss.device_info.find("LSS_Supported") != nullptr
                ? *lss.device_info.find("LSS_Supported")
                : "",
            "1");
  const auto scan =
      cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3", kLssIo + "@5"}) + "&unconfigured=5",
                   "--eds-dir", kSamples, "-o", dir / "out", "--json", dir / "scan.json"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  ASSERT_EQ(json->get("nodes")->array.size(), 1U);
  EXPECT_EQ(node_in(*json, 5), nullptr);
  const auto& unconfigured = json->get("unconfigured")->array;
  ASSERT_EQ(unconfigured.size(), 1U);
  EXPECT_EQ(unconfigured[0].get("vendor_id")->number, number_at(lss, 0x1018, 1));
  EXPECT_EQ(unconfigured[0].get("product_code")->number, number_at(lss, 0x1018, 2));
  EXPECT_EQ(unconfigured[0].get("revision")->number, number_at(lss, 0x1018, 3));
  EXPECT_EQ(unconfigured[0].get("serial")->number, number_at(lss, 0x1018, 4));
  EXPECT_THAT(scan.err, HasSubstr("without node-ID"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out/node5.dcf"));
}

// ------------------------------------------------------------------- a lossy bus -------------

// Frames lost now and then (sim:?loss=0.01): the uploads that time out are repeated, every entry
// is read, and the project verifies against the original devices.
TEST(ScanLossy, AFewLostFramesCostRetriesNotEntries) {
  for (const char* seed : {"1", "2", "3"}) {
    SCOPED_TRACE(seed);
    ScratchDir dir;
    const auto scan = cfgmgr(
        dir, {"scan", "--bus", sim({kDrive3 + "@3", kIo2 + "@2"}) + "&loss=0.01&seed=" + seed,
              "--eds-dir", kSamples, "-o", dir / "out", "--json", dir / "scan.json"});
    ASSERT_EQ(scan.exit_code, 0) << scan.err;
    const auto json = parse_json_file(dir / "scan.json");
    ASSERT_TRUE(json);
    ASSERT_NE(node_in(*json, 2), nullptr);
    ASSERT_NE(node_in(*json, 3), nullptr);
    EXPECT_EQ(node_in(*json, 2)->get("entries_read")->number,
              static_cast<double>(cfg::entries_to_scan(load(kIoEds)).size()));
    EXPECT_EQ(node_in(*json, 3)->get("entries_read")->number,
              static_cast<double>(cfg::entries_to_scan(load(kDriveEds)).size()));
    const auto verify = cfgmgr(
        dir, {"verify", dir / "out/nodelist.cpj", "--bus", sim({kDrive3 + "@3", kIo2 + "@2"})});
    EXPECT_EQ(verify.exit_code, 0) << verify.out << verify.err;
  }
}

// However many frames are lost, each node-ID asked is either found or absent, once: absent is
// asked minus the devices listed (--json: "absent" = 127 - devices for a full scan).
TEST(ScanLossy, EachNodeIdAskedIsFoundOrAbsentOnce) {
  for (int seed = 1; seed <= 12; ++seed) {
    SCOPED_TRACE("loss=0.2&seed=" + std::to_string(seed));
    ScratchDir dir;
    const auto scan = cfgmgr(
        dir, {"scan", "--bus",
              sim({kDrive3 + "@3", kIoEds + "@2"}) + "&loss=0.2&seed=" + std::to_string(seed),
              "--eds-dir", kSamples, "--no-lss", "-o", dir / "out", "--json", dir / "scan.json"});
    ASSERT_TRUE(scan.exit_code == 0 || scan.exit_code == 4) << scan.err;
    const auto json = parse_json_file(dir / "scan.json");
    ASSERT_TRUE(json);
    EXPECT_EQ(json->get("asked")->number, 127);
    EXPECT_EQ(json->get("absent")->number + static_cast<double>(json->get("nodes")->array.size()),
              127)
        << "absent " << json->get("absent")->number << ", devices "
        << json->get("nodes")->array.size();
  }
}

// ------------------------------------------------------------------- decoys ------------------

// The library has the vendor's other product only: no match, exit 4, a line naming the EDS that
// is missing and the vendor's other products; the node is in the project by its identity only,
// and a push of the project writes nothing to it.
TEST(ScanDecoy, SameVendorOtherProductIsNoMatch) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "lib");
  write_variant(dir / "lib/other.eds", 0x00000403, std::nullopt);
  const auto original = load(kDrive3);
  const auto scan = cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3"}), "--eds-dir", dir / "lib",
                                 "-o", dir / "out", "--json", dir / "scan.json"});
  EXPECT_EQ(scan.exit_code, 4) << scan.err;
  EXPECT_THAT(scan.err, HasSubstr("no EDS for vendor-ID 0x7E57C0DE, product code 0x00000402"));
  EXPECT_THAT(scan.err, HasSubstr("other products"));
  EXPECT_THAT(scan.err, HasSubstr("other.eds"));
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  const Json* node = node_in(*json, 3);
  ASSERT_NE(node, nullptr);
  EXPECT_TRUE(node->get("eds")->is(Json::Kind::Null));
  EXPECT_THAT(node->get("note")->string, HasSubstr("other products"));

  const auto dcf = load(dir / "out/node3.dcf");
  EXPECT_EQ(dcf.node_id().value_or(0), 3);
  std::set<std::uint16_t> indices;
  for (const auto& [index, object] : dcf.objects) indices.insert(index);
  EXPECT_EQ(indices, (std::set<std::uint16_t>{0x1000, 0x1001, 0x1018}));
  for (const auto a : {cfg::ObjectAddress{0x1000, 0}, cfg::ObjectAddress{0x1018, 1},
                       cfg::ObjectAddress{0x1018, 2}, cfg::ObjectAddress{0x1018, 3}}) {
    EXPECT_EQ(value_at(dcf, a, 3), value_at(original, a, 3)) << cfg::to_string(a);
  }
  auto project = cfg::load_network(dir / "out/nodelist.cpj");
  ASSERT_TRUE(project.ok());
  ASSERT_EQ(project.network->nodes.size(), 1U);

  const auto push = cfgmgr(dir, {"push", dir / "out/nodelist.cpj", "--bus", sim({kDriveEds + "@3"}),
                                 "--json", dir / "push.json"});
  EXPECT_EQ(push.exit_code, 0) << push.err;
  const auto pushed = parse_json_file(dir / "push.json");
  ASSERT_TRUE(pushed);
  const Json* pushed_node = node_in(*pushed, 3);
  ASSERT_NE(pushed_node, nullptr);
  EXPECT_EQ(pushed_node->get("entries")->number, 0);
}

// The product with a revision the library lacks: the nearest is taken (same major, lower minor),
// the note says so, revision_exact is false, exit 0; the DCF records the revision the device
// reported (device_scan.hpp as_found_dcf: 1018h sub 1-3 as read), not the EDS's.
TEST(ScanDecoy, SameProductOtherRevisionTakesTheNearestAndSaysSo) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "lib");
  const auto original = load(kDrive3);
  const std::uint32_t revision = number_at(original, 0x1018, 3);
  ASSERT_GT(revision & 0xFFFF, 1U);
  const std::uint32_t older = (revision & 0xFFFF0000) | 1;
  write_variant(dir / "lib/older.eds", std::nullopt, older);
  const auto scan = cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3"}), "--eds-dir", dir / "lib",
                                 "-o", dir / "out", "--json", dir / "scan.json"});
  EXPECT_EQ(scan.exit_code, 0) << scan.err;
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  const Json* node = node_in(*json, 3);
  ASSERT_NE(node, nullptr);
  EXPECT_FALSE(node->get("revision_exact")->boolean);
  ASSERT_TRUE(node->get("eds")->is(Json::Kind::String));
  EXPECT_TRUE(std::filesystem::equivalent(node->get("eds")->string, dir / "lib/older.eds"));
  EXPECT_THAT(node->get("note")->string, HasSubstr(cfg::hex(revision, 8)));
  EXPECT_THAT(node->get("note")->string, HasSubstr(cfg::hex(older, 8)));
  EXPECT_THAT(node->get("note")->string, HasSubstr("nearest"));
  EXPECT_THAT(scan.err, HasSubstr("nearest"));
  EXPECT_EQ(node->get("identity")->get("revision")->number, revision);

  const auto dcf = load(dir / "out/node3.dcf");
  EXPECT_EQ(value_at(dcf, {0x1018, 3}, 3), value_at(original, {0x1018, 3}, 3))
      << "1018h sub 3 of the as-found DCF: " << *dcf.sub(0x1018, 3)->configured_value();

  // So a replacement with a lower minor revision than the scanned device (which may lack what
  // that one was configured with) is refused by the push (status N, CiA 302-2 §6.9), as it is
  // with a project whose EDS matched exactly.
  const std::uint32_t lower = revision - 1;
  ASSERT_GT(lower, older);
  write_variant(dir / "replacement.eds", std::nullopt, lower);
  const auto push =
      cfgmgr(dir, {"push", dir / "out/nodelist.cpj", "--bus", sim({dir / "replacement.eds@3"})});
  EXPECT_EQ(push.exit_code, 4) << push.out << push.err;
  EXPECT_THAT(push.out, HasSubstr("error N")) << push.err;
}

// No EDS at all (an empty library, or none given): every device is in the project by its
// identity, the line says the library has no file of the vendor, exit 4.
TEST(ScanDecoy, NoEdsAtAllKeepsTheIdentityAndExits4) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "empty");
  for (const std::vector<std::string>& library :
       {std::vector<std::string>{"--eds-dir", dir / "empty"}, std::vector<std::string>{}}) {
    std::vector<std::string> args{"scan", "--bus", sim({kDrive3 + "@3"}), "-o", dir / "out"};
    args.insert(args.end(), library.begin(), library.end());
    const auto scan = cfgmgr(dir, args);
    EXPECT_EQ(scan.exit_code, 4) << scan.err;
    EXPECT_THAT(scan.err, HasSubstr("no EDS for vendor-ID 0x7E57C0DE, product code 0x00000402"));
    EXPECT_THAT(scan.err, HasSubstr("no file of vendor-ID 0x7E57C0DE"));
    const auto dcf = load(dir / "out/node3.dcf");
    EXPECT_EQ(dcf.node_id().value_or(0), 3);
    EXPECT_EQ(dcf.objects.size(), 3U);  // 1000h, 1001h, 1018h
  }
}

// A device that refuses a read the EDS allows (6083h write-only on the device: abort 0601 0001):
// the entry is skipped and counted, never fatal; the DCF records no value for it.
TEST(ScanDecoy, AnEntryTheDeviceRefusesIsSkippedAndCounted) {
  ScratchDir dir;
  cfg::DeviceDescription device = load(kDrive3);
  ASSERT_NE(device.sub(0x6083, 0), nullptr);
  device.sub(0x6083, 0)->access = cfg::AccessType::Wo;
  tool_test::write_file(dir / "device.dcf", cfg::write_device_description(device, {}));
  const auto scan = cfgmgr(dir, {"scan", "--bus", sim({dir / "device.dcf@3"}), "--eds-dir",
                                 kSamples, "-o", dir / "out", "--json", dir / "scan.json"});
  EXPECT_EQ(scan.exit_code, 0) << scan.err;
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  const Json* node = node_in(*json, 3);
  ASSERT_NE(node, nullptr);
  EXPECT_EQ(node->get("entries_skipped")->number, 1);
  EXPECT_EQ(node->get("entries_read")->number,
            static_cast<double>(cfg::entries_to_scan(load(kDriveEds)).size() - 1));
  const auto dcf = load(dir / "out/node3.dcf");
  ASSERT_NE(dcf.sub(0x6083, 0), nullptr);
  EXPECT_FALSE(dcf.sub(0x6083, 0)->parameter_value);
  EXPECT_TRUE(dcf.sub(0x6084, 0)->parameter_value);  // the next one is read
}

// A broken file in the library (a ParameterValue that is no UNSIGNED32, an error in either read
// mode, line 9) is named with its file:line and skipped; the scan goes on and, the device's EDS
// being there, exits 0.
TEST(ScanDecoy, ABrokenEdsInTheLibraryIsNamedAndSkipped) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "lib/vendor");
  std::filesystem::copy_file(kDriveEds, dir / "lib/vendor/drive.eds");
  tool_test::write_file(dir / "lib/broken.eds",
                        std::string("[FileInfo]\r\nFileName=broken.eds\r\n\r\n[1000]\r\n"
                                    "ParameterName=Device type\r\nObjectType=0x7\r\n"
                                    "DataType=0x0007\r\nAccessType=ro\r\n"
                                    "ParameterValue=not a number\r\n"));
  const auto scan = cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3"}), "--eds-dir", dir / "lib",
                                 "-o", dir / "out", "--json", dir / "scan.json"});
  EXPECT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_THAT(scan.err, HasSubstr("broken.eds:9:"));
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  const Json* node = node_in(*json, 3);
  ASSERT_NE(node, nullptr);
  ASSERT_TRUE(node->get("eds")->is(Json::Kind::String));
  EXPECT_TRUE(std::filesystem::equivalent(node->get("eds")->string, dir / "lib/vendor/drive.eds"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out/node3.dcf"));
}

// ------------------------------------------------------------------- the output directory ----

// An existing project directory: the project's files are replaced whole, a file of someone else
// stays as it was.
TEST(ScanOutput, AnExistingDirectoryGetsNewProjectFilesAndKeepsForeignOnes) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "out");
  const std::string old_project =
      "[Topology]\r\nNetName=old\r\nNodes=0x01\r\nNode9Present=0x01\r\n"
      "Node9DCFName=node9.dcf\r\n";
  tool_test::write_file(dir / "out/nodelist.cpj", old_project);
  tool_test::write_file(dir / "out/node3.dcf", std::string("old and short\r\n"));
  tool_test::write_file(dir / "out/notes.txt", std::string("mine\n"));
  const auto scan = cfgmgr(
      dir, {"scan", "--bus", sim({kDrive3 + "@3"}), "--eds-dir", kSamples, "-o", dir / "out"});
  ASSERT_EQ(scan.exit_code, 0) << scan.err;
  EXPECT_EQ(tool_test::slurp(dir / "out/notes.txt"), "mine\n");
  EXPECT_NE(tool_test::slurp(dir / "out/nodelist.cpj"), old_project);
  auto project = cfg::load_network(dir / "out/nodelist.cpj");
  ASSERT_TRUE(project.ok());
  ASSERT_EQ(project.network->nodes.size(), 1U);
  EXPECT_EQ(project.network->nodes[0].node_id.value(), 3);
  EXPECT_EQ(load(dir / "out/node3.dcf").node_id().value_or(0), 3);
}

TEST(ScanOutput, OutputNamingAFileIsAUsageError) {
  ScratchDir dir;
  tool_test::write_file(dir / "file", std::string("x"));
  const auto scan = cfgmgr(
      dir, {"scan", "--bus", sim({kDrive3 + "@3"}), "--eds-dir", kSamples, "-o", dir / "file"});
  EXPECT_EQ(scan.exit_code, 2) << scan.err;
  EXPECT_EQ(tool_test::slurp(dir / "file"), "x");
}

// Nobody answers an SDO (the only device has no node-ID; or --node names an absent one): exit 4,
// and no directory is made.
TEST(ScanOutput, NoDeviceOnTheBusExits4AndWritesNothing) {
  ScratchDir dir;
  const auto lonely = cfgmgr(dir, {"scan", "--bus", sim({kLssIo + "@5"}) + "&unconfigured=5",
                                   "--eds-dir", kSamples, "-o", dir / "out"});
  EXPECT_EQ(lonely.exit_code, 4) << lonely.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
  const auto absent = cfgmgr(dir, {"scan", "--bus", sim({kDrive3 + "@3"}), "--eds-dir", kSamples,
                                   "--node", "9", "-o", dir / "out2"});
  EXPECT_EQ(absent.exit_code, 4) << absent.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out2"));
}

// ------------------------------------------------------------------- only reads --------------

// The scan only reads (issue 32): over UDP against `cfgmgr simulate`, whose candump log has every
// frame on the bus, the scan sends no NMT command (000h), no SYNC or TIME, SDO requests (600h +
// node) that are uploads only (CiA 301 §7.2.4.3: ccs 2 initiate upload, 3 upload segment, 4
// abort, 5 block upload; never 0/1 download, 6 block download) and LSS requests (7E5h) that are
// Fastscan (CiA 305 cs 51h, after a switch state global to waiting) only, never a switch to
// configuration, a configure or a store. Run in a private
// network namespace (Scan.OnlyReadsOverUdp re-runs this executable there).
TEST(Scan, OnlyReadsOverUdp) {
  tool_test::run_in_private_netns("ScanInNetns.*");
}

TEST(ScanInNetns, TheScanSendsNoWriteAndNoNmtCommand) {
  REQUIRE_ISOLATED_MULTICAST();
  ScratchDir dir;
  const std::string url = test_support::udp_test_url("43241");
  {
    tool_test::SimulatedDevices devices(dir.path(), url, {"--candump", dir / "run.log"});
    devices.simulate({kDrive3 + "@3"});
    const auto scan = cfgmgr(dir, {"scan", "--bus", url, "--eds-dir", kSamples, "-o", dir / "out",
                                   "--json", dir / "scan.json"});
    ASSERT_EQ(scan.exit_code, 0) << scan.err << devices.output();
    ASSERT_EQ(devices.stop(), 0);
  }
  const auto json = parse_json_file(dir / "scan.json");
  ASSERT_TRUE(json);
  ASSERT_NE(node_in(*json, 3), nullptr);
  EXPECT_EQ(node_in(*json, 3)->get("entries_read")->number,
            static_cast<double>(cfg::entries_to_scan(load(kDriveEds)).size()));

  std::istringstream log(tool_test::slurp(dir / "run.log"));
  std::size_t uploads = 0;
  for (std::string line; std::getline(log, line);) {
    SCOPED_TRACE(line);
    const auto hash = line.find('#');
    const auto space = line.rfind(' ', hash);
    ASSERT_TRUE(hash != std::string::npos && space != std::string::npos);
    const auto id = std::stoul(line.substr(space + 1, hash - space - 1), nullptr, 16);
    const std::string data = line.substr(hash + 1);
    const auto first = data.size() >= 2 ? std::stoul(data.substr(0, 2), nullptr, 16) : 0x100UL;
    EXPECT_NE(id, 0x000UL) << "an NMT command";
    EXPECT_NE(id, 0x080UL) << "SYNC";
    EXPECT_NE(id, 0x100UL) << "TIME";
    if (id > 0x600 && id <= 0x67F) {
      const auto ccs = first >> 5;
      EXPECT_TRUE(ccs == 2 || ccs == 3 || ccs == 4 || ccs == 5) << "an SDO request that writes";
      uploads += ccs == 2 ? 1 : 0;
    }
    // Switch state global to waiting (04h 00h) may precede Fastscan: it ends any configuration
    // state and changes nothing a device holds (CiA 305 cs 04h, mode 0).
    if (id == 0x7E5) {
      EXPECT_TRUE(first == 0x51 || data.substr(0, 4) == "0400")
          << "an LSS request other than Fastscan";
    }
  }
  EXPECT_GE(uploads, 127U);  // 1000h of every node-ID at least
}

// Bad command lines are exit 2 and say which option is wrong; an --eds-dir that is no directory is
// exit 3 (--help: "3  I/O error"). Nothing is written in either case.
TEST(ScanOutput, BadArgumentsExit2AndAMissingLibraryExit3) {
  ScratchDir dir;
  const std::string bus = sim({kDrive3 + "@3"});
  const auto node0 = cfgmgr(dir, {"scan", "--bus", bus, "--node", "0", "-o", dir / "out"});
  EXPECT_EQ(node0.exit_code, 2);
  EXPECT_THAT(node0.err, HasSubstr("--node")) << "names the option the user gave";
  const auto no_devices = cfgmgr(dir, {"scan", "--bus", "sim:", "-o", dir / "out"});
  EXPECT_EQ(no_devices.exit_code, 2);
  EXPECT_THAT(no_devices.err, HasSubstr("device=FILE@NODES"));
  EXPECT_EQ(cfgmgr(dir, {"scan", "--bus", bus}).exit_code, 2);  // -o is required
  const auto file_library =
      cfgmgr(dir, {"scan", "--bus", bus, "--eds-dir", kDriveEds, "-o", dir / "out"});
  EXPECT_EQ(file_library.exit_code, 3);
  EXPECT_THAT(file_library.err, HasSubstr("--eds-dir"));
  EXPECT_EQ(
      cfgmgr(dir, {"scan", "--bus", bus, "--eds-dir", dir / "absent", "-o", dir / "out"}).exit_code,
      3);
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

// ------------------------------------------------------------------- --help ------------------

TEST(Scan, HelpHasExamplesAndExitCodes) {
  ScratchDir dir;
  const auto help = cfgmgr(dir, {"scan", "--help"});
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_THAT(help.out, HasSubstr("Examples:"));
  EXPECT_THAT(help.out, HasSubstr("cfgmgr scan --bus"));
  EXPECT_THAT(help.out, HasSubstr("Exit codes:"));
  for (const char* code : {"  0  ", "  2  ", "  3  ", "  4  "}) {
    EXPECT_THAT(help.out, HasSubstr(code));
  }
}

}  // namespace
