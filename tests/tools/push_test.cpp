// cfgmgr push end to end on the simulated bus (sim:): the sample network (samples/network) and
// the test networks of tests/data/network. The expected entries and bytes per node come from the
// nodes' concise DCFs as dcf2concise writes them from the same DCFs (CiA 302 §6.2 stream: a
// UNSIGNED32 count, then per entry index, sub-index, size and data).
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "tool_test_support.hpp"

namespace {

using tool_test::Json;
using tool_test::JsonParser;
using tool_test::RunResult;
using tool_test::ScratchDir;

RunResult cfgmgr(const ScratchDir& dir, const std::vector<std::string>& args) {
  return tool_test::run("cfgmgr", args, dir.path().string());
}

std::string sample(const std::string& name) {
  return std::string(CANOPEN_SAMPLES_DIR) + "/network/" + name;
}

std::string network(const std::string& name) {
  return tool_test::data_path("network/" + name);
}

struct Concise {
  std::size_t entries = 0;
  std::size_t bytes = 0;
};

// The node's concise DCF by dcf2concise, counted: CiA 302 §6.2 (count, then index u16,
// sub-index u8, size u32, data per entry; little-endian).
Concise concise_of(const ScratchDir& dir, const std::string& dcf) {
  const std::string out = dir / "node.bin";
  auto r = tool_test::run("dcf2concise", {dcf, "-o", out}, dir.path().string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const std::string s = tool_test::slurp(out);
  const auto le = [&s](std::size_t at, int n) {
    std::uint32_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<std::uint8_t>(s.at(at + i));
    return v;
  };
  Concise c;
  c.entries = le(0, 4);
  std::size_t at = 4;
  for (std::size_t i = 0; i < c.entries; ++i) {
    const std::uint32_t size = le(at + 3, 4);
    c.bytes += size;
    at += 7 + size;
  }
  EXPECT_EQ(at, s.size()) << "the stream has data after its last entry";
  return c;
}

Json parse_json(const std::string& path) {
  const std::string text = tool_test::slurp(path);
  JsonParser parser(text);
  auto value = parser.parse();
  EXPECT_TRUE(value && value->is(Json::Kind::Object)) << parser.error() << ": " << text;
  return value ? *value : Json{};
}

std::map<int, const Json*> nodes_of(const Json& report) {
  std::map<int, const Json*> out;
  const Json* nodes = report.get("nodes");
  EXPECT_TRUE(nodes != nullptr && nodes->is(Json::Kind::Array));
  if (nodes == nullptr) return out;
  for (const auto& n : nodes->array) out[static_cast<int>(n.get("node_id")->number)] = &n;
  return out;
}

TEST(Push, HelpDocumentsOptionsExamplesAndExitCodes) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"push", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text :
       {"NETWORK", "--bus", "--json", "--boot-time", "--dry-run", "--only", "--force", "--no-start",
        "--no-save", "--sdo-timeout", "--retries", "10 s", "Examples:", "Exit codes:", "  4  "}) {
    EXPECT_NE(r.out.find(text), std::string::npos) << text;
  }
  EXPECT_NE(cfgmgr(dir, {"--help"}).out.find("push"), std::string::npos);
}

