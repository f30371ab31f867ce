// What a network scan makes of what it read (cfg/device_scan.hpp): the EDS library and its
// matching on 1018h, the entries a scan uploads, the as-found DCF and the project, read back with
// the same reader and load_network a push uses. Two tiers: tests/data files (always), and vendor
// files of the corpus (skipped when it is absent).
#include "cfg/device_scan.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/network.hpp"
#include "cfg/value.hpp"
#include "prerequisite.hpp"
#include "scratch_dir.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

namespace fs = std::filesystem;
using test_support::ScratchDir;
using ::testing::Contains;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;
using Values = std::map<ObjectAddress, std::vector<std::uint8_t>>;

std::string corpus(const std::string& relative) {
  return std::string(CANOPEN_CORPUS_DIR) + "/" + relative;
}

#define SKIP_WITHOUT_CORPUS()                                       \
  if (!std::filesystem::exists(corpus("MANIFEST.tsv"))) {           \
    PREREQUISITE_MISSING("corpus not found: ", CANOPEN_CORPUS_DIR); \
  }

std::string data(const std::string& relative) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/" + relative;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_text(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

void copy_into(const std::string& from, const std::string& to) {
  write_text(to, read_text(from));
}

DeviceDescription load(const std::string& path) {
  auto read = read_device_file(path);
  EXPECT_TRUE(read.ok()) << read.diagnostics.format();
  return read.device ? *read.device : DeviceDescription{};
}

DeviceIdentity identity(std::uint32_t vendor, std::uint32_t product,
                        std::optional<std::uint32_t> revision) {
  DeviceIdentity id;
  id.vendor_id = vendor;
  id.product_code = product;
  id.revision_number = revision;
  return id;
}

bool has_warning_at(const Diagnostics& diagnostics, const std::string& file, int line,
                    const std::string& text) {
  return std::any_of(diagnostics.items().begin(), diagnostics.items().end(), [&](const auto& d) {
    return d.severity == Severity::Warning && d.file == file && d.line == line &&
           d.message.find(text) != std::string::npos;
  });
}

int line_of(const std::string& text, const std::string& what) {
  const auto at = text.find(what);
  return at == std::string::npos
             ? 0
             : 1 + static_cast<int>(
                       std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

std::vector<std::uint8_t> u8(std::uint8_t v) {
  return {v};
}
std::vector<std::uint8_t> u16(std::uint16_t v) {
  return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8)};
}
std::vector<std::uint8_t> u32(std::uint32_t v) {
  return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
          static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
}

// --- the library over tests/data files ---------------------------------------------------------

// A vendor directory as users have them: nested folders, upper-case extensions, a DCF, notes, a
// broken file. Identities from the files' [DeviceInfo] (and equal 1018h defaults):
//   sim_device.eds     7E57C0DEh / 508h / 00020001h
//   no_device_type.eds 7E57C0DEh / 509h / 00010000h
//   spec_slave.eds     0000ABCDh / 42h  / 00010002h
//   master/slave.eds   0000ABCDh / 42h  / 00020003h
class DeviceScanLibrary : public ::testing::Test {
 protected:
  void SetUp() override {
    copy_into(data("sim_device.eds"), dir / "io/sim_device.eds");
    copy_into(data("no_device_type.eds"), dir / "io/deep/NO_TYPE.EDS");
    copy_into(data("spec_slave.eds"), dir / "abcd/spec_slave.Eds");
    copy_into(data("master/slave.eds"), dir / "abcd/slave_rev2.eds");
    // Not an EDS by name: never read, whatever they contain.
    copy_into(data("sim_device.eds"), dir / "io/configured_node.dcf");
    write_text(dir / "io/README.txt", "vendor files\n");
    write_text(dir / "io/notes.eds", "These are not the droids you are looking for.\n");
    write_text(dir / "io/broken.eds", kBroken);
    library = EdsLibrary::load(dir.path().string(), diagnostics);
  }

  static constexpr const char* kBroken =
      "[FileInfo]\nFileName=broken.eds\n[DeviceInfo]\nVendorNumber=0x7E57C0DE\n"
      "ProductNumber=0x00000600\n[2000]\nParameterName=Value\nObjectType=0x7\n"
      "DataType=0x0007\nAccessType=rw\nParameterValue=No\n";

