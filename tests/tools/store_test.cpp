// cfgmgr store end to end: on a store directory (--store DIR), and on a running `cfgmgr master
// --store DIR` over UDP multicast inside a private network namespace (as master_test.cpp does),
// where a tool fills the master's 1F22h and starts the configuration with 1F25h 'conf'.
//
// The concise DCFs are written out byte by byte from DSP 302 §6.2 (UNSIGNED32 count, then per
// entry UNSIGNED16 index, UNSIGNED8 sub-index, UNSIGNED32 size, data; little-endian).
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "tool_test_support.hpp"

namespace {

using tool_test::cfgmgr;
using tool_test::Json;
using tool_test::JsonParser;
using tool_test::RunResult;
using tool_test::ScratchDir;
using tool_test::test_network;
using tool_test::write_file;

std::string text_of(const std::vector<std::uint8_t>& bytes) {
  return {bytes.begin(), bytes.end()};
}

// 3 entries: 2000h sub 0 = 34h (UNSIGNED8), 1017h sub 0 = 1000 ms (UNSIGNED16), 2001h sub 0 =
// "left" (4 bytes): 4 + 8 + 9 + 11 = 32 bytes.
const std::vector<std::uint8_t> kConcise = {
    0x03, 0x00, 0x00, 0x00,                                // number of entries
    0x00, 0x20, 0x00, 0x01, 0x00, 0x00, 0x00, 0x34,        // 2000h sub 0, 1 byte
    0x17, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0xE8, 0x03,  // 1017h sub 0, 2 bytes
    0x01, 0x20, 0x00, 0x04, 0x00, 0x00, 0x00, 'l',  'e',  'f', 't'};

// Node 2 of tests/data/network (io_node2.dcf, which has 2000h and 1017h, not 2001h): one entry,
// 1017h sub 0 = 1000 ms, its heartbeat unchanged. The network's own configuration of node 2 has
// two entries (2000h and 1017h).
const std::vector<std::uint8_t> kNode2Concise = {0x01, 0x00, 0x00, 0x00,  // number of entries
                                                 0x17, 0x10, 0x00, 0x02, 0x00,
                                                 0x00, 0x00, 0xE8, 0x03};  // 1017h sub 0, 2 bytes

const Json* node_entry(const Json& root, int node) {
  const Json* nodes = root.get("nodes");
  if (nodes == nullptr) return nullptr;
  for (const auto& n : nodes->array) {
    const Json* id = n.get("node_id");
    if (id != nullptr && static_cast<int>(id->number) == node) return &n;
  }
  return nullptr;
}

TEST(Store, HelpDocumentsActionsExamplesAndExitCodes) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"store", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text :
       {"put NODE FILE", "get NODE", "list", "rm NODE", "configure NODE|all", "--store", "--bus",
        "--master", "--what", "--json", "--output", "1F22h", "Examples:", "Exit codes:", "  3  "}) {
    EXPECT_NE(r.out.find(text), std::string::npos) << text;
  }
  EXPECT_NE(cfgmgr(dir, {"--help"}).out.find("store"), std::string::npos);
}

// §6.2: a concise DCF stored for node 5 reads back unchanged; list shows its size and count;
// the entry is a file of the store directory named after index and node
// (cfg/config_manager.hpp: "1F22-05").
TEST(Store, PutGetListOfAConciseDcfInAStoreDirectory) {
  ScratchDir dir;
  const std::string store = dir / "store";
  write_file(dir / "node5.cdcf", kConcise);
  auto put = cfgmgr(dir, {"store", "put", "5", dir / "node5.cdcf", "--store", store});
  ASSERT_EQ(put.exit_code, 0) << put.err;
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(store) / "1F22-05"));

  auto get = cfgmgr(dir, {"store", "get", "5", "--store", store});
  ASSERT_EQ(get.exit_code, 0) << get.err;
  EXPECT_EQ(get.out, text_of(kConcise));
  auto to_file = cfgmgr(
      dir, {"store", "--store", store, "get", "5", "--what", "concise", "-o", dir / "back.cdcf"});
  ASSERT_EQ(to_file.exit_code, 0) << to_file.err;
  EXPECT_EQ(tool_test::slurp(dir / "back.cdcf"), text_of(kConcise));

  auto list = cfgmgr(dir, {"store", "list", "--json", "--store", store});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  JsonParser parser(list.out);
  auto root = parser.parse();
  ASSERT_TRUE(root.has_value()) << parser.error() << "\n" << list.out;
  const Json* five = node_entry(*root, 5);
  ASSERT_NE(five, nullptr) << list.out;
  EXPECT_EQ(five->get("concise_bytes")->number, 32);
  EXPECT_EQ(five->get("concise_entries")->number, 3);
  EXPECT_TRUE(five->get("dcf_bytes")->is(Json::Kind::Null));
  // The stamp rule of cfg/network.hpp: a day from 1 January 2000 (5844 days after 1 January
  // 1984) to 31 December 2049, a time of day below 86 400 000 ms; never 0/0 (CiA 302-2 §3.5 a).
  const double days = five->get("expected_date")->number;
  EXPECT_GE(days, 5844);
  EXPECT_LT(days, 5844 + 18263);
  EXPECT_LT(five->get("expected_time")->number, 86'400'000);

  auto table = cfgmgr(dir, {"store", "list", "--store", store});
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_NE(table.out.find("node"), std::string::npos) << table.out;
  EXPECT_NE(table.out.find("\n5 "), std::string::npos) << table.out;
}

