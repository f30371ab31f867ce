// `cfgmgr scan` end to end (issue 32, "Done when"): a running machine over the UDP multicast bus
// in real time, against devices written with python-can alone from the specs
// (tests/io/python/scan_slaves.py) and an EDS library written for them (tests/data/scan/eds):
// scan, check, push onto replacement devices at their factory defaults, every value equal to
// the original's entry by entry, verify. The decoys: same vendor other product (no EDS), same
// product at an older revision than any EDS (the nearest, said), a vendor no EDS has, a device
// that refuses reads of some rw entries, a device without node-ID (LSS Fastscan), and a file
// in the library that is no EDS. Runs inside a private network namespace
// (tests/support/run_in_netns.sh) as the other UDP tool tests do; elsewhere it skips. The output
// directory's rules are checked on sim: (ScanOutput.*), which needs no namespace.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "multicast_netns.hpp"
#include "python_peer.hpp"
#include "tool_test_support.hpp"

namespace {

using ::testing::EndsWith;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;
using tool_test::Json;
using tool_test::ScratchDir;

constexpr const char* kPort = "43231";  // 43232 is free for the next test file

// scan_slaves.py's identities (its docstring) and the EDS library's files.
constexpr std::uint32_t kVendor = 0x00C0FFEE;
constexpr std::uint32_t kDrive = 0x2001;
constexpr std::uint32_t kDriveRevision = 0x00020001;
constexpr std::uint32_t kOldRevision = 0x00010003;  // older than both EDS of the drive
constexpr std::uint32_t kFirstSerials = 0x5E000000;
constexpr std::uint32_t kReplacementSerials = 0x6E000000;
// The drive's EDS (drives/sd2001_r2.eds) has 39 entries the scan reads: its rw and rwr
// sub-objects but 1010h/1011h sub 1 and the DOMAIN 2007h. The device answers each of them.
constexpr double kDriveEntries = 39;
// The sensor's EDS lists 6 (1017h, 2100h-2104h); the device has no 2101h and refuses reads of
// 2102h.
constexpr double kSensorRead = 4;
constexpr double kSensorSkipped = 2;

const std::vector<std::string> kDevices = {"drive@3", "drive_old@4", "io@5", "foreign@6",
                                           "sensor@7"};

std::string eds_library() {
  return tool_test::data_path("scan/eds");
}

// What the peers printed, by kind of line.
struct PeerLog {
  std::vector<std::string> lines;