  ScratchDir dir;
  Diagnostics diagnostics;
  EdsLibrary library;
};

TEST_F(DeviceScanLibrary, LoadsEveryEdsFileUnderTheDirectoryAndNoDcf) {
  EXPECT_EQ(library.size(), 4u) << diagnostics.format();
  EXPECT_FALSE(diagnostics.has_errors()) << diagnostics.format();
}

TEST_F(DeviceScanLibrary, ReportsABrokenFileAsWarningsAtItsLinesAndGoesOn) {
  const std::string broken = dir / "io/broken.eds";
  EXPECT_TRUE(has_warning_at(diagnostics, broken, line_of(kBroken, "ParameterValue=No"),
                             "[2000] ParameterValue \"No\" is not a valid UNSIGNED32"))
      << diagnostics.format();
  EXPECT_TRUE(has_warning_at(diagnostics, broken, 0, "not in the EDS library"));
  EXPECT_TRUE(has_warning_at(diagnostics, dir / "io/notes.eds", 0, "not in the EDS library"));
  // The broken file's vendor and product are not matched.
  EXPECT_FALSE(library.match(identity(0x7E57C0DE, 0x600, 0x00010000)));
}

TEST_F(DeviceScanLibrary, MatchesVendorProductAndTheExactRevision) {
  const auto m = library.match(identity(0x7E57C0DE, 0x508, 0x00020001));
  ASSERT_TRUE(m);
  EXPECT_EQ(m->path, dir / "io/sim_device.eds");
  EXPECT_TRUE(m->revision_exact);
  EXPECT_THAT(m->note, IsEmpty());
  ASSERT_NE(m->eds, nullptr);
  EXPECT_EQ(*m->eds->device_info.find("ProductName"), "SIM-8 simulated I/O");

  const auto upper = library.match(identity(0x7E57C0DE, 0x509, 0x00010000));
  ASSERT_TRUE(upper);
  EXPECT_EQ(upper->path, dir / "io/deep/NO_TYPE.EDS");  // nested, upper-case extension
  EXPECT_TRUE(upper->revision_exact);

  const auto rev1 = library.match(identity(0xABCD, 0x42, 0x00010002));
  ASSERT_TRUE(rev1);
  EXPECT_EQ(rev1->path, dir / "abcd/spec_slave.Eds");
  const auto rev2 = library.match(identity(0xABCD, 0x42, 0x00020003));
  ASSERT_TRUE(rev2);
  EXPECT_EQ(rev2->path, dir / "abcd/slave_rev2.eds");
}

TEST_F(DeviceScanLibrary, NearestRevisionPrefersTheSameMajorRevisionAndSaysSo) {
  // CiA 301 §7.5.2.23: 00020005h is major 2, minor 5. The library has 2.3 and 1.2: 2.3 (same
  // major, lower minor: the device is a compatible superset of what that file describes).
  const auto newer_minor = library.match(identity(0xABCD, 0x42, 0x00020005));
  ASSERT_TRUE(newer_minor);
  EXPECT_EQ(newer_minor->path, dir / "abcd/slave_rev2.eds");
  EXPECT_FALSE(newer_minor->revision_exact);
  EXPECT_EQ(newer_minor->note,
            "revision 0x00020005 not in the library; nearest 0x00020003 (same "
            "major revision, lower minor) in " +
                (dir / "abcd/slave_rev2.eds"));
  // 1.1: no lower minor of major 1, the higher 1.2 rather than 2.3.
  const auto older_minor = library.match(identity(0xABCD, 0x42, 0x00010001));
  ASSERT_TRUE(older_minor);
  EXPECT_EQ(older_minor->path, dir / "abcd/spec_slave.Eds");
  EXPECT_THAT(older_minor->note, HasSubstr("same major revision, higher minor"));
  // 3.0: no file of major 3; the closest number, 2.3.
  const auto other_major = library.match(identity(0xABCD, 0x42, 0x00030000));
  ASSERT_TRUE(other_major);
  EXPECT_EQ(other_major->path, dir / "abcd/slave_rev2.eds");
  EXPECT_THAT(other_major->note, HasSubstr("another major revision"));
  // No revision reported: the highest.
  const auto none = library.match(identity(0xABCD, 0x42, std::nullopt));
  ASSERT_TRUE(none);
  EXPECT_EQ(none->path, dir / "abcd/slave_rev2.eds");
  EXPECT_THAT(none->note, HasSubstr("the device reports no revision"));
}