// §6.1: a DCF goes to 1F20h and reads back as written; rm removes every entry of the node, after
// which 1F20h is "data set empty" (0800 0024h, exit 1) and 1F22h reads as the count-0 stream
// (§6.2 application hint 2).
TEST(Store, PutDcfThenRmLeavesNothing) {
  ScratchDir dir;
  const std::string store = dir / "store";
  const std::string dcf = test_network("nodes/io_node2.dcf");
  auto put = cfgmgr(dir, {"store", "put", "2", dcf, "--store", store});
  ASSERT_EQ(put.exit_code, 0) << put.err;
  auto get = cfgmgr(dir, {"store", "get", "2", "--what", "dcf", "--store", store});
  ASSERT_EQ(get.exit_code, 0) << get.err;
  EXPECT_EQ(get.out, tool_test::slurp(dcf));
  auto listed = cfgmgr(dir, {"store", "list", "--json", "--store", store});
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  JsonParser parser(listed.out);
  auto root = parser.parse();
  ASSERT_TRUE(root.has_value()) << parser.error() << "\n" << listed.out;
  const Json* two = node_entry(*root, 2);
  ASSERT_NE(two, nullptr) << listed.out;
  EXPECT_EQ(two->get("dcf_bytes")->number, static_cast<double>(tool_test::slurp(dcf).size()));
  EXPECT_TRUE(two->get("concise_bytes")->is(Json::Kind::Null));

  auto rm = cfgmgr(dir, {"store", "rm", "2", "--store", store});
  ASSERT_EQ(rm.exit_code, 0) << rm.err;
  auto gone = cfgmgr(dir, {"store", "get", "2", "--what", "dcf", "--store", store});
  EXPECT_EQ(gone.exit_code, 1);
  EXPECT_NE(gone.err.find("0x08000024"), std::string::npos) << gone.err;
  auto concise = cfgmgr(dir, {"store", "get", "2", "--store", store});
  ASSERT_EQ(concise.exit_code, 0) << concise.err;
  EXPECT_EQ(concise.out, std::string(4, '\0'));
  auto list = cfgmgr(dir, {"store", "list", "--json", "--store", store});
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_EQ(list.out, "{\"nodes\": []}\n");
}

// A stream whose count (2) promises more entries than it has is no concise DCF (§6.2): refused
// with exit 1 and nothing stored.
TEST(Store, PutOfAMalformedConciseDcfIsRefused) {
  ScratchDir dir;
  const std::string store = dir / "store";
  std::vector<std::uint8_t> bad(kConcise.begin(), kConcise.begin() + 12);
  bad[0] = 2;
  write_file(dir / "bad.bin", bad);
  auto put = cfgmgr(dir, {"store", "put", "5", dir / "bad.bin", "--store", store});
  EXPECT_EQ(put.exit_code, 1) << put.err;
  auto list = cfgmgr(dir, {"store", "list", "--json", "--store", store});
  EXPECT_EQ(list.out, "{\"nodes\": []}\n");
}

TEST(Store, UsageErrors) {
  ScratchDir dir;
  const std::string store = dir / "store";
  write_file(dir / "node5.cdcf", kConcise);
  write_file(dir / "node5.txt", kConcise);
  // NODE outside 1..127.
  EXPECT_EQ(cfgmgr(dir, {"store", "put", "0", dir / "node5.cdcf", "--store", store}).exit_code, 2);
  EXPECT_EQ(cfgmgr(dir, {"store", "rm", "128", "--store", store}).exit_code, 2);
  // Neither or both of --store and --bus.
  EXPECT_EQ(cfgmgr(dir, {"store", "list"}).exit_code, 2);
  EXPECT_EQ(cfgmgr(dir, {"store", "list", "--store", store, "--bus",
                         test_support::udp_test_url("43141"), "--master", "1"})
                .exit_code,
            2);
  // --bus without --master, and the simulated bus, which has no master.
  EXPECT_EQ(cfgmgr(dir, {"store", "list", "--bus", test_support::udp_test_url("43141")}).exit_code,
            2);
  EXPECT_EQ(cfgmgr(dir, {"store", "list", "--bus", "sim:", "--master", "1"}).exit_code, 2);
  // configure asks a running master.
  EXPECT_EQ(cfgmgr(dir, {"store", "configure", "5", "--store", store}).exit_code, 2);
  // An extension that says nothing, and a --what that is none.
  EXPECT_EQ(cfgmgr(dir, {"store", "put", "5", dir / "node5.txt", "--store", store}).exit_code, 2);
  EXPECT_EQ(cfgmgr(dir, {"store", "get", "5", "--what", "xml", "--store", store}).exit_code, 2);
  // ... while --what makes the .txt a concise DCF.
  EXPECT_EQ(
      cfgmgr(dir, {"store", "put", "5", dir / "node5.txt", "--what", "concise", "--store", store})
          .exit_code,
      0);
}

