// The SDO manager in NmtMaster (DSP 302 §7) on the simulated bus, where the master's parts meet
// the manager engine (its protocol alone is tested through a fake port in
// sdo_manager_engine_test.cpp): the master's error control reports an SRD's loss to it and
// watches what it asks for (guarding of an SRD without heartbeat values, its heartbeat when it
// has one), the master's own transfers wait while the manager gave a default SDO away, and a
// standby flying master keeps its manager inactive. Values in the assertions are the bit
// layouts of DSP 302 §7.2.3 (1F10h, 1F00h/1F01h, 1F02h, 1F03h) and the choices the top of
// nmt/master/nmt_master.hpp documents (the pool 680h.. of a DCF without 1F02h).
//
// Devices: slaves 2 and 3 of tests/data/master/master.dcf from slave.eds; SRDs are slave.eds
// devices at high node-IDs that get 1F10h, 1F11h and client entries 1280h-1282h put into their
// dictionaries (CiA 301 client SDO parameters, bit 31 set: not valid). Slave 2 also gets one
// additional server entry 1201h (not valid), slave 3 none.
#include <gtest/gtest.h>

#include "nmt_master_spec_test_rig.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using namespace cfg::literals;
using master_spec::MasterRig;
using Kind = MasterEvent::Kind;

constexpr std::uint8_t kMasterId = master_spec::kMaster;
constexpr std::uint32_t kInvalid = 0x80000000;
constexpr std::uint32_t kInUse = 0x40000000;  // 1F02h bit 30 (§7.2.3)

DictionaryEntry entry(std::uint16_t index, std::uint8_t sub, cfg::DataType type,
                      std::uint64_t value, cfg::AccessType access = cfg::AccessType::Rw) {
  DictionaryEntry e;
  e.index = index;
  e.sub_index = sub;
  e.name = "test entry";
  e.data_type = static_cast<std::uint16_t>(type);
  e.basic_type = type;
  e.access = access;
  e.bytes = master_spec::le(value, cfg::data_type_info(type).size_bytes);
  return e;
}

/// A CiA 301 SDO parameter record (server 1200h.. or client 1280h..), bit 31 set.
void add_sdo_record(LocalDictionary& dict, std::uint16_t index) {
  dict.insert(entry(index, 0, cfg::DataType::Unsigned8, 3, cfg::AccessType::Const));
  dict.insert(entry(index, 1, cfg::DataType::Unsigned32, kInvalid));
  dict.insert(entry(index, 2, cfg::DataType::Unsigned32, kInvalid));
  dict.insert(entry(index, 3, cfg::DataType::Unsigned8, 0));
}

class SdoManagerTest : public ::testing::Test {
 protected:
  SdoManagerTest() {
    rig.options.sdo_manager.enabled = true;
    rig.options.sdo_manager.scan_timeout = 20ms;
  }