  std::string all() const {
    std::string text;
    for (const auto& l : lines) text += l + "\n";
    return text;
  }
  /// The lines starting with `prefix` (e.g. "WRITE 5 ").
  std::vector<std::string> starting(const std::string& prefix) const {
    std::vector<std::string> out;
    for (const auto& l : lines) {
      if (l.rfind(prefix, 0) == 0) out.push_back(l);
    }
    return out;
  }
  /// The DUMP of `node` at the end: "INDEX SUB" -> data (hex, little-endian).
  std::map<std::string, std::string> dump(int node) const {
    std::map<std::string, std::string> values;
    for (const auto& l : starting("DUMP " + std::to_string(node) + " ")) {
      std::istringstream in(l);
      std::string word, number, index, sub, data;
      in >> word >> number >> index >> sub >> data;
      values[index + " " + sub] = data;
    }
    return values;
  }
  /// The entries of `node` that were read ("INDEX SUB").
  std::set<std::string> reads(int node) const {
    std::set<std::string> out;
    for (const auto& l : starting("READ " + std::to_string(node) + " ")) {
      out.insert(l.substr(l.find(' ', 5) + 1));
    }
    return out;
  }
};

/// Ends the peers (the frame 7FFh without data: they dump their entries and end) and takes what
/// they printed.
PeerLog end_peers(test_support::PythonPeer& peers) {
  {
    test_support::PythonPeer end({"send", test_support::kUdpTestGroup, kPort, "7FF#"});
    (void)end.finish();
  }
  PeerLog log{peers.read_all()};
  EXPECT_EQ(peers.finish(), 0) << log.all();
  return log;
}

const Json* node_of(const Json& report, int node_id) {
  const Json* nodes = report.get("nodes");
  if (nodes == nullptr) return nullptr;
  for (const auto& n : nodes->array) {
    const Json* id = n.get("node_id");
    if (id != nullptr && id->number == node_id) return &n;
  }
  return nullptr;
}

double number(const Json& j, const std::string& key) {
  const Json* v = j.get(key);
  EXPECT_TRUE(v != nullptr && v->is(Json::Kind::Number)) << key;
  return v != nullptr ? v->number : -1;
}

std::string text(const Json& j, const std::string& key) {
  const Json* v = j.get(key);
  EXPECT_TRUE(v != nullptr && v->is(Json::Kind::String)) << key;
  return v != nullptr ? v->string : std::string();
}

void expect_identity(const Json& node, std::uint32_t vendor, std::uint32_t product,
                     std::uint32_t revision, std::uint32_t serial) {
  const Json* id = node.get("identity");
  ASSERT_NE(id, nullptr);
  EXPECT_EQ(number(*id, "vendor_id"), vendor);
  EXPECT_EQ(number(*id, "product_code"), product);
  EXPECT_EQ(number(*id, "revision"), revision);
  EXPECT_EQ(number(*id, "serial_number"), serial);
}

TEST(ScanUdp, EndToEndOverUdp) {
  tool_test::run_in_private_netns("ScanUdpInNetns.*");
}

TEST(ScanUdpInNetns, ScanPushOntoReplacementsAndVerifyRestoreEveryDeviceAsFound) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  ScratchDir dir;
  const std::string bus = test_support::udp_test_url(kPort);
  const std::string script = test_support::python_script("scan_slaves.py");
  const std::string out = dir / "out";
  const std::string project = out + "/nodelist.cpj";

  // 1. The running machine: every device as found, and one without node-ID.
  PeerLog found;
  tool_test::RunResult scan;
  {
    std::vector<std::string> args{test_support::kUdpTestGroup, kPort, "40"};
    args.insert(args.end(), kDevices.begin(), kDevices.end());
    args.push_back("lss");
    test_support::PythonPeer peers(script, args);
    ASSERT_EQ(peers.read_line(), "READY");
    scan = tool_test::cfgmgr(dir, {"scan", "--bus", bus, "--eds-dir", eds_library(), "-o", out,
                                   "--json", dir / "scan.json"});
    found = end_peers(peers);
  }
  const std::string context = scan.out + scan.err + "--- devices:\n" + found.all();
  // Exit 4: io and foreign have no EDS (they are in the project by their identity only).
  ASSERT_EQ(scan.exit_code, 4) << context;
  // The file of the library that is no EDS is named with its diagnostic; the scan went on.
  EXPECT_THAT(scan.err, HasSubstr("io2002_saved_as_xdd.eds"));
  EXPECT_THAT(scan.err, HasSubstr("no [section] header found"));

  // The scan only reads: no SDO download, no NMT command, no LSS configuration.
  EXPECT_THAT(found.starting("WRITE "), IsEmpty()) << context;
  EXPECT_THAT(found.starting("REFUSED"), testing::Each(Not(HasSubstr(" down")))) << context;
  EXPECT_THAT(found.starting("NMT "), IsEmpty()) << context;
  EXPECT_THAT(found.starting("SAVE "), IsEmpty()) << context;
  EXPECT_THAT(found.starting("LSS CONFIGURE"), IsEmpty()) << context;
  EXPECT_THAT(found.starting("LSS STORE"), IsEmpty()) << context;
  // Not 1010h/1011h (store, restore), not a DOMAIN, not ro/const/wo entries.
  for (const char* entry : {"1010 01", "1011 01", "2007 00", "2009 00", "200A 00", "1008 00"}) {
    EXPECT_FALSE(found.reads(3).contains(entry)) << entry << "\n" << context;
  }
  // The devices without EDS: their identity only.
  for (int node : {5, 6}) {
    for (const auto& entry : found.reads(node)) {
      EXPECT_TRUE(entry.rfind("1000 ", 0) == 0 || entry.rfind("1018 ", 0) == 0)
          << "node " << node << " " << entry;
    }
  }

