// The SDO manager of NmtMaster (dynamic establishment of SDO connections) against CiA DSP 302
// v3.2.1 §7 (../shared/spec/001_846495643a25878e.txt) and the decisions every helper shares
// (DSP 302 §7.2.3 word layouts; 1F03h-1F06h read-only with 254 rows). Written from the spec and
// the public headers only, not from the engine's sources or its own tests: an NmtMaster with its
// SDO manager, simulated slaves and SDO requesting devices (SRDs) on one 500 kbit/s simulated bus
// with simulated time. Helpers come from nmt_master_spec_test_rig.hpp.
//
// The cases that are the manager's protocol alone (scan, registration, requests, refusals,
// releases, the tables) moved with their assertions to sdo_manager_engine_spec_test.cpp, where
// the manager engine runs alone through a fake of its port; the ones here are where the master's
// parts meet the manager: an SRD using what it was given, timing, error control, a standby
// flying master, frame loss.
//
// An SRD here is a SlaveNode built from tests/data/sdo_manager/srd.eds (1F10h, 1F11h, client
// SDO entries 1280h-1283h, heartbeat 100 ms) that the manager reads and writes over its default
// SDO, plus what the test does as the SRD's application: it sets 1F10h and sends the Dynamic SDO
// Request (6E0h, no data), and it talks over the client entries the manager wrote with an
// SdoClient built from their COB-IDs. No SRD engine of the library is used.
//
// Data files (tests/data/sdo_manager/): manager.dcf (master.dcf of the NmtMasterSpec tests, node
// 1, slaves 2 and 3, plus 1F00h, 1F01h and 1F02h = eight free 11-bit COB-IDs 681h-688h and a
// ninth, 689h, marked not valid), slave_channels.eds (slave.eds plus server SDOs 1201h and 1202h,
// not valid by default), srd.eds. Node 2 has the additional server channels, node 3 (slave.eds)
// has only its default SDO. SRDs sit at the highest node-IDs (§7.2.4 guideline 2).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "nmt_master_spec_test_rig.hpp"
#include "sdo_manager_spec_words.hpp"
#include "test_paths.hpp"

namespace nmt::master_spec {
namespace {

using Kind = MasterEvent::Kind;

inline const cfg::DeviceDescription& data_file(const std::string& name) {
  static std::map<std::string, cfg::DeviceDescription> files;
  auto it = files.find(name);
  if (it != files.end()) return it->second;
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sdo_manager/" + name);
  EXPECT_TRUE(result.ok()) << name << ": " << result.diagnostics.format();
  return files.emplace(name, result.device.value_or(cfg::DeviceDescription{})).first->second;
}
const cfg::DeviceDescription& manager_dcf() {
  return data_file("manager.dcf");
}
const cfg::DeviceDescription& srd_eds() {
  return data_file("srd.eds");
}
const cfg::DeviceDescription& slave_channels_eds() {
  return data_file("slave_channels.eds");
}

// An expedited SDO download request (CiA 301 §7.2.4.3.3: ccs 1, e = 1) the manager sent to a
// node's default SDO, decoded.
struct Write {
  TimePoint at;
  std::uint16_t index;
  std::uint8_t sub;
  std::uint32_t value;
};
std::optional<Write> expedited_write(const Seen& s) {
  const CanFrame& f = s.frame;
  if (f.rtr || f.dlc != 8 || (f.data[0] >> 5U) != 1 || (f.data[0] & 2U) == 0) return std::nullopt;
  const unsigned size = (f.data[0] & 1U) != 0 ? 4 - ((f.data[0] >> 2U) & 3U) : 4;
  std::uint32_t value = 0;
  for (unsigned i = 0; i < size; ++i) value |= std::uint32_t{f.data[4 + i]} << (8 * i);
  return Write{s.at, static_cast<std::uint16_t>(f.data[1] | f.data[2] << 8U), f.data[3], value};
}

class ManagerRig : public MasterRig {
 public:
  ManagerRig() {
    master = manager_dcf();
    options.sdo_manager.enabled = true;
    // §7.2.1: registered SRDs take part in error control. The manager's 1016h names their
    // heartbeats (srd.eds: 1017h = 100 ms) with 300 ms; the test without these entries is
    // RegisteredSrdIsWatchedByItsOwnHeartbeatWithoutA1016hEntry.
    std::uint8_t entry = 10;
    for (std::uint8_t node : {kSrd, kSrd2, kSrd3}) consume_heartbeat(entry++, node, 300);
  }
  /// Without the 1016h entries for the SRDs.
  void forget_srd_heartbeats() {
    for (std::uint8_t entry = 10; entry <= 12; ++entry) set_value(master, 0x1016, entry, 0);
  }

