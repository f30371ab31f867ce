// NmtMaster serving the configuration manager (DSP 302 v3.2.1 §6) over its SDO server
// (MasterOptions::manager): a tool on the bus writes a node's concise DCF into 1F22h and a DCF
// into 1F20h, reads them back, and starts the configuration with 1F25h 'conf'; 1F26h/1F27h have
// one owner. The rig (nmt_master_spec_test_rig.hpp) has the master at node 1 and the tool as
// its SDO client (601h/581h). The objects' values and the persist-hold flow alone, through a
// fake port, are in configuration_store_objects_test.cpp; this file keeps the composition (SDO
// transfers, boots, the driver's part).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cfg/config_manager.hpp"
#include "configuration_store_test_data.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/entry_persister.hpp"
#include "nmt/master/master_host.hpp"
#include "nmt_master_spec_test_rig.hpp"
#include "socket_pair_bus.hpp"

namespace nmt::master_spec {
namespace {

namespace fs = std::filesystem;
using Kind = MasterEvent::Kind;
using store_test::kConf;
using store_test::kNetworkDcf;
using store_test::kNetworkStream;
using store_test::kNode;
using store_test::kStream;
using store_test::NetworkLikeSource;
using store_test::ScratchDir;

// The tool's SDO request COB-ID: 600h + the master's node-ID (CiA 301 pre-defined set).
constexpr std::uint32_t kToolRequestId = 0x600 + kMaster;

SdoTransferOptions by(SdoMode mode) {
  SdoTransferOptions o;
  o.mode = mode;
  return o;
}

std::vector<std::uint8_t> conf_bytes(std::uint32_t value = kConf) {
  return le(value, 4);
}

/// The rig with node 5 (slave.eds) assigned as a booted slave, the manager given, the network
/// started and NMT start-up complete.
struct StoreRig {
  explicit StoreRig(std::shared_ptr<cfg::ConfigManager> m = std::make_shared<cfg::ConfigManager>(),
                    const cfg::DeviceDescription& eds = slave_eds())
      : manager(std::move(m)) {
    rig.options.manager = manager;
    rig.assign(kNode, kSlave | kBoot);
    rig.add_slave(kNode, {}, eds);
  }
  void start() {
    rig.power_on_network();
    ASSERT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));
  }
  /// Writes 'conf' to 1F25h sub `sub` and runs until node 5 has booted after it; the time of
  /// the write, nullopt when the write was refused or no boot followed.
  std::optional<TimePoint> configure(std::uint8_t sub) {
    const TimePoint from = rig.bus.now();
    if (!rig.tool_write(0x1F25, sub, conf_bytes()).ok()) return std::nullopt;
    const bool booted = rig.run_until_event(
        [&](const MasterEvent& e) {
          // Later than `from`: an earlier boot's event may carry that very time.
          return e.kind == Kind::SlaveBooted && e.node_id == kNode && e.at > from;
        },
        10s);
    return booted ? std::optional(from) : std::nullopt;
  }
  /// The first SDO request of the tool at or after `from` (the initiate frame).
  std::optional<CanFrame> first_tool_request(TimePoint from) const {
    for (const auto& s : rig.on_id(kToolRequestId, from)) return s.frame;
    return std::nullopt;
  }
  MasterRig rig;
  std::shared_ptr<cfg::ConfigManager> manager;
};

// §6.2: "Uploading the configuration of a device from a Configuration Tool to the Configuration
// Manager is done by writing the stream to the object 1F22h with the sub-index equal to the
// devices Node-ID" - here by block download (CiA 301 §7.2.4.3.9: initiate ccs 6), and reading
// it back gives the same bytes.
// With the SDO manager on (DSP 302 §7), its write hook saw every write to the master's
// dictionary and read the data as a number of data.size() bytes, DOMAINs of any length too:
// cfg::load_le asserts 1..8 bytes (builds with assertions on stopped here). A concise DCF
// (DOMAIN, §6.2) of 36 bytes by block and by segmented transfer is stored as it is.
TEST(NmtMasterStore, ConciseDcfWriteWithTheSdoManagerOnIsStored) {
  StoreRig s;
  s.rig.options.sdo_manager.enabled = true;
  s.start();
  for (auto mode : {SdoMode::Block, SdoMode::Segmented}) {
    auto written = s.rig.tool_write(0x1F22, kNode, kStream, by(mode));
    ASSERT_TRUE(written.ok()) << written.abort;
    EXPECT_EQ(s.manager->concise(*cfg::NodeId::from(kNode)), kStream);
  }
  // A numeric object of the wrong length is still refused (the dictionary checks the size before
  // the hooks): one byte to 1F80h (UNSIGNED32).
  EXPECT_EQ(s.rig.tool_write(0x1F80, 0, {0x01}).abort, SdoAbort::LengthTooLow);  // 0607 0013
}

