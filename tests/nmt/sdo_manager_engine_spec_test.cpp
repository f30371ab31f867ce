// The SDO manager engine (SdoManagerProcess) against CiA DSP 302 v3.2.1 §7
// (../shared/spec/001_846495643a25878e.txt): the cases of the SDO manager's spec suite that are
// the manager's protocol alone, moved here from sdo_manager_spec_test.cpp with their assertions,
// driven through a fake of the engine's port (sdo_manager_engine_rig.hpp) instead of a master
// on a simulated bus. The cases where the master's parts meet the manager (error control, the
// SRD's own transfers on what it was given, timing, frame loss, a standby flying master) stay
// in sdo_manager_spec_test.cpp.
//
// The scene is that suite's: the manager is node 1 with tests/data/sdo_manager/manager.dcf
// (1F00h, 1F01h and 1F02h = eight free 11-bit COB-IDs 681h-688h and a ninth, 689h, marked not
// valid), its 1016h consumes the SRDs 127, 126 and 124 with 300 ms; node 2 has slave_channels.eds
// (server SDOs 1201h, 1202h, not valid), node 3 slave.eds (its default SDO only); SRDs are
// srd.eds devices. "Writes to a node" are the SDO downloads the engine started to it (all
// expedited, over the default SDO), in order.
#include <gtest/gtest.h>

#include <set>

#include "sdo_manager_engine_rig.hpp"

namespace nmt::engine_test {
namespace {

using master_spec::ClientEntry;
using master_spec::cnxn;
using master_spec::cnxn_of;
using master_spec::error_of;
using master_spec::hex_text;
using master_spec::index_of;
using master_spec::kClientSdo, master_spec::kConnectionState, master_spec::kConnections;
using master_spec::kDefaultOnly, master_spec::kWithChannels, master_spec::kSrd, master_spec::kSrd2,
    master_spec::kSrd3;
using master_spec::kIdBits, master_spec::kNotValid, master_spec::kPoolEntries,
    master_spec::kInvalidPoolId;
using master_spec::kRq, master_spec::kPool, master_spec::kRequestSdo, master_spec::kReleaseSdo;
using master_spec::row_word;
using master_spec::set_value;
using master_spec::state_word;

class SdoManagerEngineSpec : public ::testing::Test, public ManagerEngineRig {
 protected:
  SdoManagerEngineSpec() {
    auto master = LocalDictionary::from_device(device_file("sdo_manager/manager.dcf"),
                                               *cfg::NodeId::from(kManager));
    EXPECT_TRUE(master.ok());
    dict = std::move(master).value();
    for (std::uint8_t node : {kSrd, kSrd2, kSrd3}) port.consumer[node] = 300ms;
  }

  /// Slave 2 (with channels, or `eds2`), slave 3 (default SDO only) and the SRDs.
  void start_network(std::initializer_list<std::uint8_t> srds = {kSrd},
                     const cfg::DeviceDescription& eds2 = slave_channels_eds()) {
    auto d = LocalDictionary::from_device(eds2, *cfg::NodeId::from(kWithChannels));
    ASSERT_TRUE(d.ok());
    port.devices.emplace(kWithChannels, std::move(d).value());
    add_device(kDefaultOnly, "master/slave.eds");
    for (auto node : srds) add_srd(node);
    engine();
  }
  static const cfg::DeviceDescription& slave_channels_eds() {
    return device_file("sdo_manager/slave_channels.eds");
  }
  void set_state(std::uint8_t node, std::uint32_t value) {
    port.devices.at(node).set_unsigned(kConnectionState, 0, value);
  }
  /// §7.2.1: the SRD sets 1F10h and sends 6E0h; the 1F10h value once the manager is done.
  std::uint32_t register_srd(std::uint8_t node,
                             std::uint32_t request = state_word(kClientSdo, 0, kRq)) {
    set_state(node, request);
    EXPECT_TRUE(engine().on_frame(*from_candump(master_spec::kDynamicSdoRequestFrame), now, out));
    run();
    return at(node, kConnectionState, 0);
  }
  void register_ok(std::uint8_t node, std::uint16_t index = kClientSdo) {
    const auto confirmed = register_srd(node, state_word(index, 0, kRq));
    ASSERT_EQ(confirmed, state_word(index, 0, cnxn(1)))
        << "SRD " << int{node} << " 1F10h = " << hex_text(confirmed);
    set_state(node, 0);
  }

  ClientEntry client_entry(std::uint8_t node, std::uint16_t index) {
    return {at(node, index, 1), at(node, index, 2), static_cast<std::uint8_t>(at(node, index, 3))};
  }
  std::optional<std::uint64_t> device_value(std::uint8_t node, std::uint16_t index,
                                            std::uint8_t sub) {
    return port.devices.at(node).get_unsigned(index, sub);
  }

