// cfgmgr master as the network's configuration manager without extra flags (DSP 302 v3.2.1 §6):
// over UDP multicast inside a private network namespace (as master_test.cpp does), `cfgmgr sdo`
// reads the running master's 1F22h/1F20h, which must be exactly what `cfgmgr build` writes and
// the network's DCF files; a concise DCF written to 1F22h and 1F25h 'conf' reconfigure the
// node with exactly that; a restart without --store gives the network's configuration again,
// one with --store the written one.
//
// The written concise DCF is spelled out from DSP 302 §6.2 (UNSIGNED32 count, then per entry
// UNSIGNED16 index, UNSIGNED8 sub-index, UNSIGNED32 size, data; little-endian).
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "tool_test_support.hpp"

namespace {

using tool_test::cfgmgr;
using tool_test::RunResult;
using tool_test::ScratchDir;
using tool_test::test_network;
using tool_test::write_file;

const std::string kBus = test_support::udp_test_url("43157");
// tests/data/network/master.dcf (README.md there): the master is node 1; node 2 is configured
// from the DCF 1F20h sub 2 names (nodes/io_node2.dcf), node 3 from the concise DCF of 1F22h
// sub 3 alone.
constexpr const char* kMaster = "1";

// One entry: 2000h sub 0 = 34h (UNSIGNED8, 1 byte). io_node2.dcf configures 2000h to 12h and
// 1017h to 1000 ms, so a node that got exactly this has 2000h = 34h after a download of 1
// entry, 1 byte.
const std::vector<std::uint8_t> kNode2Concise = {0x01, 0x00, 0x00, 0x00,  // number of entries
                                                 0x00, 0x20, 0x00, 0x01,
                                                 0x00, 0x00, 0x00, 0x34};  // 2000h sub 0, 1 byte

std::string text_of(const std::vector<std::uint8_t>& bytes) {
  return {bytes.begin(), bytes.end()};
}

TEST(MasterConfigManager, HelpSaysTheMasterServes1F20hTo1F27hAndStoreMakesItDurable) {
  ScratchDir dir;
  const auto master = cfgmgr(dir, {"master", "--help"});
  EXPECT_EQ(master.exit_code, 0);
  for (const char* text : {"configuration manager", "1F22h sub N", "nodeN.bin", "1F25h",
                           "held in memory", "--store", "kept in DIR"}) {
    EXPECT_NE(master.out.find(text), std::string::npos) << text;
  }
  const auto push = cfgmgr(dir, {"push", "--help"});
  EXPECT_EQ(push.exit_code, 0);
  EXPECT_NE(push.out.find("configuration manager"), std::string::npos);
}

TEST(MasterConfigManager, EndToEndOverUdp) {
  tool_test::run_in_private_netns("MasterConfigManagerInNetns.*");
}

/// Nodes 2 and 3 of master.dcf simulated by `cfgmgr simulate`; a master started and stopped.
class MasterConfigManagerInNetns : public ::testing::Test {
 protected:
  void SetUp() override {
    REQUIRE_ISOLATED_MULTICAST();
    devices_ = std::make_unique<tool_test::SpawnedTool>(
        "cfgmgr",
        std::vector<std::string>{"simulate", "--bus", kBus, "--for", "120",
                                 test_network("nodes/io_node2.dcf"),
                                 test_network("nodes/drive_node3.dcf")},
        dir_ / "sim.out", dir_ / "sim.err");
    ASSERT_TRUE(devices_->started());
    ASSERT_TRUE(devices_->wait_until_simulating()) << devices_->output();
  }

