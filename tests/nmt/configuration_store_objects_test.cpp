// The configuration manager's objects alone (manager/configuration_store_objects.hpp, DSP 302
// v3.2.1 §6): 1F20h-1F25h served from a cfg::ConfigManager, the one owner of 1F26h/1F27h, and
// the persist-hold flow of a store directory (no disk I/O in the engine: PersistEntry out, the
// SDO confirmation held until entry_persisted). The objects are reached as the master's SDO
// server reaches them, through the dictionary they are installed in (read, write,
// write_download); a fake port stands for the NMT master and records what the process asks of
// it. The composition (SDO transfers, boots after 'conf', the driver on a loop) is tested in
// nmt_master_store_test.cpp.
#include "manager/configuration_store_objects.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/config_manager.hpp"
#include "configuration_store_test_data.hpp"
#include "master/master_support.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace store_test;
using Kind = MasterEvent::Kind;

// What the process asked of the NMT master.
struct FakePort final : ConfigurationStorePort {
  bool is_slave(cfg::NodeId node) const override { return slaves.count(node.value()) != 0; }
  bool boots_slaves() const override { return active; }
  void configure(cfg::NodeId node, TimePoint now, Output& /*out*/) override {
    configured.emplace_back(node.value(), now);
  }
  void complete_download(std::uint64_t ticket, SdoAbort code, Output& /*out*/) override {
    completed.emplace_back(ticket, code);
  }

  std::set<std::uint8_t> slaves{2, kNode};  // 1F81h
  bool active = true;
  std::vector<std::pair<std::uint8_t, TimePoint>> configured;
  std::vector<std::pair<std::uint64_t, SdoAbort>> completed;
};

/// The master's dictionary as far as the process needs it: 1F26h/1F27h (CiA 302-2 §6.6/§6.7,
/// UNSIGNED32 arrays of 127 rw entries, which the master adds), then the process installed.
struct StoreObjects {
  explicit StoreObjects(
      std::shared_ptr<cfg::ConfigManager> m = std::make_shared<cfg::ConfigManager>(),
      std::shared_ptr<const ConfigurationSource> source = nullptr)
      : manager(std::move(m)), objects(dict, port, manager, std::move(source)) {
    for (const std::uint16_t index : {std::uint16_t{0x1F26}, std::uint16_t{0x1F27}}) {
      dict.insert(make_entry(index, 0, "Highest sub-index supported", cfg::DataType::Unsigned8,
                             cfg::AccessType::Const, 127));
      for (unsigned sub = 1; sub <= 127; ++sub) {
        dict.insert(make_entry(index, static_cast<std::uint8_t>(sub), "node",
                               cfg::DataType::Unsigned32, cfg::AccessType::Rw, 0));
      }
    }
    objects.install();
  }
  struct Read {
    SdoAbort abort = SdoAbort::None;
    std::vector<std::uint8_t> data;
  };
  Read read(std::uint16_t index, std::uint8_t sub) {
    Read r;
    r.abort = dict.read(index, sub, r.data, now, out);
    return r;
  }
  std::uint32_t read_u(std::uint16_t index, std::uint8_t sub) {
    const auto r = read(index, sub);
    EXPECT_EQ(r.abort, SdoAbort::None) << cfg::to_string(cfg::ObjectAddress{index, sub});
    return cfg::low_le32(r.data);
  }
  SdoAbort write(std::uint16_t index, std::uint8_t sub, const std::vector<std::uint8_t>& data) {
    return dict.write(index, sub, data, now, out);
  }
  SdoAbort write_u(std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
    return write(index, sub, cfg::le32_bytes(value));
  }
  /// As the master's SDO server writes a download: the verdict says whether it is held.
  WriteVerdict download(std::uint16_t index, std::uint8_t sub,
                        const std::vector<std::uint8_t>& data) {
    return dict.write_download(index, sub, data, now, out);
  }

  LocalDictionary dict;
  FakePort port;
  std::shared_ptr<cfg::ConfigManager> manager;
  ConfigurationStoreObjects objects;
  TimePoint now{std::chrono::milliseconds(100)};
  ConfigurationStoreObjects::Output out;
};