  /// An SRD from srd.eds at `node`, powered on now.
  SimulatedDevice& add_srd(std::uint8_t node, DeviceFaults faults = {},
                           const cfg::DeviceDescription& eds = srd_eds()) {
    auto device = SimulatedDevice::create(eds, node, std::move(faults));
    EXPECT_TRUE(device.ok()) << (device.ok() ? "" : device.error().message);
    auto& slot = srds_[node];
    if (slot) bus.detach(*slot);
    slot = std::make_unique<SimEngineNode<SimulatedDevice>>(std::move(device).value());
    bus.attach(*slot);
    slot->apply(
        [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
    return slot->engine();
  }
  SimulatedDevice& srd(std::uint8_t node) { return srds_.at(node)->engine(); }
  std::uint64_t srd_value(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    auto v = srd(node).node().dictionary().get_unsigned(index, sub);
    EXPECT_TRUE(v.has_value()) << "SRD " << int{node} << " has no " << hex_text(index) << " sub "
                               << int{sub};
    return v.value_or(0);
  }
  /// The SRD's application sets its own 1F10h.
  void set_state(std::uint8_t node, std::uint32_t value) {
    EXPECT_EQ(srd(node).node().dictionary().write(kConnectionState, 0, le(value, 4), bus.now()),
              SdoAbort::None);
  }

  /// The usual scene: slave 2 (with channels), slave 3 (default SDO only) and the SRDs on at 0,
  /// the master 50 ms later; returns once NMT start-up completed.
  NmtMaster& start_network(std::initializer_list<std::uint8_t> srds = {kSrd},
                           const cfg::DeviceDescription& eds2 = slave_channels_eds()) {
    add_slave(kWithChannels, {}, eds2);
    add_slave(kDefaultOnly);
    for (auto node : srds) add_srd(node);
    auto& m = power_on_network();
    EXPECT_TRUE(run_until_kind(Kind::StartupComplete, 20s)) << "NMT start-up did not complete";
    run_for(200ms);  // the boot-ups after the start-up's reset communication are all out
    return m;
  }

  /// §7.2.1: the SRD sets 1F10h to `request` and sends the Dynamic SDO Request; runs until the
  /// manager wrote 1F10h (it no longer holds the request) or `limit`. The 1F10h value then.
  std::uint32_t register_srd(std::uint8_t node,
                             std::uint32_t request = state_word(kClientSdo, 0, kRq),
                             Duration limit = 20s) {
    set_state(node, request);
    send_foreign(kDynamicSdoRequestFrame);
    return await_state(node, request, limit);
  }
  /// Runs until the SRD's 1F10h differs from `from` or `limit`; the value then.
  std::uint32_t await_state(std::uint8_t node, std::uint32_t from, Duration limit = 20s) {
    bus.run_until([&] { return srd_value(node, kConnectionState, 0) != from; }, bus.now() + limit);
    return static_cast<std::uint32_t>(srd_value(node, kConnectionState, 0));
  }
  /// register_srd() expecting the §7.2.3 confirmation (Cnxn 1, Rq 0, the index); then the SRD
  /// clears its 1F10h again ("when ... already registered by the Manager, the value has to be
  /// 0").
  void register_ok(std::uint8_t node, std::uint16_t index = kClientSdo) {
    const auto confirmed = register_srd(node, state_word(index, 0, kRq));
    ASSERT_EQ(confirmed, state_word(index, 0, cnxn(1)))
        << "SRD " << int{node} << " 1F10h = " << hex_text(confirmed);
    set_state(node, 0);
  }

  ClientEntry client_entry(std::uint8_t node, std::uint16_t index) {
    return {static_cast<std::uint32_t>(srd_value(node, index, 1)),
            static_cast<std::uint32_t>(srd_value(node, index, 2)),
            static_cast<std::uint8_t>(srd_value(node, index, 3))};
  }

  /// One transfer of the SRD over its client entry `index` (nullopt: the entry is not valid).
  std::optional<SdoResult> srd_transfer(std::uint8_t node, std::uint16_t index, bool upload,
                                        std::uint16_t object, std::uint8_t sub,
                                        std::vector<std::uint8_t> data = {}) {
    const auto entry = client_entry(node, index);
    if (!entry.valid()) return std::nullopt;
    SdoClientConfig config;
    config.request_cob_id = cfg::CobId::from_word(entry.request);
    config.response_cob_id = cfg::CobId::from_word(entry.response);
    config.node_id = cfg::NodeId::from(entry.server);
    SimEngineNode<SdoClient> client(config);
    std::optional<SdoResult> result;
    client.set_event_handler([&](const SdoResult& r, TimePoint) { result = r; });
    bus.attach(client);
    test_support::started(client.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
      return upload ? c.upload(object, sub, now, out) : c.download(object, sub, data, now, out);
    }));
    bus.run_until([&] { return result.has_value(); }, bus.now() + 5s);
    bus.detach(client);
    EXPECT_TRUE(result.has_value()) << "the SRD's transfer did not end";
    return result;
  }
  /// The SRD reads (object, sub) over its client entry `index` and gets `expected`.
  void expect_read(std::uint8_t node, std::uint16_t index, std::uint16_t object, std::uint8_t sub,
                   std::uint64_t expected) {
    auto read = srd_transfer(node, index, true, object, sub);
    ASSERT_TRUE(read.has_value()) << "SRD " << int{node} << ": " << hex_text(index) << " not valid";
    EXPECT_TRUE(read->ok()) << "SRD " << int{node} << " reading " << hex_text(object) << ": "
                            << read->abort;
    EXPECT_EQ(value_of(read->data), expected);
  }
  /// 1F00h or 1F01h written by SRD `node` over its channel to the manager (1280h unless said).
  SdoAbort srd_write_manager(std::uint8_t node, std::uint16_t object, std::uint32_t value,
                             std::uint16_t channel = kClientSdo) {
    auto r = srd_transfer(node, channel, false, object, 0, le(value, 4));
    if (!r) {
      ADD_FAILURE() << "SRD " << int{node} << " has no valid channel " << hex_text(channel);
      return SdoAbort::General;
    }
    return r->abort;
  }
  /// §7.2.2: SRD `node` requests a connection to `slave` on its client entry `index` and waits
  /// for the manager's 1F10h; returns it (its 1F10h is 0 before, as after register_ok()).
  std::uint32_t request(std::uint8_t node, std::uint8_t slave, std::uint16_t index,
                        Duration limit = 20s) {
    EXPECT_EQ(srd_value(node, kConnectionState, 0), 0U);
    const SdoAbort code = srd_write_manager(node, kRequestSdo, request_word(index, node, slave));
    EXPECT_EQ(code, SdoAbort::None) << "1F00h write: " << code;
    const auto state = await_state(node, 0, limit);
    set_state(node, 0);
    return state;
  }
  /// request() expecting §7.2.3's confirmation: Cnxn 3 with the index.
  void connect_ok(std::uint8_t node, std::uint8_t slave, std::uint16_t index) {
    const auto state = request(node, slave, index);
    EXPECT_EQ(cnxn_of(state), 3U) << "1F10h = " << hex_text(state);
    EXPECT_EQ(index_of(state), index) << "1F10h = " << hex_text(state);
    EXPECT_EQ(error_of(state), 0U) << "1F10h = " << hex_text(state);
  }
  /// 1F01h from SRD `node`, then runs `settle`.
  void release(std::uint8_t node, std::uint32_t word, Duration settle = 5s) {
    EXPECT_EQ(srd_write_manager(node, kReleaseSdo, word), SdoAbort::None);
    run_for(settle);
  }