  /// 1F00h/1F01h written by SRD `node` over its channel to the manager: the abort the engine's
  /// server channel answered with (None: the download response).
  SdoAbort srd_write_manager(std::uint8_t node, std::uint16_t object, std::uint32_t value) {
    if (!client_entry(node, kClientSdo).valid()) {
      ADD_FAILURE() << "SRD " << int{node} << " has no valid channel";
      return SdoAbort::General;
    }
    const auto answer = srd_write(node, kClientSdo, object, value);
    if (!answer) return SdoAbort::General;
    if (answer->data[0] == 0x60) return SdoAbort::None;
    EXPECT_EQ(answer->data[0], 0x80);
    return static_cast<SdoAbort>(cfg::load_le(std::span(answer->data).subspan(4, 4), 4));
  }
  /// The SRD's upload of (object, sub 0) over its channel to the manager: the frame answering.
  CanFrame srd_read_manager(std::uint8_t node, std::uint16_t object) {
    CanFrame request = CanFrame::make(
        at(node, kClientSdo, 1) & kIdBits,
        std::vector<std::uint8_t>{0x40, static_cast<std::uint8_t>(object & 0xFF),
                                  static_cast<std::uint8_t>(object >> 8U), 0, 0, 0, 0, 0},
        (at(node, kClientSdo, 1) & master_spec::k29Bit) != 0);
    const auto before = out.frames.size();
    EXPECT_TRUE(engine().on_frame(request, now, out));
    EXPECT_EQ(out.frames.size(), before + 1);
    return out.frames.back();
  }
  /// §7.2.2: a request on client entry `index`; the 1F10h value then (reset to 0 after).
  std::uint32_t request(std::uint8_t node, std::uint8_t slave, std::uint16_t index) {
    EXPECT_EQ(at(node, kConnectionState, 0), 0U);
    const SdoAbort code = srd_write_manager(node, kRequestSdo, request_word(index, node, slave));
    EXPECT_EQ(code, SdoAbort::None) << "1F00h write: " << code;
    run();
    const auto state = at(node, kConnectionState, 0);
    set_state(node, 0);
    return state;
  }
  void connect_ok(std::uint8_t node, std::uint8_t slave, std::uint16_t index) {
    const auto state = request(node, slave, index);
    EXPECT_EQ(cnxn_of(state), 3U) << "1F10h = " << hex_text(state);
    EXPECT_EQ(index_of(state), index) << "1F10h = " << hex_text(state);
    EXPECT_EQ(error_of(state), 0U) << "1F10h = " << hex_text(state);
  }
  void refused(std::uint8_t node, std::uint8_t slave, std::uint16_t index, std::uint8_t error) {
    const auto before = in_use(pool());
    const auto state = request(node, slave, index);
    EXPECT_EQ(cnxn_of(state), 0U) << "1F10h = " << hex_text(state);
    EXPECT_EQ(error_of(state), error) << "1F10h = " << hex_text(state);
    EXPECT_FALSE(client_entry(node, index).valid());
    EXPECT_EQ(in_use(pool()), before) << "no COB-ID stays allocated";
  }
  void release(std::uint8_t node, std::uint32_t word) {
    EXPECT_EQ(srd_write_manager(node, kReleaseSdo, word), SdoAbort::None);
    run();
  }

  /// Where the accesses from now on begin.
  std::size_t mark() const { return port.accesses.size(); }
  std::vector<Access> writes_to(std::uint8_t node, std::size_t from = 0) const {
    std::vector<Access> found;
    for (auto i = from; i < port.accesses.size(); ++i) {
      const auto& a = port.accesses[i];
      if (a.node == node && !a.upload) found.push_back(a);
    }
    return found;
  }
  std::vector<std::size_t> uploads_of(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                      std::size_t from = 0) const {
    std::vector<std::size_t> found;
    for (auto i = from; i < port.accesses.size(); ++i) {
      if (port.accesses[i] == read(node, index, sub)) found.push_back(i);
    }
    return found;
  }
  static std::ptrdiff_t position_of(const std::vector<Access>& writes, std::uint16_t index,
                                    std::uint8_t sub,
                                    std::optional<std::uint32_t> value = std::nullopt) {
    for (std::size_t i = 0; i < writes.size(); ++i) {
      if (writes[i].index == index && writes[i].sub == sub &&
          (!value || writes[i].value == *value)) {
        return static_cast<std::ptrdiff_t>(i);
      }
    }
    return -1;
  }