TEST(NmtMasterStore, ToolWritesConciseDcfByBlockTransferAndReadsItBack) {
  StoreRig s;
  s.start();
  const TimePoint from = s.rig.bus.now();
  auto written = s.rig.tool_write(0x1F22, kNode, kStream, by(SdoMode::Block));
  ASSERT_TRUE(written.ok()) << written.abort;
  auto initiate = s.first_tool_request(from);
  ASSERT_TRUE(initiate.has_value());
  EXPECT_EQ(initiate->data[0] >> 5U, 6U) << to_candump(*initiate);  // ccs 6: block download
  EXPECT_EQ(s.manager->concise(*cfg::NodeId::from(kNode)), kStream);

  auto block = s.rig.tool_read(0x1F22, kNode, by(SdoMode::Block));
  ASSERT_TRUE(block.ok()) << block.abort;
  EXPECT_EQ(block.data, kStream);
  auto plain = s.rig.tool_read(0x1F22, kNode);
  ASSERT_TRUE(plain.ok()) << plain.abort;
  EXPECT_EQ(plain.data, kStream);
}

// The same by segmented download (CiA 301 §7.2.4.3.3: initiate ccs 1 with e = 0, s = 1 and the
// size 36 = 24h in bytes 4-7).
TEST(NmtMasterStore, ToolWritesConciseDcfBySegmentedTransferAndReadsItBack) {
  StoreRig s;
  s.start();
  const TimePoint from = s.rig.bus.now();
  auto written = s.rig.tool_write(0x1F22, kNode, kStream, by(SdoMode::Segmented));
  ASSERT_TRUE(written.ok()) << written.abort;
  auto initiate = s.first_tool_request(from);
  ASSERT_TRUE(initiate.has_value());
  EXPECT_EQ(to_candump(*initiate), "601#21221F0524000000");

  auto read = s.rig.tool_read(0x1F22, kNode);
  ASSERT_TRUE(read.ok()) << read.abort;
  EXPECT_EQ(read.data, kStream);
}

// §6.4: 'conf' written to 1F25h sub node-ID makes the manager configure that slave: the master
// boots node 5 and downloads the stream written to 1F22h, after which the device has the values.
TEST(NmtMasterStore, ConfToConfigureSlaveBootsTheNodeWithTheStoredValues) {
  StoreRig s;
  s.start();
  ASSERT_TRUE(s.rig.tool_write(0x1F22, kNode, kStream).ok());
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 10U);  // slave.eds default, not configured yet

  const TimePoint from = s.rig.bus.now();
  const auto conf = s.rig.tool_write(0x1F25, kNode, conf_bytes());
  ASSERT_TRUE(conf.ok()) << conf.abort;
  ASSERT_TRUE(s.rig.run_until_event(
      [&](const MasterEvent& e) {
        return e.kind == Kind::SlaveBooted && e.node_id == kNode && e.at >= from;
      },
      10s));
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 0x1234U);
  EXPECT_EQ(s.rig.device_value(kNode, 0x1017, 0), 200U);
  const auto name = s.rig.slave(kNode).node().dictionary().get_bytes(0x2001, 0);
  ASSERT_TRUE(name.has_value());
  EXPECT_EQ(std::string(name->begin(), name->end()), "spindle");
  EXPECT_EQ(s.rig.downloads_of(kNode, 0x2000, 0, from).size(), 1U);
}