TEST_F(DeviceScanLibrary, SameVendorOtherProductIsNoMatchAndMissingNamesWhatTheLibraryHas) {
  const DeviceIdentity device = identity(0x7E57C0DE, 0x999, 0x00010000);
  EXPECT_FALSE(library.match(device));
  EXPECT_EQ(library.missing(device),
            "no EDS for vendor-ID 0x7E57C0DE, product code 0x00000999, revision 0x00010000; the "
            "library has, of the same vendor, other products: 0x00000509 rev 0x00010000 (" +
                (dir / "io/deep/NO_TYPE.EDS") + "), 0x00000508 rev 0x00020001 (" +
                (dir / "io/sim_device.eds") + ")");
}

TEST_F(DeviceScanLibrary, UnknownVendorIsNoMatchAndMissingSaysSo) {
  const DeviceIdentity device = identity(0x11111111, 0x1, 0x00010000);
  EXPECT_FALSE(library.match(device));
  EXPECT_EQ(library.missing(device),
            "no EDS for vendor-ID 0x11111111, product code 0x00000001, revision 0x00010000; the "
            "library has no file of vendor-ID 0x11111111 (4 files)");
}

TEST(DeviceScanLibraryLoad, AMissingDirectoryIsAnError) {
  Diagnostics diagnostics;
  const auto library = EdsLibrary::load(data("no/such/directory"), diagnostics);
  EXPECT_EQ(library.size(), 0u);
  EXPECT_TRUE(diagnostics.has_errors());
}

TEST(DeviceScanLibraryLoad, AddedDescriptionIsUsedAsAnEds) {
  EdsLibrary library;
  DeviceDescription eds = load(data("sim_device.eds"));
  eds.sub(0x1017, 0)->parameter_value = "0x0064";
  library.add(std::move(eds), "1021h of node 3");
  const auto m = library.match(identity(0x7E57C0DE, 0x508, 0x00020001));
  ASSERT_TRUE(m);
  EXPECT_EQ(m->path, "1021h of node 3");
  EXPECT_FALSE(m->eds->sub(0x1017, 0)->parameter_value);
}

// --- the entries a scan reads ------------------------------------------------------------------

std::vector<ObjectAddress> addresses(
    std::initializer_list<std::pair<std::uint16_t, std::uint8_t>> list) {
  std::vector<ObjectAddress> out;
  for (const auto& [index, sub] : list) out.push_back({index, sub});
  return out;
}

TEST(DeviceScanEntries, EveryReadWriteEntryOfTheSimDeviceButCommandsOutputsAndIdentity) {
  // tests/data/sim_device.eds, its rw entries by section: not 1000h/1018h/1200h (ro), 1010h/
  // 1011h (store/restore), 1020h (the master's stamp), 1F50h sub 1 (wo DOMAIN), 1F51h sub 1
  // (program control), 6200h sub 1 (rww, an output), 1400h/1800h sub 0 (ro).
  const auto entries = entries_to_scan(load(data("sim_device.eds")));
  const auto expected =
      addresses({{0x100C, 0}, {0x100D, 0}, {0x1014, 0}, {0x1015, 0}, {0x1016, 1}, {0x1016, 2},
                 {0x1017, 0}, {0x1029, 1}, {0x1400, 1}, {0x1400, 2}, {0x1600, 0}, {0x1600, 1},
                 {0x1600, 2}, {0x1600, 3}, {0x1600, 4}, {0x1600, 5}, {0x1600, 6}, {0x1600, 7},
                 {0x1600, 8}, {0x1800, 1}, {0x1800, 2}, {0x1800, 3}, {0x1800, 4}, {0x1800, 5},
                 {0x1800, 6}, {0x1A00, 0}, {0x1A00, 1}, {0x1A00, 2}, {0x1A00, 3}, {0x1A00, 4},
                 {0x1A00, 5}, {0x1A00, 6}, {0x1A00, 7}, {0x1A00, 8}, {0x2000, 0}, {0x2001, 0}});
  EXPECT_EQ(entries, expected);
}