  /// Expedited writes the manager sent to `node`'s default SDO, from `from` on.
  std::vector<Write> writes_to(std::uint8_t node, TimePoint from = TimePoint{}) const {
    std::vector<Write> out;
    for (const auto& s : requests_to(node, from)) {
      if (auto w = expedited_write(s)) out.push_back(*w);
    }
    return out;
  }
  std::vector<Write> writes_to(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                               TimePoint from = TimePoint{}) const {
    std::vector<Write> out;
    for (const auto& w : writes_to(node, from)) {
      if (w.index == index && w.sub == sub) out.push_back(w);
    }
    return out;
  }

  /// 1F02h as the manager's SDO server gives it: sub 1..sub 0.
  std::vector<std::uint32_t> pool() {
    std::vector<std::uint32_t> out;
    const auto count = tool_read_u(kPool, 0);
    EXPECT_TRUE(count.has_value()) << "1F02h sub 0 unreadable";
    for (unsigned sub = 1; sub <= count.value_or(0); ++sub) {
      out.push_back(static_cast<std::uint32_t>(
          tool_read_u(kPool, static_cast<std::uint8_t>(sub)).value_or(0xFFFFFFFF)));
    }
    return out;
  }
  static std::size_t in_use(const std::vector<std::uint32_t>& pool) {
    return static_cast<std::size_t>(
        std::count_if(pool.begin(), pool.end(), [](std::uint32_t e) { return (e & kInUse) != 0; }));
  }
  /// The valid rows of 1F03h (neither node-ID field 0) as the manager's SDO server gives them.
  std::vector<std::uint32_t> rows() {
    std::vector<std::uint32_t> out;
    const auto count = tool_read_u(kConnections, 0);
    EXPECT_TRUE(count.has_value()) << "1F03h sub 0 unreadable";
    for (unsigned sub = 1; sub <= count.value_or(0); ++sub) {
      const auto row = tool_read_u(kConnections, static_cast<std::uint8_t>(sub)).value_or(0);
      if ((row & 0xFF) != 0 && ((row >> 16U) & 0xFF) != 0) {
        out.push_back(static_cast<std::uint32_t>(row));
      }
    }
    return out;
  }