// §6.4 "Request re-configuration": the download happens even when the device's 1020h matches
// 1F26h/1F27h (which made NMT start-up skip it, §3.5 c). The stamps are the manager's (one
// owner): the master DCF has none for node 5.
TEST(NmtMasterStore, ConfDownloadsEvenWhenVerifyConfigurationMatches) {
  constexpr std::uint32_t kDate = 0x3A99;
  constexpr std::uint32_t kTime = 0x01234567;
  auto eds = slave_eds();
  set_value(eds, 0x1020, 1, kDate);
  set_value(eds, 0x1020, 2, kTime);
  auto manager = std::make_shared<cfg::ConfigManager>();
  const auto node = *cfg::NodeId::from(kNode);
  ASSERT_TRUE(manager->put_concise(node, kStream));
  ASSERT_TRUE(manager->set_expected_stamp(node, {kDate, kTime}));
  StoreRig s(manager, eds);
  s.start();
  EXPECT_TRUE(s.rig.downloads_of(kNode, 0x2000, 0).empty()) << "1020h matched: no download";
  ASSERT_EQ(s.rig.uploads_of(kNode, 0x1020, 1).size(), 1U);

  const TimePoint from = s.rig.bus.now();
  ASSERT_TRUE(s.rig.tool_write(0x1F25, kNode, conf_bytes()).ok());
  ASSERT_TRUE(s.rig.run_until_event(
      [&](const MasterEvent& e) {
        return e.kind == Kind::SlaveBooted && e.node_id == kNode && e.at >= from;
      },
      10s));
  EXPECT_EQ(s.rig.downloads_of(kNode, 0x2000, 0, from).size(), 1U);
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 0x1234U);
}

// The re-configuration request outlives a failed try: node 5 does not answer when 'conf' comes
// (status B), and the retry (§3.3, an optional slave every retry_interval) still downloads
// although 1020h matches.
TEST(NmtMasterStore, ConfStillDownloadsOnTheRetryAfterAFailedTry) {
  constexpr std::uint32_t kDate = 0x3A99;
  constexpr std::uint32_t kTime = 0x01234567;
  auto eds = slave_eds();
  set_value(eds, 0x1020, 1, kDate);
  set_value(eds, 0x1020, 2, kTime);
  auto manager = std::make_shared<cfg::ConfigManager>();
  const auto node = *cfg::NodeId::from(kNode);
  ASSERT_TRUE(manager->put_concise(node, kStream));
  ASSERT_TRUE(manager->set_expected_stamp(node, {kDate, kTime}));
  StoreRig s(manager, eds);
  s.start();
  ASSERT_TRUE(s.rig.downloads_of(kNode, 0x2000, 0).empty());

  s.rig.set_faults(kNode, absent_device());
  const TimePoint from = s.rig.bus.now();
  ASSERT_TRUE(s.rig.tool_write(0x1F25, kNode, conf_bytes()).ok());
  ASSERT_TRUE(s.rig.run_until_event(
      [&](const MasterEvent& e) {
        return e.kind == Kind::BootError && e.node_id == kNode && e.at >= from &&
               e.error == BootError::B;
      },
      10s));
  s.rig.set_faults(kNode, {});
  ASSERT_TRUE(s.rig.run_until_event(
      [&](const MasterEvent& e) {
        return e.kind == Kind::SlaveBooted && e.node_id == kNode && e.at >= from;
      },
      10s));
  EXPECT_EQ(s.rig.downloads_of(kNode, 0x2000, 0, from).size(), 1U);
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 0x1234U);
}

// §6.4: only 'conf' starts the process ("To avoid accidental access"); another value is refused
// and nothing is sent to the node. 0800 0020h: CiA 301 "data cannot be transferred or stored".
TEST(NmtMasterStore, ConfigureSlaveWithAnotherValueThanConfIsRefused) {
  StoreRig s;
  s.start();
  ASSERT_TRUE(s.rig.tool_write(0x1F22, kNode, kStream).ok());
  const TimePoint from = s.rig.bus.now();
  for (std::uint32_t value : {0x666E6F64U, 0x636F6E66U, 0U}) {  // near, byte-swapped, zero
    const auto code = s.rig.tool_write_u(0x1F25, kNode, value, 4);
    EXPECT_TRUE(code == SdoAbort::CannotStoreOrTransfer || code == SdoAbort::General)
        << hex_text(value) << ": " << code;
  }
  s.rig.run_for(1s);
  EXPECT_TRUE(s.rig.requests_to(kNode, from).empty());
}