std::shared_ptr<cfg::ConfigManager> open_manager(const std::string& path) {
  auto opened = cfg::ConfigManager::open(path);
  EXPECT_TRUE(opened.ok()) << opened.error().message;
  return std::make_shared<cfg::ConfigManager>(std::move(opened).value());
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<std::uint8_t> bytes_of(const std::string& text) {
  return {text.begin(), text.end()};
}

// §6.2 application hint 2: "If no data has been stored, an SDO Read Request will return a valid
// concise stream" with the number of entries 0 (UNSIGNED32): 00 00 00 00.
TEST(ConfigurationStoreObjects, EmptyConciseDcfReadsAsTheStreamWithCountZero) {
  StoreObjects s;
  auto read = s.read(0x1F22, 9);
  ASSERT_EQ(read.abort, SdoAbort::None);
  EXPECT_EQ(read.data, (std::vector<std::uint8_t>{0x00, 0x00, 0x00, 0x00}));
  // §6.2: sub-index 0 "is equal to the maximum possible Node-ID (127)".
  EXPECT_EQ(s.read_u(0x1F22, 0), 127U);
}

// §6.4: "If no data had been stored, an SDO Write Request to 01h to 7Fh is aborted with the error
// code 0800 0024h ... An SDO Write Request to sub-index 80h returns without error even if there
// is no data stored." 1F25h is write-only: its read is refused (CiA 301 0601 0001h).
TEST(ConfigurationStoreObjects,
     ConfigureSlaveWithNothingStoredAbortsDataSetEmptyExceptForAllNodes) {
  StoreObjects s;
  EXPECT_EQ(s.write_u(0x1F25, kNode, kConf), SdoAbort::NoDataAvailable);
  EXPECT_EQ(s.write_u(0x1F25, 0x80, kConf), SdoAbort::None);
  EXPECT_EQ(s.read(0x1F25, kNode).abort, SdoAbort::ReadOfWriteOnly);
  // §6.4: "Sub-Index 00h NrOfSupportedObjects has the ro value 128".
  EXPECT_EQ(s.read_u(0x1F25, 0), 128U);
  EXPECT_TRUE(s.port.configured.empty());
}

// §6.1: a DCF written to 1F20h sub node-ID reads back unchanged (the manager keeps it
// compressed inside), and 1F21h storage format then reads 0 ("ASCII, not compressed").
TEST(ConfigurationStoreObjects, DcfWrittenTo1F20hReadsBackUnchanged) {
  StoreObjects s;
  const std::string text = read_text(std::string(CANOPEN_TEST_DATA_DIR) + "/master/slave.eds");
  ASSERT_GT(text.size(), 1000U);
  const std::vector<std::uint8_t> bytes(text.begin(), text.end());
  // §6.1: nothing stored: 0800 0024h.
  EXPECT_EQ(s.read(0x1F20, kNode).abort, SdoAbort::NoDataAvailable);
  ASSERT_EQ(s.write(0x1F20, kNode, bytes), SdoAbort::None);
  auto read = s.read(0x1F20, kNode);
  ASSERT_EQ(read.abort, SdoAbort::None);
  EXPECT_EQ(read.data, bytes);
  EXPECT_EQ(s.read_u(0x1F21, kNode), 0U);
}

// One owner of 1F26h/1F27h (nmt_master.hpp): for a node the manager holds nothing for, the
// master DCF's value is read; an SDO write goes to the manager (keeping the other half), and the
// C++ API's value is what SDO reads give.
TEST(ConfigurationStoreObjects, ExpectedConfigurationHasOneOwner) {
  auto manager = std::make_shared<cfg::ConfigManager>();
  StoreObjects s(manager);
  s.dict.set_unsigned(0x1F26, 3, 0x1111);
  s.dict.set_unsigned(0x1F27, 3, 0x2222);
  const auto three = *cfg::NodeId::from(3);
  EXPECT_EQ(s.read_u(0x1F26, 3), 0x1111U);
  EXPECT_EQ(s.read_u(0x1F27, 3), 0x2222U);

  ASSERT_EQ(s.write_u(0x1F26, 3, 0x3333), SdoAbort::None);
  EXPECT_EQ(manager->expected_stamp(three), (cfg::ConfigurationStamp{0x3333, 0x2222}));
  EXPECT_EQ(s.read_u(0x1F27, 3), 0x2222U);

  ASSERT_TRUE(manager->set_expected_stamp(three, {0x4444, 0x5555}));
  EXPECT_EQ(s.read_u(0x1F26, 3), 0x4444U);
  EXPECT_EQ(s.read_u(0x1F27, 3), 0x5555U);
  // The boot's check configuration (CiA 302-2 §3.5 c) compares 1020h with the same owner's.
  EXPECT_EQ(s.objects.expected_configuration(three), (cfg::ConfigurationStamp{0x4444, 0x5555}));
  // §6.3: 1F27h counts ms after midnight; 86 400 000 or more is no time of day.
  EXPECT_EQ(s.write_u(0x1F27, 3, 86'400'000), SdoAbort::ValueRangeExceeded);
}

// A 1F22h stream that is not a concise DCF (count 2, one entry) is refused and not stored.
TEST(ConfigurationStoreObjects, MalformedConciseDcfIsRefused) {
  StoreObjects s;
  std::vector<std::uint8_t> short_stream(kStream.begin(), kStream.begin() + 13);
  short_stream[0] = 2;
  EXPECT_EQ(s.write(0x1F22, kNode, short_stream), SdoAbort::ValueRangeExceeded);
  EXPECT_FALSE(s.manager->concise(*cfg::NodeId::from(kNode)).has_value());
}

// DSP 302 §6.1: 1F20h sub node-ID is the node's DCF, 1F21h its storage format 0 (ASCII); a node
// the network names no DCF for reads 0800 0024h (no data available), one whose DCF cannot be
// read 0800 0020h.
TEST(ConfigurationStoreObjects, UnstoredNodeReadsTheNetworksDcfIn1F20h) {
  StoreObjects s(std::make_shared<cfg::ConfigManager>(), std::make_shared<NetworkLikeSource>());
  auto dcf = s.read(0x1F20, kNode);
  ASSERT_EQ(dcf.abort, SdoAbort::None);
  EXPECT_EQ(dcf.data, bytes_of(kNetworkDcf));
  EXPECT_EQ(s.read_u(0x1F21, kNode), 0U);
  EXPECT_EQ(s.read(0x1F20, 9).abort, SdoAbort::NoDataAvailable);
  EXPECT_EQ(s.read(0x1F21, 9).abort, SdoAbort::NoDataAvailable);
  EXPECT_EQ(s.read(0x1F20, 6).abort, SdoAbort::CannotStoreOrTransfer);
}

// The network's source, counting the DCFs it is asked for (a real one reads each from disk).
class CountingSource final : public ConfigurationSource {
 public:
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    return network_.configuration(node);
  }
  cfg::Result<std::optional<std::string>> dcf(cfg::NodeId node) const override {
    ++dcf_reads;
    return network_.dcf(node);
  }
  mutable int dcf_reads = 0;

 private:
  NetworkLikeSource network_;
};