 private:
  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<SimulatedDevice>>> srds_;
};

// ------------------------------------------------------------------------------------------------
// §7.2.2 requesting connections, used by the SRD

// §7.1: "If it decides to use the default SDO of S, it does not need to write to the object
// dictionary of S"; §7.2.2: the manager then writes the SRD's client entry and confirms in 1F10h
// (Cnxn 3, the index).
TEST(SdoManagerSpec, ConnectionOnAFreeDefaultSdoWritesOnlyTheSrd) {
  ManagerRig rig;
  rig.start_network();
  rig.register_ok(kSrd);
  const TimePoint from = rig.bus.now();
  const auto state = rig.request(kSrd, kWithChannels, 0x1281);
  EXPECT_EQ(state, state_word(0x1281, 0, cnxn(3))) << hex_text(state);
  const auto entry = rig.client_entry(kSrd, 0x1281);
  // CiA 301 pre-defined connection set: 600h + node-ID client -> server, 580h + node-ID back.
  EXPECT_EQ(entry.request, 0x600U + kWithChannels);
  EXPECT_EQ(entry.response, 0x580U + kWithChannels);
  EXPECT_EQ(entry.server, kWithChannels);
  EXPECT_TRUE(rig.all_downloads(kWithChannels, from).empty())
      << "the manager wrote to the slave: " << rig.all_downloads(kWithChannels, from).front();
  EXPECT_EQ(ManagerRig::in_use(rig.pool()), 2U) << "only the registration's two COB-IDs";
  // The SRD uses the connection (slave_channels.eds: 1018h sub 1 = 0000ABCDh).
  rig.expect_read(kSrd, 0x1281, 0x1018, 1, kVendor);
}

// The same, used: SRD 126 reads the slave's identity over the additional channel (CiA 301: a
// server channel 1201h.. serves while both COB-IDs are valid).
TEST(SdoManagerSpec, SecondSrdReadsTheSlaveOverTheAdditionalChannel) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);
  rig.expect_read(kSrd2, 0x1281, 0x1018, 2, kProduct);
  rig.expect_read(kSrd, 0x1281, 0x1018, 3, kRevision);
}

// ------------------------------------------------------------------------------------------------
// §7.2.1 / §7.2.2 with the master: timing and error control

// §7.2.3 1F10h: "After the SRD is registered and a connection from the SRD to the Manager is
// established, the Manager confirms the registration by writing to this object": once the SRD
// has taken the confirmation, it is registered and may write 1F00h over the new channel at once.
// The SRD here answers SDO requests 5 ms late (a tool behind a gateway); it sends its request as
// soon as its answer to the confirmation is on the bus.
TEST(SdoManagerSpec, RequestRightAfterTheRegistrationConfirmationIsServed) {
  ManagerRig rig;
  rig.forget_srd_heartbeats();  // the manager may then read the SRD's 1017h (see the top)
  rig.start_network({});
  DeviceFaults slow;
  slow.sdo_latency = 5ms;
  rig.add_srd(kSrd, slow);
  rig.run_for(200ms);
  // CiA 301 §7.2.4.3.4: the download response to 1F10h sub 0 is 60 10 1F 00 (from 580h + 127).
  const std::string answer = "5FF#60101F0000000000";
  const std::size_t before = rig.seen.size();
  auto answered = [&] {
    for (std::size_t i = before; i < rig.seen.size(); ++i) {
      if (rig.seen[i].text() == answer) return true;
    }
    return false;
  };
  rig.set_state(kSrd, state_word(kClientSdo, 0, kRq));
  rig.send_foreign(kDynamicSdoRequestFrame);
  ASSERT_TRUE(rig.bus.run_until(answered, rig.bus.now() + 20s)) << "no confirmation";
  ASSERT_EQ(rig.srd_value(kSrd, kConnectionState, 0), state_word(kClientSdo, 0, cnxn(1)));
  rig.set_state(kSrd, 0);
  EXPECT_EQ(rig.srd_write_manager(kSrd, kRequestSdo, request_word(0x1281, kSrd, kWithChannels)),
            SdoAbort::None);
  const auto state = rig.await_state(kSrd, 0);
  EXPECT_EQ(state, state_word(0x1281, 0, cnxn(3))) << hex_text(state);
}

