// The SDO manager in NmtMaster (DSP 302 §7) on the simulated bus: SRDs register after the
// Dynamic SDO Request (6E0h), ask for connections with 1F00h over their channel to the manager,
// give them back with 1F01h, and lose them with their error control. Values in the assertions
// are the bit layouts of DSP 302 §7.2.3 (1F10h, 1F00h/1F01h, 1F02h, 1F03h) and the choices the
// top of nmt/nmt_master.hpp documents (the pool 680h.. of a DCF without 1F02h, the scan from
// 127 down, guarding of an SRD without heartbeat values).
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
    rig.options.sdo_manager = true;
    rig.options.sdo_manager_scan_timeout = 20ms;
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
    srd.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
      return c.download(index, 0, master_spec::le(value, 4), now, out);
    });
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

TEST_F(SdoManagerTest, RegistrationScansFrom127DownAndEnablesTheClientEntryNamedIn1F10h) {
  add_srd(120);
  start_network();
  const auto from = rig.bus.now();
  // §7.2.3: xxxx0001h, xxxx = the client entry for the channel to the manager.
  ASSERT_TRUE(register_srd(120, 0x12810001));
  // §7.2.4 guideline 2: the scan starts at 127; 127..121 are silent.
  std::vector<std::uint8_t> scanned;
  for (const auto& s : rig.seen) {
    if (s.at < from || s.frame.id < 0x600 || s.frame.id > 0x67F) continue;
    if (master_spec::is_upload_initiate(s.frame) && master_spec::addresses(s.frame, 0x1F10, 0)) {
      scanned.push_back(static_cast<std::uint8_t>(s.frame.id - 0x600));
    }
  }
  ASSERT_FALSE(scanned.empty());
  EXPECT_EQ(scanned.front(), 127);
  EXPECT_EQ(scanned.back(), 120);
  EXPECT_TRUE(std::is_sorted(scanned.rbegin(), scanned.rend()));
  // The pool of a DCF without 1F02h begins at 680h: request 680h, response 681h; sub 3 = the
  // manager (CiA 301 client entry: node-ID of the server).
  EXPECT_EQ(at(120, 0x1281, 1), 0x680U);
  EXPECT_EQ(at(120, 0x1281, 2), 0x681U);
  EXPECT_EQ(at(120, 0x1281, 3), kMasterId);
  // §7.2.3: Rq indication reset, Cnxn state 1, the index kept.
  EXPECT_EQ(at(120, 0x1F10, 0), 0x12810002U);
  // 1F02h entries in use have bit 30 set; 1F03h sub 1 = client offset 01h, client 78h (120),
  // server offset 01h (1201h), server 01h.
  EXPECT_EQ(rig.tool_read_u(0x1F02, 1), kInUse | 0x680);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 2), kInUse | 0x681);
  EXPECT_EQ(rig.tool_read_u(0x1F03, 1), 0x01780101U);
  const auto srds = rig.engine().registered_srds();
  ASSERT_EQ(srds.size(), 1U);
  EXPECT_EQ(srds[0].node, 120);
  EXPECT_EQ(srds[0].client_index, 0x1281);
  const auto rows = rig.engine().sdo_connections();
  ASSERT_EQ(rows.size(), 1U);
  EXPECT_TRUE(rows[0].to_manager);
  EXPECT_EQ(rows[0].server_index, 0x1201);
}

TEST_F(SdoManagerTest, RequestGetsTheFreeDefaultSdoOfTheSlaveWithoutWritingToIt) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  const auto from = rig.bus.now();
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 2)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, 120));
  // §7.1: the default SDO of S needs no write to S.
  EXPECT_TRUE(rig.all_downloads(2, from).empty());
  EXPECT_EQ(at(120, 0x1282, 1), 0x602U);
  EXPECT_EQ(at(120, 0x1282, 2), 0x582U);
  EXPECT_EQ(at(120, 0x1282, 3), 2U);
  // §7.2.3: Cnxn state 3 with the index.
  EXPECT_EQ(at(120, 0x1F10, 0), 0x12820006U);
  // 1F03h sub 2: client offset 02h, client 78h, server offset 00h (default), server 02h.
  EXPECT_EQ(rig.tool_read_u(0x1F03, 2), 0x02780002U);
}