TEST(DeviceScanEntries, LeavesOutDomainsAndEntriesRefusingReadOnScan) {
  DeviceDescription eds = load(data("sim_device.eds"));
  eds.sub(0x2001, 0)->data_type = 0x000F;  // DOMAIN
  eds.sub(0x2000, 0)->obj_flags = 0x2;     // CiA 306 ObjFlags bit 1: refuse read on scan
  const auto entries = entries_to_scan(eds);
  EXPECT_THAT(entries, Not(Contains(ObjectAddress{0x2001, 0})));
  EXPECT_THAT(entries, Not(Contains(ObjectAddress{0x2000, 0})));
  EXPECT_THAT(entries, Contains(ObjectAddress{0x1017, 0}));
}

// --- the as-found DCF --------------------------------------------------------------------------

// What a scan of sim_device.eds at node 5 could read: every scanned entry, several not at their
// default (1017h, 1016h sub 1, a TPDO disabled, its mapping changed, an RPDO mapping of two
// entries, 2000h, 2001h), the COB-IDs derived from the node-ID at their default, and the identity
// (1000h, 1018h sub 1-4, serial number 12345678h).
Values scanned_sim_device() {
  Values v;
  v[{0x1000, 0}] = u32(0x000F0191);
  v[{0x1018, 0}] = u8(4);
  v[{0x1018, 1}] = u32(0x7E57C0DE);
  v[{0x1018, 2}] = u32(0x00000508);
  v[{0x1018, 3}] = u32(0x00020001);
  v[{0x1018, 4}] = u32(0x12345678);
  v[{0x100C, 0}] = u16(0);
  v[{0x100D, 0}] = u8(0);
  v[{0x1014, 0}] = u32(0x85);  // $NODEID+0x80 at node 5
  v[{0x1015, 0}] = u16(0);
  v[{0x1016, 1}] = u32(0x000A01F4);  // node 10, 500 ms
  v[{0x1016, 2}] = u32(0);
  v[{0x1017, 0}] = u16(250);
  v[{0x1029, 1}] = u8(0);
  v[{0x1400, 1}] = u32(0x205);  // $NODEID+0x200 at node 5
  v[{0x1400, 2}] = u8(0xFF);
  v[{0x1600, 0}] = u8(2);
  v[{0x1600, 1}] = u32(0x62000108);
  v[{0x1600, 2}] = u32(0x20000010);
  for (std::uint8_t s = 3; s <= 8; ++s) v[{0x1600, s}] = u32(0);
  v[{0x1800, 1}] = u32(0x80000185);  // TPDO 1 disabled (CiA 301 §7.5.2.35 bit 31)
  v[{0x1800, 2}] = u8(0xFE);
  v[{0x1800, 3}] = u16(100);
  v[{0x1800, 4}] = u8(0);
  v[{0x1800, 5}] = u16(1000);
  v[{0x1800, 6}] = u8(0);
  v[{0x1A00, 0}] = u8(1);
  v[{0x1A00, 1}] = u32(0x64010110);
  for (std::uint8_t s = 2; s <= 8; ++s) v[{0x1A00, s}] = u32(0);
  v[{0x2000, 0}] = u16(250);
  const std::string name = "SCANNED";
  v[{0x2001, 0}] = std::vector<std::uint8_t>(name.begin(), name.end());
  return v;
}

bool is_identity_entry(ObjectAddress a) {
  return a.index == 0x1000 || a.index == 0x1018;
}