  std::vector<std::uint32_t> pool() {
    std::vector<std::uint32_t> found;
    for (unsigned sub = 1; sub <= own(kPool, 0); ++sub) {
      found.push_back(own(kPool, static_cast<std::uint8_t>(sub)));
    }
    return found;
  }
  static std::size_t in_use(const std::vector<std::uint32_t>& pool) {
    return static_cast<std::size_t>(
        std::count_if(pool.begin(), pool.end(), [](std::uint32_t e) { return (e & kInUse) != 0; }));
  }
  static void expect_pool_entries(const std::vector<std::uint32_t>& pool, const ClientEntry& entry,
                                  bool in_use) {
    for (auto id : {entry.request, entry.response}) {
      const auto e = std::find_if(pool.begin(), pool.end(),
                                  [&](std::uint32_t p) { return (p & kIdBits) == (id & kIdBits); });
      ASSERT_NE(e, pool.end()) << hex_text(id) << " is not from 1F02h";
      EXPECT_EQ(*e & (kNotValid | kInUse), in_use ? kInUse : 0U) << "1F02h entry " << hex_text(*e);
    }
  }
  std::vector<std::uint32_t> rows() {
    std::vector<std::uint32_t> found;
    for (unsigned sub = 1; sub <= own(kConnections, 0); ++sub) {
      const auto row = own(kConnections, static_cast<std::uint8_t>(sub));
      if ((row & 0xFF) != 0 && ((row >> 16U) & 0xFF) != 0) found.push_back(row);
    }
    return found;
  }
  static bool has_row(const std::vector<std::uint32_t>& rows, std::uint32_t row) {
    return std::find(rows.begin(), rows.end(), row) != rows.end();
  }
  std::optional<std::uint16_t> manager_channel_of(const ClientEntry& entry) {
    for (std::uint16_t index = 0x1201; index <= 0x127F; ++index) {
      auto sub1 = dict.get_unsigned(index, 1);
      auto sub2 = dict.get_unsigned(index, 2);
      if (sub1 && sub2 && *sub1 == entry.request && *sub2 == entry.response) return index;
    }
    return std::nullopt;
  }
};

// ------------------------------------------------------------------------------------------------
// §7.2.1 registration

// §7.2.1: "After receiving such a request, the SDO Manager scans the network ... reads the object
// 1F10h ... of all possible Node-IDs which are not yet registered"; §7.2.4 guideline 2: the scan
// starts at 127 and goes down; "It stops the scan at the first unregistered SRD it finds."
TEST_F(SdoManagerEngineSpec, DynamicSdoRequestScans1F10hFrom127DownAndStopsAtTheFirstOpenRequest) {
  constexpr std::uint8_t kLowSrd = 125;  // 127 and 126 are not on the bus
  start_network({kLowSrd});
  const auto confirmed = register_srd(kLowSrd);
  EXPECT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1))) << hex_text(confirmed);
  std::vector<std::uint8_t> scanned;
  for (std::uint8_t node = 1; node <= 127; ++node) {
    if (!uploads_of(node, kConnectionState, 0).empty()) scanned.push_back(node);
  }
  EXPECT_EQ(scanned, (std::vector<std::uint8_t>{125, 126, 127}));
  const auto first = [&](std::uint8_t node) { return uploads_of(node, kConnectionState, 0)[0]; };
  EXPECT_LT(first(127), first(126));
  EXPECT_LT(first(126), first(125));
}

// §7.2.1: "The Manager knows all default SDOs which are already allocated to other nodes": the
// scan does not read 1F10h over a default SDO an SRD holds (node 125's, held by SRD 126), nor
// that of a registered SRD.
TEST_F(SdoManagerEngineSpec, ScanSkipsDefaultSdosHeldByAConnection) {
  constexpr std::uint8_t kHeld = 125;  // a device outside 1F81h, reached through the manager
  add_device(kHeld, "master/slave.eds");
  start_network({kSrd2, kSrd3});
  register_ok(kSrd2);
  connect_ok(kSrd2, kHeld, 0x1281);
  ASSERT_EQ(client_entry(kSrd2, 0x1281).request, 0x600U + kHeld);
  const auto from = mark();
  register_ok(kSrd3);
  EXPECT_TRUE(uploads_of(kHeld, kConnectionState, 0, from).empty())
      << "1F10h read over node 125's default SDO, which SRD 126 holds";
  EXPECT_TRUE(uploads_of(kSrd2, kConnectionState, 0, from).empty())
      << "registered node 126 read again";
  EXPECT_FALSE(uploads_of(kSrd, kConnectionState, 0, from).empty()) << "127 was not scanned";
}