// §6.4 sub 80h: "Request re-configuration for all Nodes" - every slave with a stored
// configuration is booted and configured.
TEST(NmtMasterStore, ConfToSub80hConfiguresEverySlaveWithAConfiguration) {
  StoreRig s;
  s.rig.add_slave(2);
  s.start();
  ASSERT_TRUE(s.rig.tool_write(0x1F22, kNode, kStream).ok());
  ASSERT_TRUE(s.rig.tool_write(0x1F22, 2, kStream).ok());
  const TimePoint from = s.rig.bus.now();
  ASSERT_TRUE(s.rig.tool_write(0x1F25, 0x80, conf_bytes()).ok());
  s.rig.run_for(3s);
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 0x1234U);
  EXPECT_EQ(s.rig.device_value(2, 0x2000, 0), 0x1234U);
  EXPECT_EQ(s.rig.downloads_of(2, 0x2000, 0, from).size(), 1U);
}

// The writes persist in the store directory: a manager opened again on the
// directory has what the tool wrote over the bus.
TEST(NmtMasterStore, WritesOverSdoPersistInTheStoreDirectory) {
  ScratchDir dir;
  auto opened = cfg::ConfigManager::open(dir.str());
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  StoreRig s(std::make_shared<cfg::ConfigManager>(std::move(opened).value()));
  s.start();
  ASSERT_TRUE(s.rig.tool_write(0x1F22, kNode, kStream).ok());
  ASSERT_EQ(s.rig.tool_write_u(0x1F26, kNode, 0x3A99, 4), SdoAbort::None);

  auto again = cfg::ConfigManager::open(dir.str());
  ASSERT_TRUE(again.ok()) << again.error().message;
  const auto node = *cfg::NodeId::from(kNode);
  EXPECT_EQ(again.value().concise(node), kStream);
  EXPECT_EQ(again.value().expected_stamp(node).days, 0x3A99U);
}

/// The rig with a store directory whose entries the test persists itself (the driver's part:
/// cfg::ConfigManager::persist, then NmtMaster::entry_persisted).
struct DurableStoreRig {
  DurableStoreRig() : manager(open_manager(dir.str())), s(manager) {
    s.rig.persist_entries = false;
    s.start();
  }
  static std::shared_ptr<cfg::ConfigManager> open_manager(const std::string& path) {
    auto opened = cfg::ConfigManager::open(path);
    EXPECT_TRUE(opened.ok()) << opened.error().message;
    return std::make_shared<cfg::ConfigManager>(std::move(opened).value());
  }
  /// The master's SDO responses to the tool (580h + its node-ID) at or after `from`.
  std::vector<CanFrame> responses(TimePoint from) const {
    std::vector<CanFrame> out;
    for (const auto& seen : s.rig.on_id(0x580 + kMaster, from)) out.push_back(seen.frame);
    return out;
  }
  /// The PersistEntry of node 5 the master reported last.
  MasterEvent::Persist requested() const {
    const auto asked = s.rig.events_of(Kind::PersistEntry, kNode);
    EXPECT_FALSE(asked.empty());
    return asked.empty() ? MasterEvent::Persist{} : *asked.back().persist;
  }
  void complete(std::uint64_t ticket, const cfg::Status& result) {
    s.rig.call([&](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
      m.entry_persisted(ticket, result, now, out);
    });
  }
  ScratchDir dir;
  std::shared_ptr<cfg::ConfigManager> manager;
  StoreRig s;
};