TEST(DeviceScanAsFound, RecordsEveryValueReadExceptNodeIdDerivedDefaultsAndTheSerialNumber) {
  const DeviceDescription eds = load(data("sim_device.eds"));
  const Values values = scanned_sim_device();
  Diagnostics diagnostics;
  const DeviceDescription dcf = as_found_dcf(eds, *NodeId::from(5), values, diagnostics);
  EXPECT_TRUE(diagnostics.empty()) << diagnostics.format();

  // Written and read back as a DCF, as `cfgmgr scan` does.
  ReadOptions options;
  options.file_name = "node5.dcf";
  auto read = parse_device_description(write_device_description(dcf), options);
  ASSERT_TRUE(read.ok()) << read.diagnostics.format();
  const DeviceDescription& back = *read.device;
  ASSERT_TRUE(back.commissioning);
  EXPECT_EQ(back.node_id(), 5);
  EXPECT_EQ(back.commissioning->node_name, "SIM-8 simulated I/O");
  EXPECT_EQ(*back.file_info.find("FileName"), "node5.dcf");

  for (const auto& [address, bytes] : values) {
    const SubObject* sub = back.sub(address.index, address.sub_index);
    ASSERT_NE(sub, nullptr) << to_string(address);
    const bool derived = address == ObjectAddress{0x1014, 0} || address == ObjectAddress{0x1400, 1};
    const bool not_recorded =
        derived || address == ObjectAddress{0x1018, 0} || address == ObjectAddress{0x1018, 4};
    if (not_recorded) {
      EXPECT_FALSE(sub->parameter_value) << to_string(address) << " " << *sub->parameter_value;
      continue;
    }
    ASSERT_TRUE(sub->parameter_value) << to_string(address);
    auto value = parse_value(*sub->basic_type(), *sub->parameter_value);
    ASSERT_TRUE(value.ok()) << to_string(address);
    EXPECT_EQ(encode(*value), bytes) << to_string(address) << " = " << *sub->parameter_value;
  }
  // The derived COB-IDs keep the EDS's $NODEID form; the disabled TPDO's is recorded as read.
  EXPECT_EQ(back.sub(0x1014, 0)->default_value, "$NODEID+0x80");
  EXPECT_EQ(back.sub(0x1400, 1)->default_value, "$NODEID+0x200");
  EXPECT_EQ(back.sub(0x1800, 1)->parameter_value, "0x80000185");
  // The serial number is nowhere in the file a push checks.
  EXPECT_THAT(write_device_description(dcf), Not(HasSubstr("12345678")));
}

TEST(DeviceScanAsFound, ValuesThatDoNotFitTheirTypeOrAreNoScannedEntryAreWarnedAndLeftOut) {
  const DeviceDescription eds = load(data("sim_device.eds"));
  Values values;
  values[{0x1017, 0}] = u32(250);  // UNSIGNED16 in 4 bytes
  values[{0x1010, 1}] = u32(0);    // a command
  values[{0x3000, 0}] = u8(1);     // not in the EDS
  values[{0x100C, 0}] = u16(100);  // fine
  Diagnostics diagnostics;
  const DeviceDescription dcf = as_found_dcf(eds, *NodeId::from(5), values, diagnostics);
  EXPECT_EQ(diagnostics.count(Severity::Warning), 3u) << diagnostics.format();
  EXPECT_FALSE(dcf.sub(0x1017, 0)->parameter_value);
  EXPECT_FALSE(dcf.sub(0x1010, 1)->parameter_value);
  EXPECT_EQ(dcf.sub(0x100C, 0)->parameter_value, "0x64");  // format_value
  EXPECT_THAT(diagnostics.format(), HasSubstr("node 5: 1017h sub 00h not recorded"));
}

TEST(DeviceScanAsFound, AddsTheIdentityEntriesAnEdsLacks) {
  // An EDS with 1018h sub 1 only (CiA 301 makes sub 2-4 optional): the product code and revision
  // read are still what a push checks.
  DeviceDescription eds = load(data("sim_device.eds"));
  eds.object(0x1018)->subs.erase(2);
  eds.object(0x1018)->subs.erase(3);
  eds.object(0x1018)->subs.erase(4);
  eds.sub(0x1018, 0)->default_value = "1";
  Values values;
  values[{0x1018, 2}] = u32(0x508);
  values[{0x1018, 3}] = u32(0x00020004);
  Diagnostics diagnostics;
  const DeviceDescription dcf = as_found_dcf(eds, *NodeId::from(5), values, diagnostics);
  EXPECT_TRUE(diagnostics.empty()) << diagnostics.format();
  ASSERT_NE(dcf.sub(0x1018, 3), nullptr);
  EXPECT_EQ(dcf.sub(0x1018, 2)->parameter_value, "0x508");
  EXPECT_EQ(dcf.sub(0x1018, 3)->parameter_value, "0x20004");
  EXPECT_EQ(dcf.sub(0x1018, 3)->access, AccessType::Ro);
  EXPECT_EQ(dcf.sub(0x1018, 0)->default_value, "0x03");  // the highest sub-index now
  const DeviceIdentity id = identity_of(dcf, *NodeId::from(5));
  EXPECT_EQ(id.product_code, 0x508u);
  EXPECT_EQ(id.revision_number, 0x00020004u);
}