// §7.2.1: the scan stops at the first open request: a second SRD with an open request is not
// registered by the same Dynamic SDO Request, only by its own.
TEST_F(SdoManagerEngineSpec, OneDynamicSdoRequestRegistersOnlyTheFirstSrdFound) {
  start_network({kSrd, kSrd2});
  set_state(kSrd2, state_word(kClientSdo, 0, kRq));
  const auto from = mark();
  register_ok(kSrd);
  EXPECT_TRUE(uploads_of(kSrd2, kConnectionState, 0, from).empty())
      << "the scan went on past node 127, which had an open request";
  EXPECT_EQ(at(kSrd2, kConnectionState, 0), state_word(kClientSdo, 0, kRq));
  const auto second = mark();
  register_ok(kSrd2);
  EXPECT_TRUE(uploads_of(kSrd, kConnectionState, 0, second).empty())
      << "node 127 is registered and is not read again";
}

// §7.2.1: "the Manager uses the value OD Index from the object 1F10h and enables this entry in
// the 'Client SDO parameter' table. Afterwards the object 1F10h is reset by the Manager";
// §7.2.3: the confirmation has Cnxn state 1, Rq indication 0 and the index of the entry.
TEST_F(SdoManagerEngineSpec, RegistrationEnablesTheClientEntryNamedIn1F10hThenConfirms) {
  start_network();
  const auto from = mark();
  constexpr std::uint16_t kEntry = 0x1282;  // not the first one: the manager takes the one named
  const auto confirmed = register_srd(kSrd, state_word(kEntry, 0, kRq));
  EXPECT_EQ(confirmed, state_word(kEntry, 0, cnxn(1))) << hex_text(confirmed);
  const auto entry = client_entry(kSrd, kEntry);
  EXPECT_TRUE(entry.valid()) << hex_text(entry.request) << " " << hex_text(entry.response);
  EXPECT_EQ(entry.server, kManager) << "1282h sub 3: the node-ID of the server, the manager";
  EXPECT_NE(entry.request & kIdBits, entry.response & kIdBits);
  for (const std::uint16_t other :
       {std::uint16_t{0x1280}, std::uint16_t{0x1281}, std::uint16_t{0x1283}}) {
    EXPECT_FALSE(client_entry(kSrd, other).valid()) << hex_text(other) << " was not named";
  }
  const auto writes = writes_to(kSrd, from);
  const auto confirm_at = position_of(writes, kConnectionState, 0, confirmed);
  ASSERT_GE(confirm_at, 0) << "no write of 1F10h";
  for (const std::uint8_t sub : {std::uint8_t{1}, std::uint8_t{2}, std::uint8_t{3}}) {
    const auto at_sub = position_of(writes, kEntry, sub);
    EXPECT_GE(at_sub, 0) << "1282h sub " << int{sub} << " not written";
    EXPECT_LT(at_sub, confirm_at) << "1282h sub " << int{sub} << " written after the confirmation";
  }
}

// §7.2.1: the registration results in a connection SRD (client) -> manager (server); §7.2.3
// 1F02h: the manager takes its COB-IDs from the pool and sets bit 30 on them.
TEST_F(SdoManagerEngineSpec, RegistrationChannelUsesTwoPoolCobIdsMarkedInUseAndServesTheSrd) {
  start_network();
  EXPECT_EQ(in_use(pool()), 0U) << "nothing allocated before a registration";
  register_ok(kSrd);
  const auto entry = client_entry(kSrd, kClientSdo);
  const auto p = pool();
  ASSERT_EQ(p.size(), kPoolEntries);
  expect_pool_entries(p, entry, true);
  for (auto id : {entry.request, entry.response}) {
    EXPECT_NE(id & kIdBits, kInvalidPoolId) << "an entry marked not valid was used";
  }
  EXPECT_EQ(in_use(p), 2U);
  auto channel = manager_channel_of(entry);
  ASSERT_TRUE(channel.has_value()) << "no server channel 1201h.. of the manager has the COB-IDs";
  EXPECT_EQ(dict.get_unsigned(*channel, 3), kSrd) << "sub 3: the node-ID of the client";
  // And answers over it: 1F02h sub 0 (UNSIGNED8 9), expedited, on the response COB-ID.
  const auto answer = srd_read_manager(kSrd, kPool);
  EXPECT_EQ(answer.id, entry.response);
  EXPECT_EQ(answer.payload()[0], 0x4F);
  EXPECT_EQ(answer.payload()[4], kPoolEntries);
}