// No disk I/O inside on_frame: a 1F22h download to a master with a store directory
// is reported as PersistEntry; the response to its last segment (CiA 301 §7.2.4.3.6: scs 1,
// toggle of the request; the sixth segment of 36 bytes has t = 1: 30h) leaves only after the
// driver made the entry durable and said so, and the manager has the value from then on.
TEST(NmtMasterStore, ConciseDcfDownloadIsConfirmedOnlyOnceTheEntryIsDurable) {
  DurableStoreRig d;
  const auto node = *cfg::NodeId::from(kNode);
  const TimePoint from = d.s.rig.bus.now();
  const auto id = d.s.rig.tool_begin_write(0x1F22, kNode, kStream, by(SdoMode::Segmented));
  ASSERT_TRUE(d.s.rig.run_until_kind(Kind::PersistEntry, 1s, kNode));
  d.s.rig.run_for(200ms);  // time enough for the confirmation, were it not held
  // 36 bytes: the initiate and segments 1-5 are answered, segment 6 (the last) is not.
  ASSERT_EQ(kStream.size(), 36U);
  ASSERT_EQ(d.responses(from).size(), 6U);
  EXPECT_FALSE(d.s.rig.tool_result(id).has_value());
  EXPECT_FALSE(d.manager->concise(node).has_value());
  const fs::path file = fs::path(d.dir.str()) / "1F22-05";
  EXPECT_FALSE(fs::exists(file));

  const auto asked = d.requested();
  ASSERT_TRUE(asked.update);
  EXPECT_EQ(asked.update->index, 0x1F22);
  EXPECT_EQ(asked.update->node, node);
  const cfg::Status done = d.manager->persist(*asked.update);
  ASSERT_TRUE(done.ok()) << done.error().message;
  EXPECT_TRUE(fs::exists(file));
  d.s.rig.run_for(10ms);
  EXPECT_EQ(d.responses(from).size(), 6U);  // durable, but the master was not told yet
  const TimePoint told = d.s.rig.bus.now();
  d.complete(asked.ticket, done);
  d.s.rig.run_for(10ms);
  const auto confirmation = d.responses(told);
  ASSERT_EQ(confirmation.size(), 1U);
  EXPECT_EQ(confirmation[0].data[0], 0x30);
  const auto result = d.s.rig.tool_result(id);
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->abort, SdoAbort::None);
  EXPECT_EQ(d.manager->concise(node), kStream);
}

// A persist that failed aborts the download with 0800 0020h ("data cannot be transferred or
// stored to the application", CiA 301 §7.2.4.3.17, as the manager answers a store it cannot
// write), here an expedited 1F26h write; the manager keeps its value, and a second completion
// of the same ticket sends nothing.
TEST(NmtMasterStore, FailedPersistAbortsTheDownloadWith08000020) {
  DurableStoreRig d;
  const auto node = *cfg::NodeId::from(kNode);
  const TimePoint from = d.s.rig.bus.now();
  const auto id = d.s.rig.tool_begin_write(0x1F26, kNode, le(0x3A99, 4));
  ASSERT_TRUE(d.s.rig.run_until_kind(Kind::PersistEntry, 1s, kNode));
  d.s.rig.run_for(200ms);
  EXPECT_TRUE(d.responses(from).empty());
  const auto asked = d.requested();
  d.complete(asked.ticket, cfg::Status{cfg::Error{"disk full", cfg::ErrorCategory::Io}});
  d.s.rig.run_for(10ms);
  // Abort frame: 80h, 1F26h sub 05h, code 0800 0020h (little-endian).
  const auto answers = d.responses(from);
  ASSERT_EQ(answers.size(), 1U);
  const std::vector<std::uint8_t> abort(answers[0].data.begin(), answers[0].data.begin() + 8);
  EXPECT_EQ(abort, (std::vector<std::uint8_t>{0x80, 0x26, 0x1F, 0x05, 0x20, 0x00, 0x00, 0x08}));
  const auto result = d.s.rig.tool_result(id);
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->abort, SdoAbort::CannotStoreOrTransfer);
  EXPECT_EQ(d.manager->expected_stamp(node), cfg::ConfigurationStamp{});
  d.complete(asked.ticket, cfg::Status{});
  d.s.rig.run_for(10ms);
  EXPECT_EQ(d.responses(from).size(), 1U);
  EXPECT_EQ(d.manager->expected_stamp(node), cfg::ConfigurationStamp{});
}

// nmt_master.hpp: a write through dictionary() with an output of the master is persisted the
// same way: its PersistEntry goes into that output, and the manager has the value once the
// driver completed it.
TEST(NmtMasterStore, WriteThroughTheDictionaryIsPersistedByTheDriverToo) {
  DurableStoreRig d;
  const auto node = *cfg::NodeId::from(kNode);
  d.s.rig.call([&](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    EXPECT_EQ(m.dictionary().write(0x1F22, kNode, kStream, now, out), SdoAbort::None);
  });
  EXPECT_FALSE(d.manager->concise(node).has_value());
  d.s.rig.run_for(1s);
  const auto asked = d.requested();
  ASSERT_TRUE(asked.update);
  ASSERT_TRUE(d.manager->persist(*asked.update).ok());
  EXPECT_FALSE(d.manager->concise(node).has_value());
  d.complete(asked.ticket, cfg::Status{});
  EXPECT_EQ(d.manager->concise(node), kStream);
  auto again = cfg::ConfigManager::open(d.dir.str());
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(again.value().concise(node), kStream);
}