// An SDO read is answered on the frame path, which must not wait for a disk: the source's DCFs
// are read once, when the objects are installed (one per node-ID 1..127), and 1F20h/1F21h
// (DSP 302 §6.1) are answered from what was read then.
TEST(ConfigurationStoreObjects, ReadsTheSourcesDcfsOnceWhenInstalledNotOnAnSdoRead) {
  auto source = std::make_shared<CountingSource>();
  StoreObjects s(std::make_shared<cfg::ConfigManager>(), source);
  EXPECT_EQ(source->dcf_reads, 127);
  EXPECT_EQ(s.read(0x1F20, kNode).data, bytes_of(kNetworkDcf));
  EXPECT_EQ(s.read(0x1F20, kNode).data, bytes_of(kNetworkDcf));
  EXPECT_EQ(s.read_u(0x1F21, kNode), 0U);
  EXPECT_EQ(s.read(0x1F21, 9).abort, SdoAbort::NoDataAvailable);
  EXPECT_EQ(s.read(0x1F21, 6).abort, SdoAbort::CannotStoreOrTransfer);
  EXPECT_EQ(source->dcf_reads, 127);
}

// CiA 302-2 §3.5 d: the configuration downloaded to a node is the manager's when it stores one
// (DSP 302 §6.2), else the network's (the source), else nothing.
TEST(ConfigurationStoreObjects, ConfigurationIsTheStoredOneElseTheNetworks) {
  StoreObjects s(std::make_shared<cfg::ConfigManager>(), std::make_shared<NetworkLikeSource>());
  const auto node = *cfg::NodeId::from(kNode);
  EXPECT_EQ(s.objects.configuration(node), cfg::decode_concise_dcf(kNetworkStream).value());
  ASSERT_EQ(s.write(0x1F22, kNode, kStream), SdoAbort::None);
  EXPECT_EQ(s.objects.configuration(node), cfg::decode_concise_dcf(kStream).value());
  EXPECT_FALSE(s.objects.configuration(*cfg::NodeId::from(9)).has_value());
}