TEST_F(SdoManagerTest, SecondSrdForTheSameSlaveGetsAnAdditionalServerChannel) {
  add_srd(120);
  add_srd(110);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  ASSERT_TRUE(register_srd(110, 0x12810001));
  EXPECT_EQ(at(110, 0x1281, 1), 0x682U);  // the next two pool entries
  ASSERT_EQ(srd_write(110, 0x1281, 0x1F00, request_word(0x1282, 110, 2)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, 110));
  // §7.1: 1201h of S, written with two pool COB-IDs and the SRD as its client.
  EXPECT_EQ(at(2, 0x1201, 1), 0x684U);
  EXPECT_EQ(at(2, 0x1201, 2), 0x685U);
  EXPECT_EQ(at(2, 0x1201, 3), 110U);
  EXPECT_EQ(at(110, 0x1282, 1), 0x684U);
  EXPECT_EQ(at(110, 0x1282, 2), 0x685U);
  EXPECT_EQ(at(110, 0x1282, 3), 2U);
  EXPECT_EQ(at(110, 0x1F10, 0), 0x12820006U);
  // 1F03h: client offset 02h, client 6Eh (110), server offset 01h (1201h), server 02h.
  EXPECT_EQ(rig.tool_read_u(0x1F03, 4), 0x026E0102U);
}

TEST_F(SdoManagerTest, NoFreeServerChannelOnTheSlaveIsReportedIn1F10hWithError03h) {
  add_srd(120);
  add_srd(110);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 3));
  ASSERT_TRUE(register_srd(110, 0x12810001));
  // Slave 3 has no 1201h: the write succeeds (the manager started), 1F10h says why not.
  ASSERT_EQ(srd_write(110, 0x1281, 0x1F00, request_word(0x1282, 110, 3)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionRefused, 110));
  // §7.2.3: Cnxn state 0, error code 03h ("No more free server SDO entries on slave S").
  EXPECT_EQ(at(110, 0x1F10, 0), 0x12820300U);
  EXPECT_EQ(rig.events_of(Kind::SdoConnectionRefused, 110).back().connection_error, 0x03);
  EXPECT_EQ(at(110, 0x1282, 1) & kInvalid, kInvalid);
  // The pool entries it would have taken stay free.
  EXPECT_EQ(rig.tool_read_u(0x1F02, 5), 0x684U);
}

TEST_F(SdoManagerTest, SilentSlaveIsReportedWithError04h) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 50)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionRefused, 120));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x12820400U);  // §7.2.3 error 04h: slave S not available
}

TEST_F(SdoManagerTest, ReleaseWithIndex0ReleasesEveryConnectionToTheSlaveOnBothSides) {
  add_srd(120);
  add_srd(110);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));
  // §7.2.3: index 0 releases all connections of the SRD to the slave.
  ASSERT_EQ(srd_write(110, 0x1281, 0x1F01, request_word(0, 110, 2)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionReleased, 110));
  EXPECT_EQ(at(110, 0x1282, 1), kInvalid | 0x684);
  EXPECT_EQ(at(110, 0x1282, 2), kInvalid | 0x685);
  EXPECT_EQ(at(2, 0x1201, 1), kInvalid | 0x684);
  EXPECT_EQ(at(2, 0x1201, 2), kInvalid | 0x685);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 5), 0x684U);  // bit 30 cleared
  EXPECT_EQ(rig.tool_read_u(0x1F03, 4), 0U);
  // The SRD's channel to the manager and 120's connection stay.
  EXPECT_EQ(at(110, 0x1281, 1), 0x682U);
  EXPECT_EQ(rig.engine().sdo_connections().size(), 3U);
}

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
  rig.run_for(5s);
  // S's server entry is invalid again, the pool entries are free, 110 is gone from the tables.
  EXPECT_EQ(at(2, 0x1201, 1) & kInvalid, kInvalid);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 3), 0x682U);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 5), 0x684U);
  for (const auto& row : rig.engine().sdo_connections()) EXPECT_NE(row.srd, 110);
  ASSERT_EQ(rig.engine().registered_srds().size(), 1U);
  EXPECT_EQ(rig.engine().registered_srds()[0].node, 120);
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