  /// An SRD at `node` with 1F10h, 1F11h and client entries 1280h-1282h.
  SimulatedDevice& add_srd(std::uint8_t node) {
    auto& device = rig.add_slave(node);
    auto& dict = device.node().dictionary();
    dict.insert(entry(0x1F10, 0, cfg::DataType::Unsigned32, 0));
    dict.insert(entry(0x1F11, 0, cfg::DataType::Unsigned16, 0));
    for (std::uint16_t index = 0x1280; index <= 0x1282; ++index) add_sdo_record(dict, index);
    return device;
  }
  /// Slaves 2 (with a free 1201h) and 3 (only its default SDO), the master, start-up done.
  void start_network() {
    rig.add_slave(2);
    add_sdo_record(rig.slave(2).node().dictionary(), 0x1201);
    rig.add_slave(3);
    rig.power_on_network();
    ASSERT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));
  }
  std::uint64_t at(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    return rig.device_value(node, index, sub).value_or(0xDEADBEEF);
  }
  /// The SRD sets 1F10h (§7.2.3) and sends the Dynamic SDO Request (COB-ID 1760 = 6E0h, no
  /// data); true when the manager reported the registration.
  bool register_srd(std::uint8_t node, std::uint32_t request) {
    rig.slave(node).node().dictionary().set_unsigned(0x1F10, 0, request);
    const auto from = rig.events.size();
    rig.send_foreign("6E0#");
    rig.run_until_event(
        [&](const MasterEvent& e) {
          return e.node_id == node &&
                 (e.kind == Kind::SrdRegistered || e.kind == Kind::SrdRegistrationFailed);
        },
        10s);
    for (auto i = from; i < rig.events.size(); ++i) {
      if (rig.events[i].node_id == node && rig.events[i].kind == Kind::SrdRegistered) return true;
    }
    return false;
  }
  /// The SRD's client on its channel to the manager, as the manager wrote it into `client`.
  SdoAbort srd_write(std::uint8_t node, std::uint16_t client, std::uint16_t index,
                     std::uint32_t value) {
    SdoClientConfig config;
    config.request_cob_id = cfg::CobId::from_word(static_cast<std::uint32_t>(at(node, client, 1)));
    config.response_cob_id = cfg::CobId::from_word(static_cast<std::uint32_t>(at(node, client, 2)));
    SimEngineNode<SdoClient> srd(config);
    std::optional<SdoResult> result;
    srd.set_event_handler([&](const SdoResult& r, TimePoint) { result = r; });
    rig.bus.attach(srd);
    test_support::started(srd.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
      return c.download(index, 0, master_spec::le(value, 4), now, out);
    }));
    rig.bus.run_until([&] { return result.has_value(); }, rig.bus.now() + 5s);
    rig.bus.detach(srd);
    return result ? result->abort : SdoAbort::General;
  }
  /// 1F00h/1F01h value (§7.2.3): index << 16 | SRD node-ID << 8 | slave node-ID.
  static std::uint32_t request_word(std::uint16_t index, std::uint8_t srd, std::uint8_t slave) {
    return (std::uint32_t{index} << 16U) | (std::uint32_t{srd} << 8U) | slave;
  }
  bool wait_for(Kind kind, std::uint8_t node, Duration limit = 10s) {
    return rig.run_until_kind(kind, limit, node);
  }
  /// Registers `srd` (client entry 1281h) unless it is, then asks for a connection to `slave`
  /// on its client entry 1282h and waits until it is up.
  void connect(std::uint8_t srd, std::uint8_t slave) {
    const auto srds = rig.engine().registered_srds();
    if (std::none_of(srds.begin(), srds.end(), [&](const auto& s) { return s.node == srd; })) {
      ASSERT_TRUE(register_srd(srd, 0x12810001));
    }
    ASSERT_EQ(srd_write(srd, 0x1281, 0x1F00, request_word(0x1282, srd, slave)), SdoAbort::None);
    ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, srd));
  }

  MasterRig rig;
};

TEST_F(SdoManagerTest, SrdErrorControlLossReleasesItsConnectionsOnBothSides) {
  add_srd(120);
  add_srd(110);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));
  ASSERT_EQ(at(2, 0x1201, 3), 110U);
  rig.unplug(110);
  // Guarding of an SRD without 1016h/1017h/1F81h values: 500 ms x 3 (header).
  ASSERT_TRUE(wait_for(Kind::SrdLost, 110, 5s));
  ASSERT_TRUE(wait_for(Kind::SdoConnectionReleased, 110, 10s));
  // DSP 302 §7.2.1: the SRD's loss is the reason, with the count of its connections (its
  // channel to the manager and the one to node 2).
  const auto lost = rig.events_of(Kind::SrdLost, 110).front();
  EXPECT_EQ(lost.manager_reason.kind, SdoManagerReason::Kind::SrdLost);
  EXPECT_EQ(lost.manager_reason.node, 110_node);
  EXPECT_EQ(lost.released, 2U);
  EXPECT_EQ(rig.events_of(Kind::SdoConnectionReleased, 110).front().manager_reason.kind,
            SdoManagerReason::Kind::SrdLost);
  rig.run_for(5s);
  // S's server entry is invalid again, the pool entries are free, 110 is gone from the tables.
  EXPECT_EQ(at(2, 0x1201, 1) & kInvalid, kInvalid);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 3), 0x682U);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 5), 0x684U);
  for (const auto& row : rig.engine().sdo_connections()) EXPECT_NE(row.srd, 110_node);
  ASSERT_EQ(rig.engine().registered_srds().size(), 1U);
  EXPECT_EQ(rig.engine().registered_srds()[0].node, 120_node);
}