// The last value each entry is written with: the state a device is left in after the writes.
std::map<ObjectAddress, std::vector<std::uint8_t>> state_after(
    const std::vector<ObjectWrite>& writes) {
  std::map<ObjectAddress, std::vector<std::uint8_t>> state;
  for (const auto& w : writes) state[{w.index, w.sub_index}] = w.data;
  return state;
}

std::string master_value(const Network& network, std::uint16_t index, std::uint8_t node) {
  const SubObject* sub = network.master.sub(index, node);
  if (sub == nullptr || !sub->configured_value()) return "(none)";
  auto value = parse_value(DataType::Unsigned32, *sub->configured_value());
  return value ? hex(value->as_unsigned(), 8) : "(bad)";
}

TEST(DeviceScanAsFound, PushOfTheProjectReproducesTheScannedDeviceAndChecksItsIdentity) {
  ScratchDir dir;
  const DeviceDescription eds = load(data("sim_device.eds"));
  const Values values = scanned_sim_device();
  Diagnostics diagnostics;
  const NodeId node = *NodeId::from(5);
  write_text(dir / scan_dcf_file_name(node),
             write_device_description(as_found_dcf(eds, node, values, diagnostics)));
  write_text(dir / "nodelist.cpj",
             scan_project("scanned", {{node, scan_dcf_file_name(node), "io"}}));

  const NetworkLoad loaded = load_network(dir / "nodelist.cpj");
  ASSERT_TRUE(loaded.ok()) << loaded.diagnostics.format();
  EXPECT_TRUE(loaded.diagnostics.empty()) << loaded.diagnostics.format();
  const Network& network = *loaded.network;
  EXPECT_EQ(network.name, "scanned");
  const NetworkNode* pushed = network.find(node);
  ASSERT_NE(pushed, nullptr);
  EXPECT_EQ(pushed->name, "io");

  // A replacement at factory defaults (the EDS's DefaultValues, $NODEID = 5) that gets these
  // writes holds every value read; the writes touch nothing else.
  const auto state = state_after(pushed->writes);
  for (const auto& [address, bytes] : values) {
    if (is_identity_entry(address)) {
      EXPECT_FALSE(state.count(address)) << to_string(address);  // ro: checked, not written
      continue;
    }
    const auto written = state.find(address);
    if (written != state.end()) {
      EXPECT_EQ(written->second, bytes) << to_string(address);
      continue;
    }
    const SubObject* sub = eds.sub(address.index, address.sub_index);
    auto factory = parse_value(*sub->basic_type(), *sub->default_value, node.value());
    ASSERT_TRUE(factory.ok()) << to_string(address);
    EXPECT_EQ(encode(*factory), bytes) << to_string(address) << " is not written";
  }
  for (const auto& [address, bytes] : state) {
    EXPECT_TRUE(values.count(address)) << to_string(address) << " written but not scanned";
  }
  EXPECT_EQ(state.at({0x1017, 0}), u16(250));
  EXPECT_EQ(state.at({0x1800, 1}), u32(0x80000185));
  EXPECT_EQ(state.at({0x1600, 0}), u8(2));

  // CiA 302-2 §3.4 e: the master checks device type, vendor-ID, product code and revision as
  // the scanned device reported them (a newer minor revision passes the boot's 1F87h rule), and
  // not the serial number (1F88h 0: not checked).
  EXPECT_EQ(master_value(network, 0x1F84, 5), "0x000F0191");
  EXPECT_EQ(master_value(network, 0x1F85, 5), "0x7E57C0DE");
  EXPECT_EQ(master_value(network, 0x1F86, 5), "0x00000508");
  EXPECT_EQ(master_value(network, 0x1F87, 5), "0x00020001");
  const std::string serial = master_value(network, 0x1F88, 5);
  EXPECT_TRUE(serial == "(none)" || serial == "0x00000000") << serial;
}