TEST_F(SdoManagerTest, RequestFromAnUnregisteredNodeIsAbortedWith060A0023) {
  add_srd(120);
  start_network();
  // §7.2.3: "If the Manager refuses the request ... abort code 060A 0023h".
  EXPECT_EQ(rig.tool_write_u(0x1F00, 0, request_word(0x1282, 100, 2), 4),
            SdoAbort::ResourceNotAvailable);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  // Registered, but the SRD field is not the node of the channel it writes on.
  EXPECT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 100, 2)),
            SdoAbort::ResourceNotAvailable);
  // "The requested Node-ID must not be 0."
  EXPECT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 0)),
            SdoAbort::ResourceNotAvailable);
}

TEST_F(SdoManagerTest, ManagerObjectsKeepTheirAccessTypes) {
  start_network();
  // §7.2.3: 1F00h/1F01h wo, 1F03h ro.
  EXPECT_EQ(rig.tool_read(0x1F00, 0).abort, SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(rig.tool_read(0x1F01, 0).abort, SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(rig.tool_write_u(0x1F03, 1, 0x01780101, 4), SdoAbort::WriteOfReadOnly);
  EXPECT_EQ(rig.tool_read_u(0x1F03, 0), 254U);
  EXPECT_EQ(rig.tool_read_u(0x1F06, 0), 254U);
  // 1F02h: bit 30 belongs to the manager.
  EXPECT_EQ(rig.tool_write_u(0x1F02, 1, kInUse | 0x690, 4), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(rig.tool_write_u(0x1F02, 1, 0x690, 4), SdoAbort::None);
}

TEST_F(SdoManagerTest, PoolIsNotWritableWhileConnectionsUseIt) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  EXPECT_EQ(rig.tool_write_u(0x1F02, 10, 0x6F0, 4), SdoAbort::DeviceState);
}

TEST_F(SdoManagerTest, AllDefaultSdosAreGrantedWithCnxnState2) {
  add_srd(120);
  start_network();
  // §7.2.3: 00000003h asks for all default SDOs; Cnxn state 2 grants them.
  ASSERT_TRUE(register_srd(120, 0x00000003));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x00000004U);
  EXPECT_TRUE(rig.engine().sdo_connections().empty());
  ASSERT_EQ(rig.engine().registered_srds().size(), 1U);
  EXPECT_TRUE(rig.engine().registered_srds()[0].all_default_sdos);
}

TEST_F(SdoManagerTest, DeregistrationReleasesEverythingAndTheChannelToTheManagerLast) {
  add_srd(120);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  // §7.2.3: slave node-ID 0 releases all connections and de-registers.
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F01, request_word(0, 120, 0)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SrdDeregistered, 120));
  EXPECT_EQ(at(120, 0x1282, 1), kInvalid | 0x602);
  EXPECT_EQ(at(120, 0x1281, 1), kInvalid | 0x680);
  const auto released = rig.events_of(Kind::SdoConnectionReleased, 120);
  ASSERT_EQ(released.size(), 2U);
  EXPECT_FALSE(released[0].connection->to_manager);
  EXPECT_TRUE(released[1].connection->to_manager);
  EXPECT_TRUE(rig.engine().registered_srds().empty());
  EXPECT_EQ(rig.tool_read_u(0x1F03, 1), 0U);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 1), 0x680U);
}