// §6.4 'conf' to sub node-ID asks the master to configure that slave, to sub 80h every slave
// with a configuration (stored, or the network's: node 5), not node 2, which has none.
TEST(ConfigurationStoreObjects, ConfAsksTheMasterToConfigureTheSlaves) {
  StoreObjects s(std::make_shared<cfg::ConfigManager>(), std::make_shared<NetworkLikeSource>());
  ASSERT_EQ(s.write_u(0x1F25, kNode, kConf), SdoAbort::None);
  ASSERT_EQ(s.port.configured.size(), 1U);
  EXPECT_EQ(s.port.configured[0].first, kNode);
  EXPECT_EQ(s.port.configured[0].second, s.now);
  ASSERT_EQ(s.write_u(0x1F25, 0x80, kConf), SdoAbort::None);
  ASSERT_EQ(s.port.configured.size(), 2U);
  EXPECT_EQ(s.port.configured[1].first, kNode);
}

// As request NMT: only the active master boots slaves, 0800 0022h (CiA 301 "because of the
// present device state") on a standby; a node that is no slave cannot be configured by the
// master (0800 0000h: §3.4 a would end the boot with status A); a write without an output of the
// master's call (a program's own dictionary() write before it runs) has nobody to boot with.
TEST(ConfigurationStoreObjects, ConfIsRefusedWhereTheMasterCannotBoot) {
  StoreObjects s(std::make_shared<cfg::ConfigManager>(), std::make_shared<NetworkLikeSource>());
  s.port.active = false;
  EXPECT_EQ(s.write_u(0x1F25, kNode, kConf), SdoAbort::DeviceState);
  s.port.active = true;
  s.port.slaves.erase(kNode);
  EXPECT_EQ(s.write_u(0x1F25, kNode, kConf), SdoAbort::General);
  s.port.slaves.insert(kNode);
  EXPECT_EQ(s.dict.write(0x1F25, kNode, cfg::le32_bytes(kConf), s.now), SdoAbort::DeviceState);
  EXPECT_TRUE(s.port.configured.empty());
}

// --- the persist-hold flow (no disk I/O inside on_frame) ---------------------------------