TEST(Push, ConfiguresEveryNodeOfTheSampleNetworkWithTheirConciseDcfWrites) {
  ScratchDir dir;
  const std::string report = dir / "report.json";
  auto r = cfgmgr(dir, {"push", sample("nodelist.cpj"), "--bus", "sim:", "--json", report});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Not on a terminal: one line per event on stderr, as cfgmgr master prints them.
  EXPECT_NE(r.err.find("node 3: booted, configured"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("NMT start-up complete"), std::string::npos) << r.err;

  const Json json = parse_json(report);
  ASSERT_NE(json.get("ok"), nullptr);
  EXPECT_TRUE(json.get("ok")->boolean);
  ASSERT_TRUE(json.get("elapsed_s")->is(Json::Kind::Number));
  EXPECT_GT(json.get("elapsed_s")->number, 0.0);
  const auto nodes = nodes_of(json);
  // samples/network/nodelist.cpj: nodes 2 (io_left), 3 (axis_x), 4 (io_right).
  const std::map<int, std::pair<std::string, std::string>> expected = {
      {2, {"io_left", "io_module_node2.dcf"}},
      {3, {"axis_x", "drive_node3.dcf"}},
      {4, {"io_right", "io_module_node4.dcf"}}};
  ASSERT_EQ(nodes.size(), expected.size()) << tool_test::slurp(report);
  for (const auto& [id, what] : expected) {
    SCOPED_TRACE("node " + std::to_string(id));
    ASSERT_TRUE(nodes.count(id));
    const Json& n = *nodes.at(id);
    const Concise concise = concise_of(dir, sample(what.second));
    EXPECT_EQ(n.get("name")->string, what.first);
    EXPECT_EQ(n.get("result")->string, "configured");
    EXPECT_TRUE(n.get("status")->is(Json::Kind::Null));
    EXPECT_TRUE(n.get("message")->is(Json::Kind::String));
    EXPECT_EQ(n.get("entries")->number, static_cast<double>(concise.entries));
    EXPECT_EQ(n.get("bytes")->number, static_cast<double>(concise.bytes));
    EXPECT_GE(n.get("seconds")->number, 0.0);
    EXPECT_LE(n.get("seconds")->number, json.get("elapsed_s")->number);
  }
  // The table on stdout names every node with its result.
  EXPECT_NE(r.out.find("axis_x"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("configured"), std::string::npos) << r.out;
}

TEST(Push, ForceStillConfiguresEveryNode) {
  ScratchDir dir;
  const std::string report = dir / "report.json";
  // --force: download even when 1020h matches (CiA 302-2 §3.5 c is skipped); --no-save and
  // --no-start change what the master does after the download, not the result.
  auto r = cfgmgr(dir, {"push", sample("nodelist.cpj"), "--bus", "sim:", "--force", "--json",
                        report, "--no-save", "--retries", "3", "--sdo-timeout", "0.2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  for (const auto& [id, n] : nodes_of(json)) {
    EXPECT_EQ(n->get("result")->string, "configured") << id;
  }
  r = cfgmgr(dir, {"push", sample("nodelist.cpj"), "--bus", "sim:", "--force", "--no-start"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

TEST(Push, DryRunListsTheWritesInDownloadOrderWithoutABus) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"push", sample("nodelist.cpj"), "--dry-run", "--only", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("sim:"), std::string::npos) << "no bus is opened: " << r.err;
  EXPECT_NE(r.out.find("node 3 (axis_x): "), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("node 2"), std::string::npos) << r.out;
  const Concise concise = concise_of(dir, sample("drive_node3.dcf"));
  EXPECT_NE(r.out.find(std::to_string(concise.entries) + " writes"), std::string::npos) << r.out;
  // drive_node3.dcf: 1017h = 500 ms (01F4h); 1601h sub 1 maps 6040h sub 0, 16 bits. CiA 301
  // §7.3.5: the mapping's sub 0 goes to 0 before the entries and to 2 after them.
  const auto at = [&r](const std::string& line) { return r.out.find(line); };
  EXPECT_NE(at("  1017h sub 00h = f401\n"), std::string::npos) << r.out;
  const auto zero = at("  1601h sub 00h = 00\n");
  const auto entry = at("  1601h sub 01h = 10004060\n");
  const auto count = at("  1601h sub 00h = 02\n");
  ASSERT_NE(zero, std::string::npos) << r.out;
  ASSERT_NE(entry, std::string::npos) << r.out;
  ASSERT_NE(count, std::string::npos) << r.out;
  EXPECT_LT(zero, entry);
  EXPECT_LT(entry, count);
}

TEST(Push, WrongIdentityOfAMandatoryNodeIsAnErrorWithItsLetterAndExit4) {
  // wrong_identity.cpj's master DCF expects vendor-ID 0x00000BAD at node 2, which has
  // 0x00000ABC: CiA 302-2 §3.4 / Table 1 status D; a mandatory slave (§3.1 f).
  ScratchDir dir;
  const std::string report = dir / "report.json";
  auto r = cfgmgr(dir, {"push", network("wrong_identity.cpj"), "--bus", "sim:", "--json", report});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  const Json json = parse_json(report);
  EXPECT_FALSE(json.get("ok")->boolean);
  const auto nodes = nodes_of(json);
  ASSERT_TRUE(nodes.count(2)) << tool_test::slurp(report);
  EXPECT_EQ(nodes.at(2)->get("result")->string, "error");
  EXPECT_EQ(nodes.at(2)->get("status")->string, "D");
  EXPECT_NE(nodes.at(2)->get("message")->string.find("1F85h"), std::string::npos)
      << nodes.at(2)->get("message")->string;
  EXPECT_NE(r.out.find("error D: "), std::string::npos) << r.out;
}

TEST(Push, AnOptionalNodesFailureIsReportedAndExits0) {
  // wrong_identity.cpj with node 2 optional: 1F81h sub 2 = 05h (slave, boot; bit 3 mandatory
  // clear, CiA 302-2 Table 21). Its status D is reported; start-up goes on (§3.1 f is about
  // mandatory slaves only).
  ScratchDir dir;
  namespace fs = std::filesystem;
  fs::create_directories(dir / "nodes");
  fs::copy_file(network("wrong_identity.cpj"), dir / "net.cpj");
  fs::copy_file(network("nodes/io_node2.dcf"), dir / "nodes/io_node2.dcf");
  std::string master = tool_test::slurp(network("master_wrong_vendor.dcf"));
  const std::string mandatory = "ParameterValue=0x0000000D";
  const auto at = master.find(mandatory, master.find("[1F81sub2]"));
  ASSERT_NE(at, std::string::npos);
  master.replace(at, mandatory.size(), "ParameterValue=0x00000005");
  { std::ofstream(dir / "master_wrong_vendor.dcf", std::ios::binary) << master; }
  const std::string report = dir / "report.json";
  auto r = cfgmgr(dir, {"push", dir / "net.cpj", "--bus", "sim:", "--json", report});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  EXPECT_TRUE(json.get("ok")->boolean);
  const auto nodes = nodes_of(json);
  ASSERT_TRUE(nodes.count(2)) << tool_test::slurp(report);
  EXPECT_EQ(nodes.at(2)->get("result")->string, "error");
  EXPECT_EQ(nodes.at(2)->get("status")->string, "D");
}

TEST(Push, OnlyRestrictsTheNodes) {
  ScratchDir dir;
  const std::string report = dir / "report.json";
  auto r = cfgmgr(
      dir, {"push", sample("nodelist.cpj"), "--bus", "sim:", "--only", "3-4", "--json", report});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  const auto nodes = nodes_of(json);
  EXPECT_EQ(nodes.size(), 2U);
  EXPECT_TRUE(nodes.count(3) && nodes.count(4));
  EXPECT_EQ(r.err.find("node 2: booted"), std::string::npos) << r.err;
}

TEST(Push, BadArgumentsExit2) {
  ScratchDir dir;
  const std::string cpj = sample("nodelist.cpj");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"push", cpj},  // no --bus, no --dry-run
        {"push", cpj, "--bus", "sim:?speed=1"},
        {"push", cpj, "--bus", "sim:", "--only", "0"},
        {"push", cpj, "--bus", "sim:", "--only", "5-3"},
        {"push", cpj, "--bus", "sim:", "--only", "9"},  // not in the network
        {"push", cpj, "--bus", "sim:", "--only", "3,x"},
        {"push", cpj, "--bus", "sim:", "--boot-time", "-1"},
        {"push", cpj, "--bus", "sim:", "--sdo-timeout", "0"},
        {"push", cpj, "--bus", "sim:", "--no-such-option"}}) {
    auto r = cfgmgr(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args.back() << ": " << r.err;
  }
  EXPECT_EQ(cfgmgr(dir, {"push", dir / "absent.cpj", "--bus", "sim:"}).exit_code, 3);
}

}  // namespace