// §7.2.1 Error Control of SRD: "On a Error Control Error Event caused by the SRD, the Manager
// forces all SDOs requested by that SRD to be released by writing into the corresponding SDO
// tables of the SRD and all by the SRD accessed devices." The SRD's heartbeat stops while it
// still answers SDO requests.
TEST(SdoManagerSpec, SrdHeartbeatLossReleasesItsConnectionsOnBothSides) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});  // node 126's heartbeat will stop
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);  // 1201h on the slave
  rig.connect_ok(kSrd2, kDefaultOnly, 0x1282);   // default SDO of node 3
  rig.run_for(2s);
  ASSERT_TRUE(rig.client_entry(kSrd2, 0x1281).valid()) << "released while the SRD was alive";
  DeviceFaults stop;
  stop.heartbeat_stops_at = rig.bus.now();
  rig.srd(kSrd2).set_faults(stop);
  rig.run_for(5s);
  EXPECT_FALSE(rig.client_entry(kSrd2, 0x1281).valid());
  EXPECT_FALSE(rig.client_entry(kSrd2, 0x1282).valid());
  EXPECT_NE(rig.device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U)
      << "the slave's server channel stays enabled";
  const auto rows = rig.rows();
  for (auto row : rows) EXPECT_NE((row >> 16U) & 0xFF, kSrd2) << hex_text(row);
  EXPECT_EQ(ManagerRig::in_use(rig.pool()), 2U) << "only SRD 127's registration";
  // Node 3's default SDO is free again for SRD 127 (no write to node 3).
  const TimePoint from = rig.bus.now();
  rig.connect_ok(kSrd, kDefaultOnly, 0x1282);
  EXPECT_EQ(rig.client_entry(kSrd, 0x1282).request, 0x600U + kDefaultOnly);
  EXPECT_TRUE(rig.all_downloads(kDefaultOnly, from).empty());
  // SRD 127 kept its connection.
  EXPECT_TRUE(rig.client_entry(kSrd, 0x1281).valid());
}

// §7.2.1: "Any registered SRD has to participate in Error Control. After entering the list of
// registered SRDs the SDO Manager will start the Node Guarding Protocol or Heartbeat Protocol."
// An SRD that produces heartbeats (srd.eds: 1017h = 100 ms) without a 1016h entry in the
// manager's DCF stays registered while its heartbeat runs (CiA 301: a device whose heartbeat
// producer time is not 0 uses the heartbeat protocol and does not answer node guarding), and
// loses its connections once its heartbeat stops.
TEST(SdoManagerSpec, RegisteredSrdIsWatchedByItsOwnHeartbeatWithoutA1016hEntry) {
  ManagerRig rig;
  rig.forget_srd_heartbeats();
  rig.start_network();
  rig.register_ok(kSrd);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.run_for(10s);
  EXPECT_TRUE(rig.client_entry(kSrd, kClientSdo).valid()) << "released while the SRD was alive";
  EXPECT_TRUE(rig.client_entry(kSrd, 0x1281).valid()) << "released while the SRD was alive";
  DeviceFaults stop;
  stop.heartbeat_stops_at = rig.bus.now();
  rig.srd(kSrd).set_faults(stop);
  rig.run_for(5s);
  EXPECT_FALSE(rig.client_entry(kSrd, 0x1281).valid()) << "kept after the heartbeat stopped";
}