// With a store directory, a 1F22h download is reported as PersistEntry (ticket, the entry to
// write) and held (WriteVerdict::hold): nothing is on disk and the manager keeps its old value
// until the driver wrote the entry and called entry_persisted(); then the manager has it and
// the held download is completed without an abort.
TEST(ConfigurationStoreObjects, StoredEntryIsHeldUntilTheDriverPersistedIt) {
  ScratchDir dir;
  StoreObjects s(open_manager(dir.str()));
  const auto node = *cfg::NodeId::from(kNode);
  const auto verdict = s.download(0x1F22, kNode, kStream);
  EXPECT_EQ(verdict.abort, SdoAbort::None);
  ASSERT_TRUE(verdict.held.has_value());
  ASSERT_EQ(s.out.events.size(), 1U);
  const auto& asked = s.out.events[0];
  EXPECT_EQ(asked.kind, Kind::PersistEntry);
  EXPECT_EQ(asked.node_id, node);
  ASSERT_TRUE(asked.persist.has_value());
  EXPECT_EQ(asked.persist->ticket, *verdict.held);
  ASSERT_TRUE(asked.persist->update);
  EXPECT_EQ(asked.persist->update->index, 0x1F22);
  EXPECT_EQ(asked.persist->update->node, node);
  EXPECT_TRUE(s.out.frames.empty());
  EXPECT_FALSE(s.manager->concise(node).has_value());
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::path(dir.str()) / "1F22-05"));
  EXPECT_TRUE(s.port.completed.empty());

  const cfg::Status done = s.manager->persist(*asked.persist->update);
  ASSERT_TRUE(done.ok()) << done.error().message;
  EXPECT_FALSE(s.manager->concise(node).has_value());  // durable, but not told yet
  s.objects.entry_persisted(asked.persist->ticket, done, s.now, s.out);
  ASSERT_EQ(s.port.completed.size(), 1U);
  EXPECT_EQ(s.port.completed[0], std::make_pair(*verdict.held, SdoAbort::None));
  EXPECT_EQ(s.manager->concise(node), kStream);
}

// A failed persist aborts the held download with 0800 0020h ("data cannot be transferred or
// stored to the application", CiA 301 §7.2.4.3.17), here a 1F26h write; the manager keeps its
// value, and a second completion of the same ticket changes nothing.
TEST(ConfigurationStoreObjects, FailedPersistAbortsTheHeldDownloadWith08000020) {
  ScratchDir dir;
  StoreObjects s(open_manager(dir.str()));
  const auto node = *cfg::NodeId::from(kNode);
  const auto verdict = s.download(0x1F26, kNode, cfg::le32_bytes(0x3A99));
  ASSERT_TRUE(verdict.held.has_value());
  ASSERT_EQ(s.out.events.size(), 1U);
  const auto ticket = s.out.events[0].persist->ticket;
  s.objects.entry_persisted(ticket, cfg::Status{cfg::Error{"disk full", cfg::ErrorCategory::Io}},
                            s.now, s.out);
  ASSERT_EQ(s.port.completed.size(), 1U);
  EXPECT_EQ(s.port.completed[0], std::make_pair(ticket, SdoAbort::CannotStoreOrTransfer));
  EXPECT_EQ(s.manager->expected_stamp(node), cfg::ConfigurationStamp{});
  s.objects.entry_persisted(ticket, cfg::Status{}, s.now, s.out);
  EXPECT_EQ(s.port.completed.size(), 1U);
  EXPECT_EQ(s.manager->expected_stamp(node), cfg::ConfigurationStamp{});
}

// Without a store directory the manager takes the value in the call: nothing to persist, no
// hold. With one, a write outside any call of the master (no output to report PersistEntry
// into) is refused with 0800 0022h and stores nothing.
TEST(ConfigurationStoreObjects, OnlyAStoreDirectoryHoldsAndOnlyWithAnOutput) {
  const auto node = *cfg::NodeId::from(kNode);
  StoreObjects memory;
  const auto verdict = memory.download(0x1F22, kNode, kStream);
  EXPECT_EQ(verdict.abort, SdoAbort::None);
  EXPECT_FALSE(verdict.held.has_value());
  EXPECT_TRUE(memory.out.empty());
  EXPECT_EQ(memory.manager->concise(node), kStream);

  ScratchDir dir;
  StoreObjects stored(open_manager(dir.str()));
  EXPECT_EQ(stored.dict.write(0x1F22, kNode, kStream, stored.now), SdoAbort::DeviceState);
  EXPECT_FALSE(stored.manager->concise(node).has_value());
}

}  // namespace
}  // namespace nmt