  auto report = tool_test::parse_json_file(dir / "scan.json");
  ASSERT_TRUE(report) << context;
  EXPECT_EQ(text(*report, "output"), out);
  EXPECT_EQ(number(*report, "asked"), 127);
  EXPECT_EQ(number(*report, "absent"), 122);
  ASSERT_NE(report->get("nodes"), nullptr);
  EXPECT_EQ(report->get("nodes")->array.size(), 5U) << context;
  {
    // The drive: its EDS exactly, from the library's subfolder.
    const Json* n = node_of(*report, 3);
    ASSERT_NE(n, nullptr) << context;
    expect_identity(*n, kVendor, kDrive, kDriveRevision, kFirstSerials + 3);
    EXPECT_EQ(number(*n->get("identity"), "device_type"), 0x00020192);
    EXPECT_THAT(text(*n, "eds"), EndsWith("drives/sd2001_r2.eds"));
    EXPECT_TRUE(n->get("revision_exact")->boolean);
    EXPECT_EQ(text(*n, "dcf"), "node3.dcf");
    EXPECT_EQ(number(*n, "entries_read"), kDriveEntries) << context;
    EXPECT_EQ(number(*n, "entries_skipped"), 0) << context;
  }
  {
    // The older revision: the nearest EDS (2.1, not 3.0, whose 2020h the device lacks), said.
    const Json* n = node_of(*report, 4);
    ASSERT_NE(n, nullptr) << context;
    expect_identity(*n, kVendor, kDrive, kOldRevision, kFirstSerials + 4);
    EXPECT_THAT(text(*n, "eds"), EndsWith("drives/sd2001_r2.eds"));
    EXPECT_FALSE(n->get("revision_exact")->boolean);
    EXPECT_THAT(text(*n, "note"), Not(IsEmpty()));
    EXPECT_EQ(number(*n, "entries_read"), kDriveEntries) << context;
    EXPECT_EQ(number(*n, "entries_skipped"), 0) << context;
    EXPECT_THAT(scan.err, HasSubstr("node 4: " + text(*n, "note")));
  }
  {
    // Same vendor, other product (the library's only file of it is no EDS), and a vendor no
    // EDS has: in the project with their identity, a line saying which EDS is missing.
    const Json* io = node_of(*report, 5);
    const Json* foreign = node_of(*report, 6);
    ASSERT_TRUE(io != nullptr && foreign != nullptr) << context;
    expect_identity(*io, kVendor, 0x2002, 0x00010000, kFirstSerials + 5);
    expect_identity(*foreign, 0x00BADBAD, 0x0001, 0x00010000, kFirstSerials + 6);
    for (const Json* n : {io, foreign}) {
      EXPECT_TRUE(n->get("eds")->is(Json::Kind::Null)) << context;
      EXPECT_THAT(text(*n, "note"), Not(IsEmpty()));
      EXPECT_EQ(number(*n, "entries_read"), 0);
      EXPECT_THAT(scan.err,
                  HasSubstr("node " + std::to_string(static_cast<int>(number(*n, "node_id"))) +
                            ": " + text(*n, "note")));
    }
  }
  {
    // The sensor refuses two of its EDS's rw entries: skipped and counted, not fatal.
    const Json* n = node_of(*report, 7);
    ASSERT_NE(n, nullptr) << context;
    expect_identity(*n, kVendor, 0x3001, 0x00010000, kFirstSerials + 7);
    EXPECT_THAT(text(*n, "eds"), EndsWith("sensor_s3001.eds"));
    EXPECT_EQ(number(*n, "entries_read"), kSensorRead) << context;
    EXPECT_EQ(number(*n, "entries_skipped"), kSensorSkipped) << context;
  }
  {
    // The device without node-ID, by its LSS address (CiA 305 Fastscan).
    const Json* unconfigured = report->get("unconfigured");
    ASSERT_NE(unconfigured, nullptr);
    ASSERT_EQ(unconfigured->array.size(), 1U) << context;
    const Json& a = unconfigured->array[0];
    EXPECT_EQ(number(a, "vendor_id"), kVendor);
    EXPECT_EQ(number(a, "product_code"), kDrive);
    EXPECT_EQ(number(a, "revision"), kDriveRevision);
    EXPECT_EQ(number(a, "serial"), kFirstSerials + 0x99);
    EXPECT_TRUE(report->get("lss_problem")->is(Json::Kind::Null));
  }