TEST_F(SdoManagerTest, SlaveFailureIsReportedIn1F11hToAnSrdThatAskedForErrorControl) {
  add_srd(120);
  rig.add_slave(5);  // not in 1F81h: nobody watches it until the SRD asks
  start_network();
  // §7.2.3: xxxx0009h asks for error control of the slaves (Req EC).
  ASSERT_TRUE(register_srd(120, 0x12810009));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x1281000AU);  // Req EC kept: supported
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 5)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, 120));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x1282000EU);
  rig.unplug(5);
  ASSERT_TRUE(wait_for(Kind::SlaveFailedReported, 120, 10s));
  // §7.2.3 1F11h: reason 00h, slave node-ID 05h; then the client entry is cleared.
  EXPECT_EQ(at(120, 0x1F11, 0), 0x0005U);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionReleased, 120, 5s));
  EXPECT_EQ(at(120, 0x1282, 1) & kInvalid, kInvalid);
}

// §7.1: "The SDO Manager manages all SDO connections in the network": a default SDO it gave to
// an SRD is the SRD's. The master's own transfers to that slave (application and boot) wait
// until it is released (choice, nmt/nmt_master.hpp): two clients on one channel would collide.
TEST_F(SdoManagerTest, MasterTransfersToASlaveWaitWhileAnSrdHoldsItsDefaultSdo) {
  add_srd(120);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  const auto from = rig.bus.now();
  rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.sdo_upload(master_spec::id(2), 0x1000, 0, now, out);
  });
  rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.boot_slave(master_spec::id(2), now, out);
  });
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
  EXPECT_FALSE(rig.requests_to(2, released).empty());
}

TEST_F(SdoManagerTest, MasterTransfersWaitWhileAnSrdOwnsAllDefaultSdos) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x00000003));  // §7.2.3: all default SDOs, Cnxn 2
  const auto from = rig.bus.now();
  rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.sdo_upload(master_spec::id(3), 0x1000, 0, now, out);
  });
  rig.run_for(2s);
  EXPECT_TRUE(rig.requests_to(3, from).empty());
  // §7.2.2: the SRD gives them back only by ending its error control (de-registered).
  rig.unplug(120);
  ASSERT_TRUE(wait_for(Kind::SrdLost, 120, 5s));
  ASSERT_TRUE(wait_for(Kind::SdoFinished, 3, 2s));
  EXPECT_TRUE(rig.events_of(Kind::SdoFinished, 3).front().sdo->ok());
}

// Jobs run one at a time, but a scan (126 silent node-IDs x the scan timeout) lets a request
// that came meanwhile go before its next read (choice, nmt/nmt_master.hpp).
TEST_F(SdoManagerTest, RequestIsServedBetweenTheReadsOfAScanNotAfterIt) {
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  // A 6E0h nobody else answers: the scan reads 127..2 (about 2.4 s at 20 ms each).
  rig.send_foreign("6E0#");
  rig.run_for(100ms);
  const auto asked = rig.bus.now();
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 2)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, 120, 5s));
  const auto established = rig.events_of(Kind::SdoConnectionEstablished, 120).front().at;
  EXPECT_LT(established - asked, 300ms);
  // The scan goes on afterwards, down to node 3 (2's default SDO is now held: skipped).
  rig.run_for(4s);
  bool scanned_3_after = false;
  for (const auto& s : rig.requests_to(3, established)) {
    if (master_spec::is_upload_initiate(s.frame) && master_spec::addresses(s.frame, 0x1F10, 0)) {
      scanned_3_after = true;
    }
  }
  EXPECT_TRUE(scanned_3_after);
}