TEST_F(SdoManagerTest, SrdWithHeartbeatIsWatchedByItsHeartbeatNotGuarded) {
  add_srd(120);
  start_network();
  // The SRD produces heartbeats every 100 ms (CiA 301 1017h); the manager reads it at the
  // registration and consumes it with 2 x 100 + 100 ms (header), without guarding RTRs.
  ASSERT_EQ(
      rig.slave(120).node().dictionary().write(0x1017, 0, master_spec::le(100, 2), rig.bus.now()),
      SdoAbort::None);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  const auto registered = rig.bus.now();
  rig.run_for(2s);
  EXPECT_TRUE(rig.events_of(Kind::SrdLost, 120).empty());
  for (const auto& s : rig.on_id(0x700 + 120, registered)) EXPECT_FALSE(s.frame.rtr) << s;
  rig.unplug(120);
  const auto unplugged = rig.bus.now();
  ASSERT_TRUE(wait_for(Kind::SrdLost, 120, 2s));
  const auto lost = rig.events_of(Kind::SrdLost, 120).front().at;
  EXPECT_LE(lost - unplugged, 300ms + 1ms);
}

// §7.1: "The SDO Manager manages all SDO connections in the network": a default SDO it gave to
// an SRD is the SRD's. The master's own transfers to that slave (application and boot) wait
// until it is released (choice, nmt/master/nmt_master.hpp): two clients on one channel would
// collide.
TEST_F(SdoManagerTest, MasterTransfersToASlaveWaitWhileAnSrdHoldsItsDefaultSdo) {
  add_srd(120);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  const auto from = rig.bus.now();
  test_support::started(rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.sdo_upload(2_node, 0x1000, 0, now, out);
  }));
  ASSERT_TRUE(rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
                   return m.boot_slave(2_node, now, out);
                 })
                  .ok());
  rig.run_for(2s);
  EXPECT_TRUE(rig.requests_to(2, from).empty());
  EXPECT_TRUE(rig.events_of(Kind::SdoFinished, 2).empty());
  // Released (§7.2.3 1F01h): both go out on the default SDO and end.
  const auto released = rig.bus.now();
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F01, request_word(0x1282, 120, 2)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionReleased, 120));
  ASSERT_TRUE(wait_for(Kind::SdoFinished, 2, 2s));
  EXPECT_TRUE(rig.events_of(Kind::SdoFinished, 2).front().sdo->ok());
  ASSERT_TRUE(wait_for(Kind::SlaveBooted, 2, 5s));
  // Both went out after the release: the application's 1000h read and the boot's (one try).
  EXPECT_EQ(rig.uploads_of(2, 0x1000, 0, released).size(), 2U);
}

TEST_F(SdoManagerTest, MasterTransfersWaitWhileAnSrdOwnsAllDefaultSdos) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x00000003));  // §7.2.3: all default SDOs, Cnxn 2
  const auto from = rig.bus.now();
  test_support::started(rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.sdo_upload(3_node, 0x1000, 0, now, out);
  }));
  rig.run_for(2s);
  EXPECT_TRUE(rig.requests_to(3, from).empty());
  // §7.2.2: the SRD gives them back only by ending its error control (de-registered).
  rig.unplug(120);
  ASSERT_TRUE(wait_for(Kind::SrdLost, 120, 5s));
  ASSERT_TRUE(wait_for(Kind::SdoFinished, 3, 2s));
  EXPECT_TRUE(rig.events_of(Kind::SdoFinished, 3).front().sdo->ok());
}

// CiA 302-2 §3.3: the boot of a slave "shall run asynchronously to other processes"; DSP 302
// §7.1: the manager checks S before it gives S's default SDO to the SRD. A boot of S that begins
// while the manager's read of S's 1000h is on the bus leaves that read running: the manager gets
// its answer and establishes the connection, and its later jobs (the release) run too.
TEST_F(SdoManagerTest, ABootOfTheSlaveDuringTheManagersProbeLeavesTheProbeRunning) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  const auto from = rig.bus.now();
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 3)), SdoAbort::None);
  // The manager's probe of S, CiA 301 §7.2.4.3.5 initiate upload of 1000h sub 0.
  ASSERT_TRUE(rig.bus.run_until([&] { return !rig.uploads_of(3, 0x1000, 0, from).empty(); },
                                rig.bus.now() + 1s));
  const auto probe = rig.uploads_of(3, 0x1000, 0, from).front();
  ASSERT_TRUE(rig.on_id(0x583, probe.at).empty()) << "answered before the boot began";
  const auto asked = rig.bus.now();
  ASSERT_TRUE(rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
                   return m.boot_slave(3_node, now, out);
                 })
                  .ok());
  ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, 120, 2s));
  // No abort of the probe (CiA 301 §7.2.4.3.17, ccs 4): S answered it; the boot's own read of
  // 1000h waited behind it on S's default SDO.
  for (const auto& s : rig.requests_to(3, asked)) EXPECT_NE(s.frame.data[0], 0x80) << s;
  const auto uploads = rig.uploads_of(3, 0x1000, 0, from);
  ASSERT_EQ(uploads.size(), 2U);
  const auto answers = rig.on_id(0x583, from);
  ASSERT_FALSE(answers.empty());
  EXPECT_EQ(answers.front().text(), "583#4300100091010F00") << "1000h = 000F0191h (slave.eds)";
  EXPECT_LT(answers.front().at, uploads[1].at);
  // §7.1: S's default SDO, given to the SRD's 1282h.
  EXPECT_EQ(at(120, 0x1282, 1), 0x603U);
  EXPECT_EQ(at(120, 0x1282, 2), 0x583U);
  // The boot that began went on: S booted once more, without an error.
  const auto booted = rig.booted(3);
  ASSERT_FALSE(booted.empty());
  EXPECT_GE(booted.back().at, asked);
  EXPECT_TRUE(rig.boot_errors(3).empty());
  // The SRD lets S go (§7.2.2 1F01h): the manager's next job runs.
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F01, request_word(0x1282, 120, 3)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionReleased, 120));
}