// §7.2.3 1F02h: bit 29 set marks a 29-bit identifier. With only such entries valid, the SRD's
// channel to the manager runs on extended frames.
TEST_F(SdoManagerEngineSpec, PoolEntriesWith29BitIdentifiersGiveAnExtendedChannel) {
  constexpr std::uint32_t k29Bit = master_spec::k29Bit;
  dict.set_unsigned(kPool, 1, k29Bit | 0x1234567U);
  dict.set_unsigned(kPool, 2, k29Bit | 0x1234568U);
  for (std::uint8_t sub = 3; sub <= 8; ++sub)
    dict.set_unsigned(kPool, sub, kNotValid | (0x680U + sub));
  start_network();
  register_ok(kSrd);
  const auto entry = client_entry(kSrd, kClientSdo);
  EXPECT_EQ((std::set<std::uint32_t>{entry.request, entry.response}),
            (std::set<std::uint32_t>{k29Bit | 0x1234567U, k29Bit | 0x1234568U}));
  const auto answer = srd_read_manager(kSrd, kPool);
  EXPECT_TRUE(answer.extended);
  EXPECT_EQ(answer, *from_candump("01234568#4F021F0009000000"));
}

// §7.2.2 "Requesting Access to all default SDOs", §7.2.3 Cnxn state 2: granted when all default
// SDOs are unused; "the Manager does not have to set-up any SDOs on the slaves and on the SRD".
TEST_F(SdoManagerEngineSpec, AllDefaultSdosRequestIsConfirmedWithCnxn2AndNoClientEntry) {
  start_network();
  const auto from = mark();
  const auto confirmed = register_srd(kSrd, 0x00000003);
  EXPECT_EQ(cnxn_of(confirmed), 2U) << hex_text(confirmed);
  EXPECT_EQ(confirmed & kRq, 0U) << hex_text(confirmed);
  EXPECT_EQ(error_of(confirmed), 0U) << hex_text(confirmed);
  for (std::uint16_t index = 0x1280; index <= 0x1283; ++index) {
    EXPECT_FALSE(client_entry(kSrd, index).valid()) << hex_text(index);
    EXPECT_LT(position_of(writes_to(kSrd, from), index, 1), 0) << hex_text(index);
  }
  EXPECT_TRUE(writes_to(kWithChannels, from).empty()) << "nothing is written to slaves";
  EXPECT_TRUE(writes_to(kDefaultOnly, from).empty()) << "nothing is written to slaves";
  EXPECT_EQ(in_use(pool()), 0U);
}

// §7.2.3 Cnxn state 2 needs "all default SDOs in the system are unused".
TEST_F(SdoManagerEngineSpec, AllDefaultSdosAreNotGrantedWhileOneIsHeld) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd2);
  connect_ok(kSrd2, kWithChannels, 0x1281);
  const auto answer = register_srd(kSrd, 0x00000003);
  EXPECT_NE(answer, 0x00000003U) << "the manager did not answer";
  EXPECT_NE(cnxn_of(answer), 2U) << hex_text(answer);
}

// §7.2.4 guideline 4: default SDOs assigned to an owner of all remain its own: another SRD's
// connection to a slave is not put on the slave's default SDO.
TEST_F(SdoManagerEngineSpec, DefaultSdosOfAnOwnerOfAllAreNotGivenToAnotherSrd) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd2);
  ASSERT_EQ(cnxn_of(register_srd(kSrd, 0x00000003)), 2U);
  const auto state = request(kSrd2, kWithChannels, 0x1281);
  const auto entry = client_entry(kSrd2, 0x1281);
  if (cnxn_of(state) == 3) {
    EXPECT_NE(entry.request, 0x600U + kWithChannels) << "the default SDO belongs to node 127";
    EXPECT_EQ(device_value(kWithChannels, 0x1201, 1), entry.request);
  } else {
    EXPECT_EQ(cnxn_of(state), 0U) << hex_text(state);
    EXPECT_FALSE(entry.valid());
  }
}

// ------------------------------------------------------------------------------------------------
// §7.2.2 requesting connections

// §7.1: the free additional server entry of S with two COB-IDs of 1F02h marked in use.
TEST_F(SdoManagerEngineSpec, SecondSrdGetsAnAdditionalServerChannelWithPoolCobIds) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);
  const auto state = request(kSrd2, kWithChannels, 0x1283);
  EXPECT_EQ(state, state_word(0x1283, 0, cnxn(3))) << hex_text(state);
  const auto entry = client_entry(kSrd2, 0x1283);
  EXPECT_TRUE(entry.valid());
  EXPECT_EQ(entry.server, kWithChannels);
  EXPECT_EQ(device_value(kWithChannels, 0x1201, 1), entry.request);
  EXPECT_EQ(device_value(kWithChannels, 0x1201, 2), entry.response);
  EXPECT_EQ(device_value(kWithChannels, 0x1201, 3), kSrd2);
  EXPECT_EQ(device_value(kWithChannels, 0x1202, 1).value_or(0) & kNotValid, kNotValid)
      << "only one channel is needed";
  const auto p = pool();
  expect_pool_entries(p, entry, true);
  EXPECT_EQ(in_use(p), 6U) << "two registrations and this connection";
  EXPECT_EQ(client_entry(kSrd, 0x1281).request, 0x600U + kWithChannels);
}