// CiA 301: a slave's additional server entries (1201h..) are not kept over a reset; the manager
// releases the connections on them when the slave boots up (choice, nmt/nmt_master.hpp).
TEST_F(SdoManagerTest, SlaveBootUpReleasesTheConnectionsOnItsAdditionalServerEntries) {
  add_srd(120);
  add_srd(110);
  start_network();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));  // 2's default SDO
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));  // 2's 1201h, pool subs 5/6
  ASSERT_EQ(rig.tool_read_u(0x1F03, 4), 0x026E0102U);
  const auto from = rig.bus.now();
  rig.power_on(2);  // boot-up 702#00
  ASSERT_TRUE(wait_for(Kind::SdoConnectionReleased, 110, 5s));
  const auto released = rig.events_of(Kind::SdoConnectionReleased, 110).front();
  EXPECT_EQ(released.connection->server, 2);
  EXPECT_EQ(released.connection->server_index, 0x1201);
  // The SRD's client entry is invalidated (§7.2.3: it observes a release in 1280h..12FFh);
  // nothing is written to S, which lost the entry itself.
  EXPECT_EQ(at(110, 0x1282, 1), kInvalid | 0x684);
  EXPECT_EQ(at(110, 0x1282, 2), kInvalid | 0x685);
  EXPECT_TRUE(rig.downloads_of(2, 0x1201, 1, from).empty());
  EXPECT_EQ(rig.tool_read_u(0x1F03, 4), 0U);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 5), 0x684U);
  EXPECT_EQ(rig.tool_read_u(0x1F02, 6), 0x685U);
  // The connection on 2's default SDO (fixed COB-IDs) stays.
  EXPECT_EQ(rig.tool_read_u(0x1F03, 2), 0x02780002U);
  EXPECT_EQ(at(120, 0x1282, 1), 0x602U);
}

// The manager's own server channels 1201h.. are opened and closed by it; an SDO write from a
// tool is refused with 0800 0021 (CiA 301: "because of local control"; choice,
// nmt/nmt_master.hpp) and changes nothing.
TEST_F(SdoManagerTest, ToolWritesToTheManagersServerChannelsAreRefusedWith08000021) {
  add_srd(120);
  start_network();
  EXPECT_EQ(rig.tool_write_u(0x1202, 1, 0x6F0, 4), SdoAbort::LocalControl);
  EXPECT_EQ(rig.tool_write_u(0x1202, 3, 100, 1), SdoAbort::LocalControl);
  EXPECT_EQ(rig.tool_read_u(0x1202, 1), kInvalid);
  EXPECT_EQ(rig.tool_read_u(0x1202, 3), 0U);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  // The channel in use (1201h, 680h/681h) is not closed by a tool either, and still serves.
  EXPECT_EQ(rig.tool_write_u(0x1201, 1, kInvalid | 0x680, 4), SdoAbort::LocalControl);
  EXPECT_EQ(rig.tool_read_u(0x1201, 1), 0x680U);
  EXPECT_EQ(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 2)), SdoAbort::None);
}