// --- "stored, else the network" (nmt_master.hpp) -------------------------------------------

struct NetworkStoreRig : StoreRig {
  NetworkStoreRig() { rig.options.configurations = std::make_shared<NetworkLikeSource>(); }
};

std::vector<std::uint8_t> bytes_of(const std::string& text) {
  return {text.begin(), text.end()};
}

// DSP 302 §6.2: 1F22h sub node-ID is the concise DCF the manager configures the node with; with
// nothing stored that is the network's (the source's), by segmented and by block upload.
TEST(NmtMasterStore, UnstoredNodeReadsTheNetworksConciseDcfBySegmentedAndBlockUpload) {
  NetworkStoreRig s;
  s.start();
  auto segmented = s.rig.tool_read(0x1F22, kNode, by(SdoMode::Segmented));
  ASSERT_TRUE(segmented.ok()) << segmented.abort;
  EXPECT_EQ(segmented.data, kNetworkStream);
  auto block = s.rig.tool_read(0x1F22, kNode, by(SdoMode::Block));
  ASSERT_TRUE(block.ok()) << block.abort;
  EXPECT_EQ(block.data, kNetworkStream);
  // §6.2 application hint 2: a node neither stored nor in the network: the count-0 stream.
  EXPECT_EQ(s.rig.tool_read(0x1F22, 9).data, (std::vector<std::uint8_t>{0, 0, 0, 0}));
}

// A stored configuration takes the place of the network's (DSP 302 §6: the manager downloads
// what 1F22h holds): 1F22h reads it, 1F20h no longer reads the network's DCF, 'conf' downloads
// it; removing it (the count-0 stream, §6.2 hint 1) gives the node back to the network.
TEST(NmtMasterStore, StoredConciseDcfTakesThePlaceOfTheNetworksUntilRemoved) {
  NetworkStoreRig s;
  s.start();
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 0x5678U);  // start-up: the network's
  ASSERT_TRUE(s.rig.tool_write(0x1F22, kNode, kStream).ok());
  EXPECT_EQ(s.rig.tool_read(0x1F22, kNode).data, kStream);
  EXPECT_EQ(s.rig.tool_read(0x1F20, kNode).abort, SdoAbort::NoDataAvailable);

  ASSERT_TRUE(s.configure(kNode).has_value());
  EXPECT_EQ(s.rig.device_value(kNode, 0x2000, 0), 0x1234U);
  EXPECT_EQ(s.rig.device_value(kNode, 0x1017, 0), 200U);

  ASSERT_TRUE(s.rig.tool_write(0x1F22, kNode, {0, 0, 0, 0}).ok());
  EXPECT_EQ(s.rig.tool_read(0x1F22, kNode).data, kNetworkStream);
  EXPECT_EQ(s.rig.tool_read(0x1F20, kNode).data, bytes_of(kNetworkDcf));
}

// DSP 302 §6.4: 'conf' re-configures a node; one with nothing stored gets the network's
// configuration downloaded again (by sub node-ID and by sub 80h, "all nodes").
TEST(NmtMasterStore, ConfDownloadsTheNetworksConfigurationOfAnUnstoredNode) {
  NetworkStoreRig s;
  s.start();
  for (const std::uint8_t sub : {kNode, cfg::kConfigureAllNodes}) {
    const auto from = s.configure(sub);
    ASSERT_TRUE(from.has_value()) << int{sub};
    EXPECT_EQ(s.rig.downloads_of(kNode, 0x2000, 0, *from).size(), 1U) << int{sub};
    EXPECT_EQ(s.rig.downloads_of(kNode, 0x1017, 0, *from).size(), 1U) << int{sub};
  }
  // Neither stored nor in the network: still 0800 0024h (§6.4).
  EXPECT_EQ(s.rig.tool_write_u(0x1F25, 9, kConf, 4), SdoAbort::NoDataAvailable);
}

// --- the driver's duties (nmt/master/master_host.hpp)
// ---------------------------------------------