// §7.1 "free additional SDOs": a server channel already valid on the slave is skipped.
TEST_F(SdoManagerEngineSpec, AServerChannelInUseOnTheSlaveIsSkipped) {
  cfg::DeviceDescription eds = slave_channels_eds();
  set_value(eds, 0x1201, 1, 0x6A0);  // configured by someone else (outside the pool)
  set_value(eds, 0x1201, 2, 0x6A1);
  start_network({kSrd, kSrd2}, eds);
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);
  connect_ok(kSrd2, kWithChannels, 0x1281);
  const auto entry = client_entry(kSrd2, 0x1281);
  EXPECT_EQ(device_value(kWithChannels, 0x1201, 1), 0x6A0U) << "the channel in use is kept";
  EXPECT_EQ(device_value(kWithChannels, 0x1202, 1), entry.request);
  EXPECT_EQ(device_value(kWithChannels, 0x1202, 2), entry.response);
  EXPECT_EQ(device_value(kWithChannels, 0x1202, 3), kSrd2);
}

// §7.2.3 error code 03h: node 3 has only its default SDO, which SRD 127 holds.
TEST_F(SdoManagerEngineSpec, SlaveWithoutAFreeServerChannelGivesError03h) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kDefaultOnly, 0x1281);
  refused(kSrd2, kDefaultOnly, 0x1281, 0x03);
}

// The same with all additional channels in use (1201h someone else's, 1202h SRD 126's).
TEST_F(SdoManagerEngineSpec, SlaveWithAllServerChannelsInUseGivesError03h) {
  cfg::DeviceDescription eds = slave_channels_eds();
  set_value(eds, 0x1201, 1, 0x6A0);
  set_value(eds, 0x1201, 2, 0x6A1);
  start_network({kSrd, kSrd2}, eds);
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);
  connect_ok(kSrd2, kWithChannels, 0x1281);
  ASSERT_EQ(in_use(pool()), 6U);
  refused(kSrd2, kWithChannels, 0x1282, 0x03);
}

// §7.2.3 error code 02h: four valid pool entries, two registrations take them all; an entry
// marked not valid is never allocated.
TEST_F(SdoManagerEngineSpec, ExhaustedPoolGivesError02h) {
  for (std::uint8_t sub = 5; sub <= 8; ++sub)
    dict.set_unsigned(kPool, sub, kNotValid | (0x680U + sub));
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);  // the default SDO needs no COB-ID
  refused(kSrd2, kWithChannels, 0x1281, 0x02);
  EXPECT_EQ(device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, kNotValid);
  for (auto node : {kWithChannels, kSrd, kSrd2}) {
    for (const auto& w : writes_to(node)) {
      const bool cob_id = (w.index >= 0x1200 && w.index <= 0x12FF) && (w.sub == 1 || w.sub == 2);
      if (cob_id) {
        EXPECT_FALSE((w.value & kIdBits) >= 0x685 && (w.value & kIdBits) <= 0x689)
            << "node " << int{node} << " got " << hex_text(w.value) << " from a not-valid entry";
      }
    }
  }
}

// §7.2.3 error code 01h: with one own server channel for SRDs, the second cannot register.
TEST_F(SdoManagerEngineSpec, NoFreeManagerChannelGivesRegistrationError01h) {
  settings.channels = 1;
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  const auto state = register_srd(kSrd2);
  EXPECT_EQ(cnxn_of(state), 0U) << hex_text(state);
  EXPECT_EQ(error_of(state), 0x01) << hex_text(state);
  EXPECT_FALSE(client_entry(kSrd2, kClientSdo).valid());
}

// §7.2.3 error code 04h: an additional channel is needed (the default SDO is held) and the
// slave does not answer.
TEST_F(SdoManagerEngineSpec, SilentSlaveGivesError04h) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);
  port.devices.erase(kWithChannels);
  refused(kSrd2, kWithChannels, 0x1281, 0x04);
}

// §7.2.3: refusals are "Abort domain transfer" with 060A 0023h; a node that is not registered
// is refused.
TEST_F(SdoManagerEngineSpec, RequestFromAnUnregisteredNodeIsAborted060A0023) {
  start_network({kSrd});
  EXPECT_EQ(dict.write(kRequestSdo, 0, le(request_word(0x1281, kSrd, kWithChannels), 4), now),
            SdoAbort::ResourceNotAvailable);
  run();
  EXPECT_FALSE(client_entry(kSrd, 0x1281).valid());
}

// §7.2.3: "The requested Node-ID must not be 0."
TEST_F(SdoManagerEngineSpec, RequestForSlave0IsAborted060A0023) {
  start_network();
  register_ok(kSrd);
  EXPECT_EQ(srd_write_manager(kSrd, kRequestSdo, request_word(0x1281, kSrd, 0)),
            SdoAbort::ResourceNotAvailable);
}