// §7.2.2 Error Control of Slave Devices and §7.2.3 Req EC / 1F11h: the SRD asks with 1F10h =
// xxxx0009h; a manager that supports it keeps bit 3 in the confirmation. "On a Error Control
// Error Event caused by the slave S, first the Manager reports the fail of slave S by writing to
// object 1F11h. Then the Client SDO entry which was assigned to the slave S is cleared on the
// SRD." 1F11h: reason 00h (heartbeat), slave node-ID.
TEST(SdoManagerSpec, ReqEcReportsASlaveHeartbeatLossIn1F11hThenClearsTheEntry) {
  ManagerRig rig;
  cfg::DeviceDescription eds = slave_channels_eds();
  set_value(eds, 0x1017, 0, 100);
  rig.consume_heartbeat(1, kWithChannels, 300);
  rig.start_network({kSrd}, eds);
  const auto confirmed = rig.register_srd(kSrd, state_word(kClientSdo, 0, kRq | kReqEc));
  ASSERT_EQ(cnxn_of(confirmed), 1U) << hex_text(confirmed);
  // §7.2.3: "If the SDO Manager supports this optional feature it will set this bit if it was
  // set before in the SRD registration request." This manager supports it (nmt_master.hpp).
  ASSERT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1) | kReqEc)) << hex_text(confirmed);
  rig.set_state(kSrd, 0);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd, kDefaultOnly, 0x1282);
  const TimePoint from = rig.bus.now();
  rig.unplug(kWithChannels);
  rig.run_for(5s);
  const auto failed = rig.writes_to(kSrd, kSlaveFailed, 0, from);
  ASSERT_FALSE(failed.empty()) << "1F11h not written";
  EXPECT_EQ(failed.front().value, 0x0000U << 8U | kWithChannels) << "reason 00h, slave 2";
  const auto cleared = rig.writes_to(kSrd, 0x1281, 1, from);
  ASSERT_FALSE(cleared.empty()) << "1281h sub 1 not cleared";
  EXPECT_NE(cleared.back().value & kNotValid, 0U);
  EXPECT_LT(failed.front().at, cleared.front().at) << "1F11h first, then the client entry";
  EXPECT_FALSE(rig.client_entry(kSrd, 0x1281).valid());
  EXPECT_TRUE(rig.client_entry(kSrd, 0x1282).valid()) << "node 3 is still there";
  EXPECT_EQ(rig.writes_to(kSrd, kSlaveFailed, 0, from).size(), 1U) << "one report for one failure";
}

// The scene of the next two tests: S is a booted slave whose heartbeat the master consumes
// (1016h: 300 ms; S's 1017h: 100 ms); SRD 126 holds S's default SDO while SRD 127 registers with
// Req EC and connects to S, so SRD 127 gets S's server channel 1201h; SRD 126 then lets S's
// default SDO go, so that S's next boot reaches S. That boot, asked by the application, fails
// with status C (1F84h expects another device type, §3.4 d): CiA 302-2 §3.4 and Table 1 end it
// without error control, so the master's own heartbeat consumer of S stops. Returns with S
// still on the bus, 1 s after the boot error.
void boot_of_a_watched_slave_fails(ManagerRig& rig) {
  cfg::DeviceDescription eds = slave_channels_eds();
  set_value(eds, 0x1017, 0, 100);
  rig.consume_heartbeat(1, kWithChannels, 300);
  rig.start_network({kSrd, kSrd2}, eds);
  rig.register_ok(kSrd2);
  const auto confirmed = rig.register_srd(kSrd, state_word(kClientSdo, 0, kRq | kReqEc));
  ASSERT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1) | kReqEc)) << hex_text(confirmed);
  rig.set_state(kSrd, 0);
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);  // S's default SDO
  rig.connect_ok(kSrd, kWithChannels, 0x1281);   // 1201h on S
  ASSERT_NE(rig.client_entry(kSrd, 0x1281).request, 0x600U + kWithChannels) << "S's default SDO";
  rig.release(kSrd2, request_word(0x1281, kSrd2, kWithChannels));
  ASSERT_TRUE(rig.client_entry(kSrd, 0x1281).valid());

  EXPECT_EQ(
      rig.engine().dictionary().write(0x1F84, kWithChannels, le(0x12345678, 4), rig.bus.now()),
      SdoAbort::None);
  const auto booted = rig.call([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.boot_slave(*cfg::NodeId::from(kWithChannels), now, out);
  });
  ASSERT_TRUE(booted.ok());
  ASSERT_TRUE(rig.run_until_event(
      [](const MasterEvent& e) {
        return e.kind == Kind::BootError && e.node_id == *cfg::NodeId::from(kWithChannels) &&
               e.error == BootError::C;
      },
      5s))
      << "S's boot did not fail with status C";
  rig.run_for(1s);
  EXPECT_TRUE(rig.writes_to(kSrd, kSlaveFailed, 0).empty()) << "1F11h while S is alive";
  ASSERT_TRUE(rig.client_entry(kSrd, 0x1281).valid());
}

// §7.2.2 ("On a Error Control Error Event caused by the slave S, first the Manager reports the
// fail of slave S by writing to object 1F11h") when the master no longer watches S itself: the
// manager watches S for the SRD, and when S leaves the bus, 1F11h reports it.
TEST(SdoManagerSpec, ReqEcReportsASlaveLostAfterItsBootFailedIn1F11h) {
  ManagerRig rig;
  ASSERT_NO_FATAL_FAILURE(boot_of_a_watched_slave_fails(rig));
  const TimePoint from = rig.bus.now();
  rig.unplug(kWithChannels);
  rig.run_for(5s);
  const auto failed = rig.writes_to(kSrd, kSlaveFailed, 0, from);
  ASSERT_EQ(failed.size(), 1U) << "1F11h not written once: the manager did not learn S is lost";
  EXPECT_EQ(failed.front().value, 0x0000U << 8U | kWithChannels) << "reason 00h, slave 2";
  // Heartbeat consumed at 300 ms (1016h), S's last heartbeat at most 100 ms before `from`.
  EXPECT_LE(failed.front().at - from, 300ms + 50ms) << "reported late";
  EXPECT_FALSE(rig.client_entry(kSrd, 0x1281).valid()) << "the client entry stays";
}