/// A store directory whose entry writes call `on_write` when the data is written (before the
/// rename that makes it the entry), and the rig on it; the rig's MasterHost writes the entries.
struct HostedStoreRig {
  explicit HostedStoreRig(std::function<void()> on_write)
      : manager(open_manager(dir.str(), std::move(on_write))), s(manager) {
    s.start();
  }
  static std::shared_ptr<cfg::ConfigManager> open_manager(const std::string& path,
                                                          std::function<void()> on_write) {
    cfg::StoreWriteHooks hooks;
    hooks.on_step = [on_write = std::move(on_write)](cfg::StoreWriteHooks::Step step, std::size_t) {
      if (step == cfg::StoreWriteHooks::Step::Wrote && on_write) on_write();
    };
    auto opened = cfg::ConfigManager::open(path, hooks);
    EXPECT_TRUE(opened.ok()) << opened.error().message;
    return std::make_shared<cfg::ConfigManager>(std::move(opened).value());
  }
  /// The master's SDO responses to the tool (580h + its node-ID) at or after `from`.
  std::vector<CanFrame> responses(TimePoint from) const {
    std::vector<CanFrame> out;
    for (const auto& seen : s.rig.on_id(0x580 + kMaster, from)) out.push_back(seen.frame);
    return out;
  }
  ScratchDir dir;
  std::shared_ptr<cfg::ConfigManager> manager;
  StoreRig s;
};

/// A writer that keeps the entries until the test writes them.
struct HeldWriter final : MasterHost::Writer {
  void write(MasterEvent::Persist entry) override { entries.push_back(std::move(entry)); }
  std::vector<MasterEvent::Persist> entries;
};

// On the simulated bus the host writes the entry at once, after the master's call: when the
// data reaches the disk the tool has no answer yet; the confirmation of the expedited 1F26h
// write (CiA 301 §7.2.4.3.3: 60h) is queued right after, and the manager has the stamp
// (DSP 302 §6.6).
TEST(MasterHost, OnSimTheConfirmationFollowsTheWriteOfTheEntry) {
  std::optional<std::size_t> answered_when_written;
  HostedStoreRig* rig = nullptr;
  TimePoint from{};
  HostedStoreRig d([&] {
    if (rig != nullptr) answered_when_written = rig->responses(from).size();
  });
  rig = &d;
  from = d.s.rig.bus.now();
  const auto id = d.s.rig.tool_begin_write(0x1F26, kNode, le(0x3A99, 4));
  d.s.rig.run_for(100ms);
  ASSERT_TRUE(answered_when_written.has_value());
  EXPECT_EQ(*answered_when_written, 0U);
  const auto answers = d.responses(from);
  ASSERT_EQ(answers.size(), 1U);
  EXPECT_EQ(answers[0].data[0], 0x60);
  const auto asked = d.s.rig.events_of(Kind::PersistEntry, kNode);
  ASSERT_EQ(asked.size(), 1U);
  // Queued in the call that reported the entry (no simulated time passes for the write), it is
  // on the bus 734 us later in this deterministic run: its turn and its bits at 500 kbit/s.
  EXPECT_EQ(d.s.rig.on_id(0x580 + kMaster, from).front().at - asked.front().at, Duration{734});
  const auto result = d.s.rig.tool_result(id);
  ASSERT_TRUE(result.has_value());
  EXPECT_EQ(result->abort, SdoAbort::None);
  EXPECT_EQ(d.manager->expected_stamp(*cfg::NodeId::from(kNode)).days, 0x3A99U);
}

// The other way of the same duty on the simulated bus: a writer that holds the entry. The
// download stays unconfirmed for as long (200 ms here) and the manager without the value; once
// the entry is written and the host's completion runs, the confirmation (60h) leaves.
TEST(MasterHost, AStoreWriteIsHeldUntilItsWriterCompletesIt) {
  HostedStoreRig d({});
  HeldWriter writer;
  d.s.rig.host->set_writer(&writer);
  const auto node = *cfg::NodeId::from(kNode);
  const TimePoint from = d.s.rig.bus.now();
  const auto id = d.s.rig.tool_begin_write(0x1F26, kNode, le(0x3A99, 4));
  d.s.rig.run_for(200ms);
  ASSERT_EQ(writer.entries.size(), 1U);
  EXPECT_TRUE(d.responses(from).empty());
  EXPECT_FALSE(d.s.rig.tool_result(id).has_value());
  EXPECT_EQ(d.manager->expected_stamp(node), cfg::ConfigurationStamp{});
  const cfg::Status written = d.s.rig.host->write(writer.entries.front());
  ASSERT_TRUE(written.ok()) << written.error().message;
  const TimePoint told = d.s.rig.bus.now();
  d.s.rig.call(d.s.rig.host->completion(writer.entries.front().ticket, written));
  d.s.rig.run_for(10ms);
  const auto answers = d.responses(told);
  ASSERT_EQ(answers.size(), 1U);
  EXPECT_EQ(answers[0].data[0], 0x60);
  EXPECT_EQ(d.manager->expected_stamp(node).days, 0x3A99U);
}