// §7.2.3 1F00h bits 15-8 "the SRD's Node-ID": asking in another SRD's name is refused.
TEST_F(SdoManagerEngineSpec, RequestInAnotherSrdsNameIsAborted060A0023) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  EXPECT_EQ(srd_write_manager(kSrd, kRequestSdo, request_word(0x1281, kSrd2, kWithChannels)),
            SdoAbort::ResourceNotAvailable);
  run();
  EXPECT_FALSE(client_entry(kSrd2, 0x1281).valid());
}

// §7.2.3 1F00h bits 7-0 "Slave Node-ID": 80h-FFh name no node (CiA 301: 1..127); the
// request is refused with 060A 0023h and no SDO access starts.
TEST_F(SdoManagerEngineSpec, RequestForSlaveNodeId80hOrAboveIsAborted060A0023) {
  start_network();
  register_ok(kSrd);
  const auto accesses = port.accesses.size();
  for (const std::uint8_t slave : {std::uint8_t{0x80}, std::uint8_t{0xFF}}) {
    EXPECT_EQ(srd_write_manager(kSrd, kRequestSdo, request_word(0x1282, kSrd, slave)),
              SdoAbort::ResourceNotAvailable)
        << "slave " << int{slave};
  }
  run();
  EXPECT_EQ(port.accesses.size(), accesses);
  EXPECT_TRUE(events_of(Kind::SdoConnectionRefused, kSrd).empty());
}

// §7.2.3 1F00h/1F01h bits 15-8 "SRD Node-ID": 0 and 80h-FFh are no SRD's node-ID: refused with
// 060A 0023h (written by a tool on the default channel, which has no SRD of its own).
TEST_F(SdoManagerEngineSpec, RequestOrReleaseWithSrdNodeId0Or80hIsAborted060A0023) {
  start_network();
  register_ok(kSrd);
  for (const std::uint16_t object : {kRequestSdo, kReleaseSdo}) {
    for (const std::uint8_t srd : {std::uint8_t{0x00}, std::uint8_t{0x80}}) {
      EXPECT_EQ(dict.write(object, 0, le(request_word(0x1282, srd, kWithChannels), 4), now),
                SdoAbort::ResourceNotAvailable)
          << hex_text(object) << " SRD node-ID " << int{srd};
    }
  }
  EXPECT_EQ(engine().srds().size(), 1U);
}

// §7.2.3 1F01h bits 7-0: 0 releases everything and de-registers; 80h-FFh name no node and are
// refused with 060A 0023h: the SRD stays registered with its connections.
TEST_F(SdoManagerEngineSpec, ReleaseOfSlaveNodeId80hIsAborted060A0023) {
  start_network();
  register_ok(kSrd);
  connect_ok(kSrd, kWithChannels, 0x1282);
  EXPECT_EQ(srd_write_manager(kSrd, kReleaseSdo, request_word(0, kSrd, 0x80)),
            SdoAbort::ResourceNotAvailable);
  run();
  EXPECT_TRUE(events_of(Kind::SdoConnectionReleased, kSrd).empty());
  EXPECT_EQ(engine().srds().size(), 1U);
  EXPECT_EQ(engine().connections().size(), 2U);  // its channel to the manager, and to S
  EXPECT_TRUE(client_entry(kSrd, 0x1282).valid());
}

// §7.2.3: 1F00h and 1F01h are wo; 1F03h-1F06h are ro, 254 rows in part 1.
TEST_F(SdoManagerEngineSpec, ObjectAccessIsAsTheSpecTablesSay) {
  start_network();
  std::vector<std::uint8_t> data;
  EXPECT_EQ(dict.read(kRequestSdo, 0, data, now), SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(dict.read(kReleaseSdo, 0, data, now), SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(own(kConnections, 0), 254U);
  EXPECT_EQ(dict.write(kConnections, 1, le(row_word(1, kSrd, 0, 2), 4), now),
            SdoAbort::WriteOfReadOnly);
  EXPECT_EQ(own(kConnections, 1), 0U) << "no connection yet, and the write failed";
  EXPECT_EQ(own(kPool, 1), 0x681U) << "1F02h as the DCF configured it";
}

// §7.2.3 1F03h rows: client offset, client node-ID, server offset, server node-ID.
TEST_F(SdoManagerEngineSpec, ConnectionTableRowsFollowTheSpecLayout) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);   // default SDO: server offset 0
  connect_ok(kSrd2, kWithChannels, 0x1283);  // 1201h: server offset 1
  const auto r = rows();
  EXPECT_TRUE(has_row(r, row_word(0x01, kSrd, 0x00, kWithChannels))) << "no row 017F0002h";
  EXPECT_TRUE(has_row(r, row_word(0x03, kSrd2, 0x01, kWithChannels))) << "no row 037E0102h";
  for (auto row : r) {
    if ((row & 0xFF) != kManager) continue;
    const std::uint8_t client = (row >> 16U) & 0xFF;
    const auto entry = client_entry(client, static_cast<std::uint16_t>(0x1280 + (row >> 24U)));
    EXPECT_EQ(manager_channel_of(entry), 0x1200 + ((row >> 8U) & 0xFF)) << hex_text(row);
  }
}