  // The project: every DCF and the network check clean.
  for (const std::string file :
       {"nodelist.cpj", "node3.dcf", "node4.dcf", "node5.dcf", "node6.dcf", "node7.dcf"}) {
    const auto check = tool_test::cfgmgr(dir, {"check", out + "/" + file});
    EXPECT_EQ(check.exit_code, 0) << file << ": " << check.out << check.err;
  }
  {
    // Node-ID-derived COB-IDs equal to their default keep the EDS's $NODEID form (no
    // ParameterValue), so the DCF follows its NodeID; the disabled TPDO2 is kept as found.
    auto read = cfg::read_device_file(out + "/node3.dcf");
    ASSERT_TRUE(read.ok()) << read.diagnostics.format();
    const cfg::DeviceDescription& dcf = *read.device;
    EXPECT_EQ(dcf.node_id(), 3);
    const std::pair<std::uint16_t, std::uint8_t> derived[] = {
        {0x1014, 0}, {0x1400, 1}, {0x1800, 1}};
    for (const auto& [index, sub] : derived) {
      ASSERT_NE(dcf.sub(index, sub), nullptr);
      EXPECT_FALSE(dcf.sub(index, sub)->parameter_value)
          << std::hex << index << " " << *dcf.sub(index, sub)->parameter_value;
    }
    ASSERT_NE(dcf.sub(0x1801, 1), nullptr);
    ASSERT_TRUE(dcf.sub(0x1801, 1)->parameter_value);
    EXPECT_THAT(
        std::string(*dcf.sub(0x1801, 1)->parameter_value),
        testing::AnyOf(testing::StrCaseEq("0x80000283"), testing::StrCaseEq("$NODEID+0x80000280")));
    ASSERT_NE(dcf.sub(0x2005, 0), nullptr);
    ASSERT_TRUE(dcf.sub(0x2005, 0)->parameter_value);
    EXPECT_EQ(std::string(*dcf.sub(0x2005, 0)->parameter_value), "AXIS_LEFT_01");
  }

  // 2. The replacements: factory defaults, other serial numbers; push, then verify.
  PeerLog replaced;
  tool_test::RunResult push, verify;
  {
    std::vector<std::string> args{"--factory", "--serial", "6E000000", test_support::kUdpTestGroup,
                                  kPort,       "40"};
    args.insert(args.end(), kDevices.begin(), kDevices.end());
    test_support::PythonPeer peers(script, args);
    ASSERT_EQ(peers.read_line(), "READY");
    push = tool_test::cfgmgr(dir, {"push", project, "--bus", bus});
    verify = tool_test::cfgmgr(dir, {"verify", project, "--bus", bus});
    replaced = end_peers(peers);
  }
  const std::string pushed = push.out + push.err + "--- verify:\n" + verify.out + verify.err +
                             "--- devices:\n" + replaced.all();
  EXPECT_EQ(push.exit_code, 0) << pushed;
  EXPECT_EQ(verify.exit_code, 0) << pushed;
  // A refused download: only the master's 1010h sub 1 "save" after a download (CiA 302-2 §3.5)
  // on a device that has no storage (the sensor's EDS has no 1010h).
  for (const auto& line : replaced.starting("REFUSED ")) {
    if (line.find(" down") != std::string::npos) {
      EXPECT_THAT(line, testing::MatchesRegex("REFUSED [0-9]+ 1010 01 06020000 down")) << pushed;
    }
  }
  // Every entry the original answered a read for holds the original's value, but the serial
  // number (another device).
  for (int node : {3, 4, 7}) {
    auto original = found.dump(node);
    auto replacement = replaced.dump(node);
    ASSERT_FALSE(original.empty()) << node;
    original.erase("1018 04");
    replacement.erase("1018 04");
    EXPECT_EQ(replacement, original) << "node " << node << "\n" << pushed;
    EXPECT_THAT(replaced.starting("WRITE " + std::to_string(node) + " "), Not(IsEmpty()));
  }
  // The devices without EDS are left as they are: no write, factory values still.
  for (int node : {5, 6}) {
    // No download at all: not even the save (1010h) after the empty configuration.
    const std::string prefix = "REFUSED " + std::to_string(node) + " ";
    EXPECT_THAT(replaced.starting("WRITE " + std::to_string(node) + " "), IsEmpty()) << pushed;
    for (const auto& line : replaced.starting(prefix)) {
      EXPECT_THAT(line, Not(HasSubstr(" down"))) << pushed;
    }
    EXPECT_EQ(replaced.dump(node)["2000 00"], "00000000") << pushed;
    EXPECT_EQ(found.dump(node)["2000 00"], "FECAAD0B");
  }
}