/// Two flying masters: the standby one ignores 6E0h and refuses 1F00h with 0800 0022.
TEST(SdoManagerFlying, StandbyMasterIgnoresTheDynamicSdoRequest) {
  SimBus bus{500'000};
  MasterOptions options;
  options.sdo_manager = true;
  options.sdo_manager_scan_timeout = 20ms;
  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<NmtMaster>>> masters;
  std::vector<std::pair<std::uint8_t, MasterEvent>> events;
  for (std::uint8_t node : {std::uint8_t{10}, std::uint8_t{11}}) {
    auto created = NmtMaster::create(master_spec::master_dcf(), master_spec::id(node), options);
    ASSERT_TRUE(created.ok());
    auto slot = std::make_unique<SimEngineNode<NmtMaster>>(std::move(created).value());
    auto& dict = slot->engine().dictionary();
    using Startup = cfg::NmtStartup;
    ASSERT_EQ(dict.write(0x1F80, 0, master_spec::le(Startup::kMaster | Startup::kFlyingMaster, 4),
                         TimePoint{0}),
              SdoAbort::None);
    ASSERT_EQ(dict.write(0x1F90, 3, master_spec::le(node == 10 ? 0 : 2, 2), TimePoint{0}),
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
  ASSERT_EQ(masters[10]->engine().active_master(), master_spec::id(10));
  ASSERT_EQ(masters[11]->engine().startup_state(), StartupState::Standby);
  // An SRD at 120 asks; only the active master scans and registers it.
  auto srd = SimulatedDevice::create(master_spec::slave_eds(), 120).value();
  SimEngineNode<SimulatedDevice> srd_node(std::move(srd));
  auto& dict = srd_node.engine().node().dictionary();
  dict.insert(entry(0x1F10, 0, cfg::DataType::Unsigned32, 0x12810001));
  add_sdo_record(dict, 0x1281);
  bus.attach(srd_node);
  srd_node.apply(
      [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output&) { d.power_on(now); });
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

// Memory a peer can make the master use (nmt_master.hpp): 1F00h requests wait in the manager's
// queue; beyond MasterOptions::sdo_manager_max_queued_requests a request is refused with
// 0504 0005 (CiA 301 "Out of memory"), and once the queue has room requests are taken again.
TEST_F(SdoManagerTest, RequestsBeyondTheQueueBoundAreRefusedOutOfMemory) {
  rig.options.sdo_manager_max_queued_requests = 1;
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  // Over the default SDO the SRD field is believed: two requests back to back, the second while
  // the first still runs.
  ASSERT_EQ(rig.tool_write_u(0x1F00, 0, request_word(0x1282, 120, 2), 4), SdoAbort::None);
  EXPECT_EQ(rig.tool_write_u(0x1F00, 0, request_word(0x1280, 120, 3), 4), SdoAbort::OutOfMemory);
  ASSERT_TRUE(wait_for(Kind::SdoConnectionEstablished, 120));
  const auto rows = rig.engine().sdo_connections();
  EXPECT_EQ(std::count_if(rows.begin(), rows.end(), [](const auto& c) { return !c.to_manager; }),
            1);
  // The queue is empty again: the refused request goes through now.
  ASSERT_EQ(rig.tool_write_u(0x1F00, 0, request_word(0x1280, 120, 3), 4), SdoAbort::None);
  // Rows: the SRD's channel to the manager and its two connections.
  EXPECT_TRUE(rig.bus.run_until([&] { return rig.engine().sdo_connections().size() == 3U; },
                                rig.bus.now() + 10s));
}

// DSP 302 §7.2.3 error 01h "No SDO channel free": registrations are bounded by
// MasterOptions::sdo_manager_channels; an SRD refused for it registers once an SRD gave its
// channel back (1F01h with slave 0, §7.2.3).
TEST_F(SdoManagerTest, SrdRefusedForLackOfAChannelRegistersOnceAnotherDeregisters) {
  rig.options.sdo_manager_channels = 1;
  add_srd(110);
  add_srd(120);
  start_network();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  EXPECT_FALSE(register_srd(110, 0x12810001));
  EXPECT_EQ(at(110, 0x1F10, 0) >> 8U & 0xFFU, 0x01U);  // Cnxn 0, error 01h
  EXPECT_EQ(rig.engine().registered_srds().size(), 1U);
  ASSERT_EQ(srd_write(120, 0x1281, 0x1F01, request_word(0, 120, 0)), SdoAbort::None);
  ASSERT_TRUE(wait_for(Kind::SrdDeregistered, 120));
  // register_srd() would find the refusal reported above: wait for the registration itself.
  rig.slave(110).node().dictionary().set_unsigned(0x1F10, 0, 0x12810001);
  rig.send_foreign("6E0#");
  EXPECT_TRUE(rig.bus.run_until(
      [&] {
        const auto srds = rig.engine().registered_srds();
        return srds.size() == 1 && srds[0].node == 110;
      },
      rig.bus.now() + 10s));
  EXPECT_EQ(at(110, 0x1F10, 0), 0x12810002U);  // Cnxn 1, no error
}

}  // namespace
}  // namespace nmt