// The same loss as the master sees it: the master reports the heartbeat lost and S missing
// (1F82h), but its error handler (§4.2, DSP 302 §5.3) does not act on an error control the master
// no longer runs: for a mandatory S it would reset S (Table 12, 1F80h bit 4 clear) or all nodes.
TEST(SdoManagerSpec, MasterDoesNotHandleALossItWatchedOnlyForTheManager) {
  ManagerRig rig;
  rig.assign(kWithChannels, kSlave | kBoot | kMandatory);
  ASSERT_NO_FATAL_FAILURE(boot_of_a_watched_slave_fails(rig));
  const TimePoint from = rig.bus.now();
  rig.unplug(kWithChannels);
  rig.run_for(5s);
  EXPECT_EQ(rig.writes_to(kSrd, kSlaveFailed, 0, from).size(), 1U) << "1F11h";
  std::size_t lost = 0;
  for (const auto& e : rig.events_of(Kind::HeartbeatLost, kWithChannels)) {
    if (e.at >= from) ++lost;
  }
  EXPECT_EQ(lost, 1U) << "the loss is not reported";
  EXPECT_EQ(rig.engine().known_state(*cfg::NodeId::from(kWithChannels)), KnownState::missing());
  EXPECT_TRUE(rig.nmt(from).empty()) << "an NMT command after the loss: " << rig.nmt(from).front();
}

// ------------------------------------------------------------------------------------------------
// The manager's activity

// §7: "The SDO Manager is active only if the NMT Master residing on the same device is active."
// A flying master in standby (CiA 302-2 §5) does not answer the Dynamic SDO Request; once it
// took over it does.
TEST(SdoManagerSpec, StandbyFlyingMasterIgnoresTheDynamicSdoRequestUntilItIsActive) {
  ManagerRig rig;
  // CiA 302-2 §6.1 Table 15: NMT master taking part in the flying master process; the masters
  // produce heartbeats so that the standby one watches the active one (§5.5.2).
  auto flying = [](cfg::DeviceDescription dcf) {
    set_value(dcf, 0x1F80, 0, Startup::kMaster | Startup::kFlyingMaster);
    set_value(dcf, 0x1017, 0, 100);
    return dcf;
  };
  auto make = [&](const cfg::DeviceDescription& dcf, std::uint8_t node, bool sdo_manager,
                  std::uint16_t priority) {
    MasterOptions options;
    options.sdo_manager.enabled = sdo_manager;
    auto created = NmtMaster::create(dcf, *cfg::NodeId::from(node), options);
    EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
    if (!created.ok()) throw std::runtime_error("NmtMaster::create failed");
    auto m = std::make_unique<SimEngineNode<NmtMaster>>(std::move(created).value());
    EXPECT_EQ(m->engine().dictionary().write(0x1F90, 3, le(priority, 2), rig.bus.now()),
              SdoAbort::None);
    rig.bus.attach(*m);
    m->apply([](NmtMaster& e, TimePoint now, NmtMaster::Output& out) { e.start(now, out); });
    return m;
  };
  rig.add_slave(kWithChannels, {}, slave_channels_eds());
  rig.add_slave(kDefaultOnly);
  rig.add_srd(kSrd);
  rig.power_on_slaves();
  rig.run_for(50ms);
  // Node 1 (priority 0) without an SDO manager (master.dcf has no 1F00h) becomes the active
  // master; node 5 (priority 1) with the manager stands by.
  auto active = make(flying(master_dcf()), 1, false, 0);
  rig.run_for(5s);
  auto standby = make(flying(manager_dcf()), 5, true, 1);
  ASSERT_TRUE(rig.bus.run_until(
      [&] {
        return standby->engine().startup_state() == StartupState::Standby &&
               active->engine().startup_state() == StartupState::Operational;
      },
      rig.bus.now() + 30s))
      << "node 1 active with node 5 standing by was not reached";

  TimePoint from = rig.bus.now();
  rig.set_state(kSrd, state_word(kClientSdo, 0, kRq));
  rig.send_foreign(kDynamicSdoRequestFrame);
  rig.run_for(3s);
  EXPECT_TRUE(rig.uploads_of(kSrd, kConnectionState, 0, from).empty())
      << "a master scanned: " << rig.uploads_of(kSrd, kConnectionState, 0, from).front();
  EXPECT_EQ(rig.srd_value(kSrd, kConnectionState, 0), state_word(kClientSdo, 0, kRq));

  // Node 1 dies: node 5 takes over (CiA 302-2 §5.5.2) and then serves the request.
  rig.bus.detach(*active);
  ASSERT_TRUE(rig.bus.run_until(
      [&] { return standby->engine().startup_state() == StartupState::Operational; },
      rig.bus.now() + 30s))
      << "node 5 did not take over";
  from = rig.bus.now();
  const auto confirmed = rig.register_srd(kSrd);
  EXPECT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1))) << hex_text(confirmed);
  EXPECT_EQ(rig.client_entry(kSrd, kClientSdo).server, 5U) << "the channel leads to node 5";
  // The one Dynamic SDO Request is served by one scan of the SRD's 1F10h.
  EXPECT_EQ(rig.uploads_of(kSrd, kConnectionState, 0, from).size(), 1U);
}