// --- the output directory (sim:, no namespace needed) --------------------------------------

const char* const kOldProject =
    "[Topology]\nNetName=old\nNodes=0x02\nNode3Present=0x01\nNode3Name=old3\n"
    "Node3DCFName=node3.dcf\nNode5Present=0x01\nNode5Name=old5\nNode5DCFName=node5.dcf\n";

// No device answered: nothing is written (exit 4), the old project stays as it was.
TEST(ScanOutput, NoDeviceAnsweringLeavesAnExistingProjectAsItWas) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "out");
  tool_test::write_file(dir / "out/nodelist.cpj", std::string(kOldProject));
  const std::string bus = "sim:?device=" + eds_library() + "/sensor_s3001.eds@9";
  const auto r = tool_test::cfgmgr(
      dir, {"scan", "--bus", bus, "--eds-dir", eds_library(), "--node", "10", "-o", dir / "out"});
  EXPECT_EQ(r.exit_code, 4) << r.out << r.err;
  EXPECT_EQ(tool_test::slurp(dir / "out/nodelist.cpj"), kOldProject);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir / "out"),
                          std::filesystem::directory_iterator{}),
            1);
}

// An output directory with an older project: nodelist.cpj is replaced whole (it names only
// the devices found now), no temporary file is left; the broken library file is named and
// skipped.
TEST(ScanOutput, AnExistingProjectIsReplacedWholeAndABrokenEdsFileIsSkipped) {
  ScratchDir dir;
  std::filesystem::create_directories(dir / "out");
  tool_test::write_file(dir / "out/nodelist.cpj", std::string(kOldProject));
  tool_test::write_file(dir / "out/node3.dcf", std::string("; an old DCF\n"));
  const std::string bus = "sim:?device=" + eds_library() + "/sensor_s3001.eds@3";
  const auto r = tool_test::cfgmgr(dir, {"scan", "--bus", bus, "--eds-dir", eds_library(), "-o",
                                         dir / "out", "--json", dir / "scan.json", "--no-lss"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("io2002_saved_as_xdd.eds"));
  const std::string project = tool_test::slurp(dir / "out/nodelist.cpj");
  EXPECT_THAT(project, HasSubstr("Node3DCFName=node3.dcf"));
  EXPECT_THAT(project, Not(HasSubstr("Node5")));
  EXPECT_THAT(project, Not(HasSubstr("NetName=old")));
  EXPECT_THAT(tool_test::slurp(dir / "out/node3.dcf"), Not(HasSubstr("an old DCF")));
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir / "out")) {
    names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"node3.dcf", "nodelist.cpj"}));
  const auto check = tool_test::cfgmgr(dir, {"check", dir / "out/nodelist.cpj"});
  EXPECT_EQ(check.exit_code, 0) << check.out << check.err;
  auto report = tool_test::parse_json_file(dir / "scan.json");
  ASSERT_TRUE(report);
  const Json* n = node_of(*report, 3);
  ASSERT_NE(n, nullptr);
  EXPECT_THAT(text(*n, "eds"), EndsWith("sensor_s3001.eds"));
  // A device built from the EDS has every entry of it: the 6 rw ones are read.
  EXPECT_EQ(number(*n, "entries_read"), 6);
  EXPECT_EQ(number(*n, "entries_skipped"), 0);
}

}  // namespace