// --- a device without EDS ----------------------------------------------------------------------

TEST(DeviceScanIdentityOnly, LoadsInAProjectWithNoWritesAndItsIdentityChecked) {
  ScratchDir dir;
  DeviceIdentity found;
  found.device_type = 0x00020192;
  found.vendor_id = 0x0BADCAFE;
  found.product_code = 0x77;
  found.revision_number = 0x00010003;
  found.serial_number = 0xCAFE0001;
  const NodeId node = *NodeId::from(9);
  write_text(dir / scan_dcf_file_name(node),
             write_device_description(identity_only_dcf(node, found)));
  write_text(dir / "nodelist.cpj",
             scan_project("one unknown device", {{node, scan_dcf_file_name(node), ""}}));

  const NetworkLoad loaded = load_network(dir / "nodelist.cpj");
  ASSERT_TRUE(loaded.ok()) << loaded.diagnostics.format();
  EXPECT_TRUE(loaded.diagnostics.empty()) << loaded.diagnostics.format();
  EXPECT_FALSE(loaded.diagnostics.has_errors());
  const Network& network = *loaded.network;
  const NetworkNode* pushed = network.find(node);
  ASSERT_NE(pushed, nullptr);
  EXPECT_THAT(pushed->writes, IsEmpty());
  EXPECT_EQ(master_value(network, 0x1F84, 9), "0x00020192");
  EXPECT_EQ(master_value(network, 0x1F85, 9), "0x0BADCAFE");
  EXPECT_EQ(master_value(network, 0x1F86, 9), "0x00000077");
  EXPECT_EQ(master_value(network, 0x1F87, 9), "0x00010003");
  EXPECT_THAT(read_text(dir / scan_dcf_file_name(node)), Not(HasSubstr("CAFE0001")));
}

// --- the project file --------------------------------------------------------------------------

TEST(DeviceScanProject, IsACia3063TopologyOfTheNodesByNodeId) {
  const std::string text = scan_project(
      "line 1", {{*NodeId::from(12), "node12.dcf", "drive"}, {*NodeId::from(3), "node3.dcf", ""}});
  EXPECT_EQ(text,
            "[Topology]\r\nNetName=line 1\r\nNodes=0x02\r\n"
            "Node3Present=0x01\r\nNode3DCFName=node3.dcf\r\n"
            "Node12Present=0x01\r\nNode12Name=drive\r\nNode12DCFName=node12.dcf\r\n");
}

// --- vendor files of the corpus ----------------------------------------------------------------