// No disk I/O inside on_frame, on a real loop: the driver's MasterHost writes the entry on a
// worker thread (nmt::EntryPersister, its writer). While the write is held (a store hook that
// waits: the slow disk, a wrapper in this test), the loop keeps serving frames: a boot-up that
// arrives meanwhile is reported (CiA 302-2 §4, boot-up handler). The SDO confirmation of the 1F26h
// write (DSP 302 §6.6) leaves only after the write ended (CiA 301 §7.2.4.3.3: 60h).
TEST(NmtMasterStore, TheLoopKeepsServingFramesWhileAWorkerPersistsAnEntry) {
  ScratchDir dir;
  std::atomic<bool> writing{false};
  std::atomic<bool> release{false};
  cfg::StoreWriteHooks hooks;
  hooks.on_step = [&](cfg::StoreWriteHooks::Step step, std::size_t) {
    if (step != cfg::StoreWriteHooks::Step::Wrote) return;
    writing = true;
    const auto end = std::chrono::steady_clock::now() + 10s;  // bounded: no hang when broken
    while (!release && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(1ms);
  };
  auto opened = cfg::ConfigManager::open(dir.str(), hooks);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  MasterOptions options;
  options.manager = std::make_shared<cfg::ConfigManager>(std::move(opened).value());
  auto created = NmtMaster::create(cfg::DeviceDescription{}, kMaster, options);
  ASSERT_TRUE(created.ok()) << created.error().message;
  NmtMaster master = std::move(created).value();
  SocketPairBus bus;
  bus.keep_sent = true;
  BusEventLoop loop(bus);
  EngineRef<NmtMaster> ref(master);
  loop.add(ref);
  std::vector<MasterEvent> events;
  const std::string confirmation = "581#60261F0200000000";
  auto sent = [&bus](const std::string& candump) {
    return std::any_of(bus.sent_frames.begin(), bus.sent_frames.end(),
                       [&](const CanFrame& f) { return to_candump(f) == candump; });
  };
  auto booted_9 = [&events] {
    return std::any_of(events.begin(), events.end(), [](const MasterEvent& e) {
      return e.kind == Kind::BootUp && e.node_id == 9;
    });
  };
  // Runs the loop in 10 ms steps until `done`, 5 s at most.
  auto run_until = [&loop](const std::function<bool()>& done) {
    for (int i = 0; i < 500 && !done(); ++i) {
      if (!loop.run_for(10ms).ok()) return false;
    }
    return done();
  };
  {
    MasterHost host(master, [&ref](const MasterHost::Call& call) { ref.apply(call); });
    EntryPersister persister(ref, host);
    ref.set_event_handler([&](const MasterEvent& e, TimePoint) {
      events.push_back(e);
      host.on_event(e);
    });
    ref.apply([](NmtMaster& m, TimePoint now, auto& out) { m.start(now, out); });
    bus.inject("601#23261F0201000000");  // 1F26h sub 2 = 1, expedited
    ASSERT_TRUE(run_until([&] { return writing.load(); }));
    bus.inject("709#00");  // node 9 boots while the disk works
    EXPECT_TRUE(run_until(booted_9));
    EXPECT_FALSE(release.load());
    EXPECT_FALSE(sent(confirmation));
    release = true;
    EXPECT_TRUE(run_until([&] { return sent(confirmation); }));
  }
  EXPECT_EQ(options.manager->expected_stamp(*cfg::NodeId::from(2)).days, 1U);
}

}  // namespace
}  // namespace nmt::master_spec