TEST(Store, AnUnreadableFileIsAnIoError) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"store", "put", "5", dir / "absent.cdcf", "--store", dir / "store"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
}

// --------------------------------------------------------- over UDP, in a namespace ----------

TEST(Store, RemoteMasterOverUdp) {
  tool_test::run_in_private_netns("StoreInNetns.*");
}

// A running master (master.dcf, node 1) serves its store: the tool puts node 2's concise DCF
// into 1F22h over SDO, reads it back, lists it, and 1F25h 'conf' makes the master configure
// node 2 again with that one entry (the network's own configuration of node 2 has two). The
// master wrote the store directory as it went.
TEST(StoreInNetns, PutGetListConfigureOnARunningMaster) {
  REQUIRE_ISOLATED_MULTICAST();
  ScratchDir dir;
  const std::string bus = test_support::udp_test_url("43141");
  const std::string store = dir / "store";
  write_file(dir / "node2.cdcf", kNode2Concise);
  tool_test::SpawnedTool devices(
      "cfgmgr",
      {"simulate", "--bus", bus, "--for", "60", test_network("nodes/io_node2.dcf"),
       test_network("nodes/drive_node3.dcf")},
      dir / "sim.out", dir / "sim.err");
  ASSERT_TRUE(devices.started());
  ASSERT_TRUE(devices.wait_until_simulating()) << devices.output();
  const std::string events = dir / "events.jsonl";
  tool_test::SpawnedTool master("cfgmgr",
                                {"master", test_network("master.dcf"), "--bus", bus,
                                 "--json-events", events, "--store", store},
                                dir / "master.out", dir / "master.err");
  ASSERT_TRUE(master.started());
  auto count = [&events](const std::string& needle) {
    const std::string text = tool_test::slurp(events);
    std::size_t n = 0;
    for (auto at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
    return n;
  };
  auto wait_for = [&count](const std::string& needle, std::size_t times) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    while (std::chrono::steady_clock::now() < end) {
      if (count(needle) >= times) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  };
  ASSERT_TRUE(wait_for("\"startup_complete\"", 1)) << tool_test::slurp(dir / "master.err");

  const std::vector<std::string> remote = {"--bus", bus, "--master", "1"};
  auto with = [&remote](std::vector<std::string> args) {
    args.insert(args.end(), remote.begin(), remote.end());
    return args;
  };
  auto put = cfgmgr(dir, with({"store", "put", "2", dir / "node2.cdcf"}));
  ASSERT_EQ(put.exit_code, 0) << put.err;
  auto get = cfgmgr(dir, with({"store", "get", "2", "-o", dir / "back.cdcf"}));
  ASSERT_EQ(get.exit_code, 0) << get.err;
  EXPECT_EQ(tool_test::slurp(dir / "back.cdcf"), text_of(kNode2Concise));
  auto list = cfgmgr(dir, with({"store", "list", "--json"}));
  ASSERT_EQ(list.exit_code, 0) << list.err;
  JsonParser parser(list.out);
  auto root = parser.parse();
  ASSERT_TRUE(root.has_value()) << parser.error() << "\n" << list.out;
  const Json* two = node_entry(*root, 2);
  ASSERT_NE(two, nullptr) << list.out;
  EXPECT_EQ(two->get("concise_entries")->number, 1);
  // §6.4: nothing stored for node 9: 0800 0024h.
  auto empty = cfgmgr(dir, with({"store", "configure", "9"}));
  EXPECT_EQ(empty.exit_code, 1);
  EXPECT_NE(empty.err.find("0x08000024"), std::string::npos) << empty.err;

  const std::size_t booted_before = count("\"slave_booted\"");
  auto configure = cfgmgr(dir, with({"store", "configure", "2"}));
  ASSERT_EQ(configure.exit_code, 0) << configure.err;
  EXPECT_TRUE(wait_for("\"slave_booted\"", booted_before + 1));
  const auto code = master.stop(SIGTERM, std::chrono::milliseconds(3000));
  const std::string err = tool_test::slurp(dir / "master.err");
  ASSERT_TRUE(code.has_value()) << err;
  EXPECT_EQ(*code, 0) << err;
  EXPECT_NE(err.find("node 2: reconfigured (1 entry, 2 bytes)"), std::string::npos) << err;
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(store) / "1F22-02"));
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(store) / "1F26-02"));
}

}  // namespace