// Identities from the files' [DeviceInfo], equal to their 1018h DefaultValues:
//   systec/IoX1_16DI_8DO.eds  63 (3Fh) / 3001000 (2DCAA8h) / 01400538h
//   systec/phyPS409Y.eds      3Fh / 409h / 01190528h
//   nanotec/CL4-E-1-12.eds    26Ch / 5Ah / 08A50000h
//   zeroerr/ZeroErrDriver.eds 5A65726Fh / 26483052h / 00020111h
TEST(DeviceScanCorpus, LibraryOfVendorFilesMatchesExactNearestAndNamesWhatIsMissing) {
  SKIP_WITHOUT_CORPUS();
  ScratchDir dir;
  copy_into(corpus("systec/IoX1_16DI_8DO.eds"), dir / "systec/IoX1_16DI_8DO.eds");
  copy_into(corpus("systec/phyPS409Y.eds"), dir / "systec/old/phyPS409Y.EDS");
  copy_into(corpus("nanotec/CL4-E-1-12.eds"), dir / "nanotec/CL4-E-1-12.eds");
  copy_into(corpus("zeroerr/ZeroErrDriver.eds"), dir / "zeroerr/ZeroErrDriver.eds");
  write_text(dir / "zeroerr/broken.eds",
             "[FileInfo]\nFileName=broken.eds\n[2000]\nDataType=0x7\n"
             "AccessType=rw\nParameterValue=none\n");
  write_text(dir / "zeroerr/manual.pdf.txt", "not a device file\n");
  Diagnostics diagnostics;
  const EdsLibrary library = EdsLibrary::load(dir.path().string(), diagnostics);
  EXPECT_EQ(library.size(), 4u);
  EXPECT_FALSE(diagnostics.has_errors()) << diagnostics.format();
  EXPECT_TRUE(has_warning_at(diagnostics, dir / "zeroerr/broken.eds", 6, "ParameterValue"))
      << diagnostics.format();

  const auto io = library.match(identity(0x3F, 3001000, 0x01400538));
  ASSERT_TRUE(io);
  EXPECT_EQ(io->path, dir / "systec/IoX1_16DI_8DO.eds");
  EXPECT_TRUE(io->revision_exact);
  // ZeroErr 2.17h reported, the library has 2.11h: nearest, same major, lower minor.
  const auto drive = library.match(identity(0x5A65726F, 0x26483052, 0x00020117));
  ASSERT_TRUE(drive);
  EXPECT_EQ(drive->path, dir / "zeroerr/ZeroErrDriver.eds");
  EXPECT_FALSE(drive->revision_exact);
  EXPECT_THAT(drive->note, HasSubstr("nearest 0x00020111 (same major revision, lower minor)"));
  // SYS TEC's other product: not the I/O module's file.
  const DeviceIdentity other = identity(0x3F, 0x410, 0x01190528);
  EXPECT_FALSE(library.match(other));
  EXPECT_THAT(library.missing(other),
              HasSubstr("product code 0x00000410, revision 0x01190528; the library has, of the "
                        "same vendor, other products: 0x002DCAA8 rev 0x01400538"));
  EXPECT_THAT(library.missing(other), HasSubstr("0x00000409 rev 0x01190528"));
  // A vendor the library lacks.
  EXPECT_THAT(library.missing(identity(0x1A3, 0x1, 0x1)),
              HasSubstr("the library has no file of vendor-ID 0x000001A3 (4 files)"));
}

TEST(DeviceScanCorpus, EntriesOfANanotecDriveLeaveOutItsProgramDomainsAndCommands) {
  SKIP_WITHOUT_CORPUS();
  // nanotec/CL4-E-1-12.eds: 1F50h sub 1/2 are rw DOMAINs (program data, line 2749), 1010h/1011h
  // sub 1-0Dh rw, 1020h sub 1/2 rw, 1600h-1607h/1A00h-1A07h sub 0-8 rw, 1017h rw.
  const auto entries = entries_to_scan(load(corpus("nanotec/CL4-E-1-12.eds")));
  for (std::uint16_t pdo = 0; pdo < 8; ++pdo) {
    for (std::uint8_t sub = 0; sub <= 8; ++sub) {
      EXPECT_THAT(entries, Contains(ObjectAddress{static_cast<std::uint16_t>(0x1600 + pdo), sub}));
      EXPECT_THAT(entries, Contains(ObjectAddress{static_cast<std::uint16_t>(0x1A00 + pdo), sub}));
    }
  }
  EXPECT_THAT(entries, Contains(ObjectAddress{0x1017, 0}));
  EXPECT_THAT(entries, Contains(ObjectAddress{0x1800, 1}));
  EXPECT_THAT(entries, Contains(ObjectAddress{0x1400, 1}));
  for (const auto& a : entries) {
    EXPECT_NE(a.index, 0x1010) << to_string(a);
    EXPECT_NE(a.index, 0x1011) << to_string(a);
    EXPECT_NE(a.index, 0x1020) << to_string(a);
    EXPECT_NE(a.index, 0x1F50) << to_string(a);
    EXPECT_NE(a.index, 0x1F51) << to_string(a);
    EXPECT_NE(a.index, 0x1000) << to_string(a);
    EXPECT_NE(a.index, 0x1018) << to_string(a);
  }
  EXPECT_TRUE(std::is_sorted(entries.begin(), entries.end()));
}

}  // namespace
}  // namespace cfg