  /// Starts `cfgmgr master NETWORK` (of tests/data/network) with `extra` and waits for NMT
  /// start-up to complete.
  void start_master(const std::vector<std::string>& extra = {},
                    const std::string& network = "master.dcf") {
    ++runs_;
    events_ = dir_ / ("events" + std::to_string(runs_) + ".jsonl");
    err_ = dir_ / ("master" + std::to_string(runs_) + ".err");
    std::vector<std::string> args{"master", test_network(network), "--bus",
                                  kBus,     "--json-events",       events_};
    args.insert(args.end(), extra.begin(), extra.end());
    master_ = std::make_unique<tool_test::SpawnedTool>("cfgmgr", args, dir_ / "master.out", err_);
    ASSERT_TRUE(master_->started());
    ASSERT_TRUE(wait_for("\"startup_complete\"", 1)) << tool_test::slurp(err_);
  }
  void stop_master() {
    const auto code = master_->stop(SIGTERM, std::chrono::milliseconds(3000));
    ASSERT_TRUE(code.has_value()) << tool_test::slurp(err_);
    EXPECT_EQ(*code, 0) << tool_test::slurp(err_);
  }
  std::size_t count(const std::string& needle) const {
    const std::string text = tool_test::slurp(events_);
    std::size_t n = 0;
    for (auto at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
    return n;
  }
  bool wait_for(const std::string& needle, std::size_t times) const {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(15);
    while (std::chrono::steady_clock::now() < end) {
      if (count(needle) >= times) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

  /// `cfgmgr sdo ARGS --bus kBus`.
  RunResult sdo(std::vector<std::string> args) {
    args.insert(args.begin(), {"sdo", "--bus", kBus});
    return cfgmgr(dir_, args);
  }
  /// The master's OBJECT (INDEX:SUB) as bytes, by segmented upload, or by block with `block`.
  std::string read_master(const std::string& object, bool block = false,
                          const std::string& master = kMaster) {
    const std::string file = dir_ / "read.bin";
    std::vector<std::string> args{"read", master, object, "--type", "domain", "-o", file};
    if (block) args.emplace_back("--block");
    const auto r = sdo(args);
    EXPECT_EQ(r.exit_code, 0) << object << ": " << r.err;
    return tool_test::slurp(file);
  }

  ScratchDir dir_;
  std::unique_ptr<tool_test::SpawnedTool> devices_;
  std::unique_ptr<tool_test::SpawnedTool> master_;
  int runs_ = 0;
  std::string events_;
  std::string err_;
};

// DSP 302 §6.2: 1F22h sub-index = node-ID holds the concise DCF the manager downloads: without
// --store that is what `cfgmgr build` writes as nodeN.bin, byte for byte, by segmented and by
// block upload; §6.1: 1F20h the node's DCF as the file is, and "no data" where there is none.
TEST_F(MasterConfigManagerInNetns, ServesTheNetworksConfigurationWithoutStore) {
  const auto build = cfgmgr(dir_, {"build", test_network("master.dcf"), "-o", dir_ / "out"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  const std::string node2 = tool_test::slurp(dir_ / "out/node2.bin");
  const std::string node3 = tool_test::slurp(dir_ / "out/node3.bin");
  ASSERT_GT(node2.size(), 4U);
  ASSERT_GT(node3.size(), 4U);

  start_master();
  EXPECT_EQ(read_master("1F22:2"), node2);
  EXPECT_EQ(read_master("1F22:2", true), node2);
  EXPECT_EQ(read_master("1F22:3"), node3);
  EXPECT_EQ(read_master("1F22:3", true), node3);
  EXPECT_EQ(read_master("1F20:2", true), tool_test::slurp(test_network("nodes/io_node2.dcf")));
  // Node 3 is given by a concise DCF alone: 0800 0024h (§6.1: "no data available").
  const auto none = sdo({"read", kMaster, "1F20:3", "--type", "domain"});
  EXPECT_EQ(none.exit_code, 1);  // cfgmgr sdo --help: 1, the transfer was aborted
  EXPECT_NE(none.err.find("08000024"), std::string::npos) << none.err;
  // master.dcf gives no 1F26h/1F27h: 0, "do not verify" (CiA 302-2 §3.5 a).
  EXPECT_EQ(sdo({"read", kMaster, "1F26:2", "--type", "u32"}).out, "0 (0x00000000)\n");
  stop_master();
}

// A derived master (a project file without a master DCF) expects in 1F26h/1F27h the stamp of
// each node's configuration (cfg/network.hpp) and, after the download, has node 2's 1020h sub
// 1/2 set to it (CiA 302-2 §3.5 e): the master serves what it compares with 1020h.
TEST_F(MasterConfigManagerInNetns, ServesTheStampsItComparesWith1020h) {
  start_master({}, "heartbeat.cpj");
  const auto build = cfgmgr(dir_, {"build", test_network("heartbeat.cpj"), "-o", dir_ / "out"});
  ASSERT_EQ(build.exit_code, 0) << build.err;
  // The derived master is node 7Fh (the project file names none).
  EXPECT_EQ(read_master("1F22:2", false, "0x7F"), tool_test::slurp(dir_ / "out/node2.bin"));
  for (const char* sub : {"1", "2"}) {
    const auto device = sdo({"read", "2", std::string("1020:") + sub, "--type", "u32"});
    ASSERT_EQ(device.exit_code, 0) << device.err;
    EXPECT_NE(device.out, "0 (0x00000000)\n") << sub;
    const std::string index = std::string(sub) == "1" ? "1F26:2" : "1F27:2";
    EXPECT_EQ(sdo({"read", "0x7F", index, "--type", "u32"}).out, device.out) << index;
  }
  stop_master();
}

// A concise DCF written to 1F22h sub 2 and 1F25h 'conf' (DSP 302 §6.4) reconfigure node 2
// with exactly that one entry; a restart without --store is back to the network's.
TEST_F(MasterConfigManagerInNetns, WrittenConfigurationLastsAsLongAsTheProcessWithoutStore) {
  write_file(dir_ / "node2.cdcf", kNode2Concise);
  start_master();
  const auto network = read_master("1F22:2");
  const auto put =
      sdo({"write", kMaster, "1F22:2", "--type", "domain", "--file", dir_ / "node2.cdcf"});
  ASSERT_EQ(put.exit_code, 0) << put.err;
  EXPECT_EQ(read_master("1F22:2", true), text_of(kNode2Concise));

  const std::size_t booted = count("\"slave_booted\"");
  // 'conf' = 666E 6F63h (§6.4).
  const auto conf = sdo({"write", kMaster, "1F25:2", "0x666E6F63", "--type", "u32"});
  ASSERT_EQ(conf.exit_code, 0) << conf.err;
  ASSERT_TRUE(wait_for("\"slave_booted\"", booted + 1)) << tool_test::slurp(err_);
  EXPECT_EQ(sdo({"read", "2", "2000:0", "--type", "u8"}).out, "52 (0x34)\n");
  stop_master();
  EXPECT_NE(tool_test::slurp(err_).find("node 2: reconfigured (1 entry, 1 byte)"),
            std::string::npos)
      << tool_test::slurp(err_);

  start_master();
  EXPECT_EQ(read_master("1F22:2"), network);
  // Start-up configured node 2 from the network again (io_node2.dcf: 2000h = 12h).
  EXPECT_EQ(sdo({"read", "2", "2000:0", "--type", "u8"}).out, "18 (0x12)\n");
  stop_master();
}

// With --store DIR the written configuration outlives the process; a node with nothing stored
// keeps reading the network's.
TEST_F(MasterConfigManagerInNetns, WrittenConfigurationOutlivesARestartWithStore) {
  write_file(dir_ / "node2.cdcf", kNode2Concise);
  const std::string store = dir_ / "store";
  start_master({"--store", store});
  const auto node3 = read_master("1F22:3");
  const auto put =
      sdo({"write", kMaster, "1F22:2", "--type", "domain", "--file", dir_ / "node2.cdcf"});
  ASSERT_EQ(put.exit_code, 0) << put.err;
  stop_master();

  start_master({"--store", store});
  EXPECT_EQ(read_master("1F22:2", true), text_of(kNode2Concise));
  EXPECT_EQ(read_master("1F22:3"), node3);
  // Start-up downloaded the stored configuration (2000h = 34h, not io_node2.dcf's 12h).
  EXPECT_EQ(sdo({"read", "2", "2000:0", "--type", "u8"}).out, "52 (0x34)\n");
  stop_master();
}

}  // namespace