// ------------------------------------------------------------------------------------------------
// §7.2.2 / §7.2.3 releasing

// §7.2.3 1F01h: the connection is released on both sides, its pool entries and row freed.
TEST_F(SdoManagerEngineSpec, ReleaseByIndexInvalidatesBothSidesAndFreesItsPoolEntries) {
  start_network({kSrd, kSrd2});
  register_ok(kSrd);
  register_ok(kSrd2);
  connect_ok(kSrd, kWithChannels, 0x1281);
  connect_ok(kSrd2, kWithChannels, 0x1281);
  const auto entry = client_entry(kSrd2, 0x1281);
  ASSERT_EQ(in_use(pool()), 6U);
  release(kSrd2, request_word(0x1281, kSrd2, kWithChannels));
  const auto after = client_entry(kSrd2, 0x1281);
  EXPECT_NE(after.request & kNotValid, 0U) << "SRD 1281h sub 1 = " << hex_text(after.request);
  EXPECT_NE(after.response & kNotValid, 0U) << "SRD 1281h sub 2 = " << hex_text(after.response);
  EXPECT_NE(device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U);
  EXPECT_NE(device_value(kWithChannels, 0x1201, 2).value_or(0) & kNotValid, 0U);
  const auto p = pool();
  expect_pool_entries(p, entry, false);
  EXPECT_EQ(in_use(p), 4U);
  const auto r = rows();
  EXPECT_FALSE(has_row(r, row_word(0x01, kSrd2, 0x01, kWithChannels)));
  EXPECT_TRUE(has_row(r, row_word(0x01, kSrd, 0x00, kWithChannels)));
  EXPECT_TRUE(client_entry(kSrd, 0x1281).valid());
}

// §7.2.3 1F01h with index 0: every connection of the SRD to that slave (and only those).
TEST_F(SdoManagerEngineSpec, ReleaseWithIndex0ReleasesEveryConnectionToThatSlave) {
  start_network();
  register_ok(kSrd);
  connect_ok(kSrd, kWithChannels, 0x1281);
  connect_ok(kSrd, kWithChannels, 0x1282);
  connect_ok(kSrd, kDefaultOnly, 0x1283);
  release(kSrd, request_word(0, kSrd, kWithChannels));
  EXPECT_FALSE(client_entry(kSrd, 0x1281).valid());
  EXPECT_FALSE(client_entry(kSrd, 0x1282).valid());
  EXPECT_NE(device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U);
  EXPECT_TRUE(client_entry(kSrd, 0x1283).valid()) << "the connection to node 3 stays";
  EXPECT_TRUE(client_entry(kSrd, kClientSdo).valid()) << "the SRD stays registered";
  EXPECT_EQ(in_use(pool()), 2U) << "only the registration's COB-IDs";
  const auto from = mark();
  connect_ok(kSrd, kWithChannels, 0x1282);
  EXPECT_EQ(client_entry(kSrd, 0x1282).request, 0x600U + kWithChannels);
  EXPECT_TRUE(writes_to(kWithChannels, from).empty());
}

// §7.2.1 de-registration: 1F01h with slave node-ID 0 releases everything; it may register again.
TEST_F(SdoManagerEngineSpec, DeregistrationReleasesEverythingOfTheSrdAndItCanRegisterAgain) {
  start_network();
  register_ok(kSrd);
  connect_ok(kSrd, kWithChannels, 0x1281);
  connect_ok(kSrd, kWithChannels, 0x1282);
  connect_ok(kSrd, kDefaultOnly, 0x1283);
  release(kSrd, request_word(0, kSrd, 0));
  for (std::uint16_t index = 0x1280; index <= 0x1283; ++index) {
    EXPECT_FALSE(client_entry(kSrd, index).valid()) << hex_text(index);
  }
  EXPECT_NE(device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U);
  EXPECT_EQ(in_use(pool()), 0U);
  EXPECT_TRUE(rows().empty());
  register_ok(kSrd);
  connect_ok(kSrd, kWithChannels, 0x1281);
}

}  // namespace
}  // namespace nmt::engine_test