// Without the SDO manager (MasterOptions::sdo_manager.enabled false and no 1F00h in the DCF) the
// Dynamic SDO Request is not answered: the guideline-1 case of §7.2.4.
TEST(SdoManagerSpec, MasterWithoutSdoManagerDoesNotScan) {
  ManagerRig rig;
  rig.master = master_dcf();
  rig.options.sdo_manager.enabled = false;
  rig.start_network();
  const TimePoint from = rig.bus.now();
  rig.set_state(kSrd, state_word(kClientSdo, 0, kRq));
  rig.send_foreign(kDynamicSdoRequestFrame);
  rig.run_for(10s);
  EXPECT_TRUE(rig.uploads_of(kSrd, kConnectionState, 0, from).empty());
  EXPECT_EQ(rig.srd_value(kSrd, kConnectionState, 0), state_word(kClientSdo, 0, kRq));
}

// §7.2.3: "The time-outs used have to take into account that the Manager has to do several SDO
// accesses": with 1% of the frames lost (any frame, the boot's included), registration and a
// connection still complete. The SRD repeats what an SRD may repeat: its Dynamic SDO Request when
// no confirmation came (§7.2.4 guideline 1), and its 1F00h write when its SDO transfer failed and
// no 1F10h came.
TEST(SdoManagerSpec, RegistrationAndConnectionCompleteWithOnePercentFrameLoss) {
  for (std::uint64_t seed : {1U, 2U, 3U, 4U}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    ManagerRig rig;
    rig.bus.set_loss_rate(0.01, seed);
    rig.start_network({kSrd, kSrd2});
    for (auto srd : {kSrd, kSrd2}) {
      std::uint32_t state = state_word(kClientSdo, 0, kRq);
      for (int attempt = 0; attempt < 5 && state == state_word(kClientSdo, 0, kRq); ++attempt) {
        state = rig.register_srd(srd, state_word(kClientSdo, 0, kRq), 15s);
      }
      ASSERT_EQ(state, state_word(kClientSdo, 0, cnxn(1))) << "SRD " << int{srd};
      rig.set_state(srd, 0);
    }
    constexpr std::uint16_t index = 0x1281;
    auto connect = [&](std::uint8_t srd, std::uint8_t slave) {
      std::uint32_t state = 0;
      for (int attempt = 0; attempt < 5 && state == 0; ++attempt) {
        auto r = rig.srd_transfer(srd, kClientSdo, false, kRequestSdo, 0,
                                  le(request_word(index, srd, slave), 4));
        ASSERT_TRUE(r.has_value());
        state = rig.await_state(srd, 0, 10s);
      }
      EXPECT_EQ(state, state_word(index, 0, cnxn(3))) << "SRD " << int{srd};
      rig.set_state(srd, 0);
    };
    connect(kSrd, kWithChannels);
    connect(kSrd2, kDefaultOnly);
    // Both connections work (a lost frame costs the SRD one retry of its own).
    for (auto srd : {kSrd, kSrd2}) {
      std::optional<SdoResult> read;
      for (int attempt = 0; attempt < 3 && !(read && read->ok()); ++attempt) {
        read = rig.srd_transfer(srd, 0x1281, true, 0x1018, 1);
      }
      ASSERT_TRUE(read.has_value());
      EXPECT_TRUE(read->ok()) << "SRD " << int{srd} << ": " << read->abort;
      EXPECT_EQ(value_of(read->data), kVendor);
    }
  }
}

}  // namespace
}  // namespace nmt::master_spec