/// Two flying masters: the standby one ignores 6E0h and refuses 1F00h with 0800 0022.
TEST(SdoManagerFlying, StandbyMasterIgnoresTheDynamicSdoRequest) {
  SimBus bus{500'000};
  MasterOptions options;
  options.sdo_manager.enabled = true;
  options.sdo_manager.scan_timeout = 20ms;
  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<NmtMaster>>> masters;
  std::vector<std::pair<std::uint8_t, MasterEvent>> events;
  for (std::uint8_t node : {std::uint8_t{10}, std::uint8_t{11}}) {
    auto created = NmtMaster::create(master_spec::master_dcf(), *cfg::NodeId::from(node), options);
    ASSERT_TRUE(created.ok());
    auto slot = std::make_unique<SimEngineNode<NmtMaster>>(std::move(created).value());
    auto& dict = slot->engine().dictionary();
    using Startup = cfg::NmtStartup;
    ASSERT_EQ(dict.write(0x1F80, 0, master_spec::le(Startup::kMaster | Startup::kFlyingMaster, 4),
                         TimePoint{}),
              SdoAbort::None);
    ASSERT_EQ(dict.write(0x1F90, 3, master_spec::le(node == 10 ? 0 : 2, 2), TimePoint{}),
              SdoAbort::None);
    slot->set_event_handler(
        [&events, node](const MasterEvent& e, TimePoint) { events.emplace_back(node, e); });
    bus.attach(*slot);
    masters[node] = std::move(slot);
  }
  for (auto& [node, slot] : masters) {
    slot->apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  }
  bus.run_for(10s);
  ASSERT_EQ(masters[10]->engine().active_master(), 10_node);
  ASSERT_EQ(masters[11]->engine().startup_state(), StartupState::Standby);
  // An SRD at 120 asks; only the active master scans and registers it.
  auto srd = SimulatedDevice::create(master_spec::slave_eds(), 120).value();
  SimEngineNode<SimulatedDevice> srd_node(std::move(srd));
  auto& dict = srd_node.engine().node().dictionary();
  dict.insert(entry(0x1F10, 0, cfg::DataType::Unsigned32, 0x12810001));
  add_sdo_record(dict, 0x1281);
  bus.attach(srd_node);
  srd_node.apply(
      [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
  bus.run_for(1s);
  FunctionNode other;
  bus.attach(other);
  bus.send(other, *from_candump("6E0#"));
  bus.run_for(5s);
  std::size_t registered_by[2] = {0, 0};
  for (const auto& [node, e] : events) {
    if (e.kind == Kind::SrdRegistered) ++registered_by[node - 10];
  }
  EXPECT_EQ(registered_by[0], 1U);
  EXPECT_EQ(registered_by[1], 0U);
  EXPECT_TRUE(masters[11]->engine().registered_srds().empty());
  // The standby master refuses 1F00h (0800 0022), as it refuses request NMT.
  EXPECT_EQ(masters[11]->engine().dictionary().write(
                0x1F00, 0, master_spec::le(0x12820000U | 120U << 8U | 2U, 4), bus.now()),
            SdoAbort::DeviceState);
}

}  // namespace
}  // namespace nmt
