// The SDO manager of NmtMaster (dynamic establishment of SDO connections) against CiA DSP 302
// v3.2.1 §7 (../shared/spec/001_846495643a25878e.txt) and the decisions every helper shares
// (DSP 302 §7.2.3 word layouts; 1F03h-1F06h read-only with 254 rows). Written from the spec and
// the public headers only, not from the engine's sources or its own tests: an NmtMaster with its
// SDO manager, simulated slaves and SDO requesting devices (SRDs) on one 500 kbit/s simulated bus
// with simulated time. Helpers come from nmt_master_spec_test_rig.hpp.
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
#include "test_paths.hpp"

namespace nmt::master_spec {
namespace {

using Kind = MasterEvent::Kind;

constexpr std::uint8_t kSrd = 127;         // §7.2.4 guideline 2: SRDs take the highest node-IDs
constexpr std::uint8_t kSrd2 = 126;        // a second SRD
constexpr std::uint8_t kSrd3 = 124;        // a third SRD
constexpr std::uint8_t kWithChannels = 2;  // slave_channels.eds: 1201h, 1202h
constexpr std::uint8_t kDefaultOnly = 3;   // slave.eds: 1200h only

// §7.2.1: "the Dynamic SDO Request ... is a data frame without data bytes. The COB-ID is 1760d."
constexpr std::uint32_t kDynamicSdoRequest = 1760;
static_assert(kDynamicSdoRequest == 0x6E0);
constexpr const char* kDynamicSdoRequestFrame = "6E0#";

// Object indices of §7.2.3 and CiA 301 (SDO parameters).
constexpr std::uint16_t kRequestSdo = 0x1F00;
constexpr std::uint16_t kReleaseSdo = 0x1F01;
constexpr std::uint16_t kPool = 0x1F02;
constexpr std::uint16_t kConnections = 0x1F03;
constexpr std::uint16_t kConnectionState = 0x1F10;
constexpr std::uint16_t kSlaveFailed = 0x1F11;
constexpr std::uint16_t kServerSdo = 0x1200;
constexpr std::uint16_t kClientSdo = 0x1280;

// 1F10h (§7.2.3): bits 31-16 index, 15-8 error code, bit 3 Req EC, bits 2-1 Cnxn state, bit 0 Rq
// indication, bits 7-4 reserved (0).
constexpr std::uint32_t kRq = 1U << 0U;
constexpr std::uint32_t kReqEc = 1U << 3U;
constexpr std::uint32_t cnxn(unsigned state) {
  return (state & 3U) << 1U;
}
constexpr std::uint32_t state_word(std::uint16_t index, std::uint8_t error, std::uint32_t bits) {
  return std::uint32_t{index} << 16U | std::uint32_t{error} << 8U | bits;
}
constexpr unsigned cnxn_of(std::uint32_t word) {
  return (word >> 1U) & 3U;
}
constexpr std::uint8_t error_of(std::uint32_t word) {
  return static_cast<std::uint8_t>(word >> 8U);
}
constexpr std::uint16_t index_of(std::uint32_t word) {
  return static_cast<std::uint16_t>(word >> 16U);
}
// §7.2.3 examples: xxxx0001h a request, xxxx0009h a request with Req EC, 00000003h all default
// SDOs.
static_assert(state_word(0x1280, 0, kRq) == 0x12800001);
static_assert(state_word(0x1280, 0, kRq | kReqEc) == 0x12800009);
static_assert(state_word(0, 0, kRq | cnxn(1)) == 0x00000003);

// 1F00h / 1F01h (§7.2.3): bits 31-16 the SRD's client SDO index, 15-8 SRD node-ID, 7-0 slave.
constexpr std::uint32_t request_word(std::uint16_t index, std::uint8_t srd, std::uint8_t slave) {
  return std::uint32_t{index} << 16U | std::uint32_t{srd} << 8U | slave;
}
// 1F03h row (§7.2.3): client offset (from 1280h), client node-ID, server offset (from 1200h),
// server node-ID.
constexpr std::uint32_t row_word(std::uint8_t client_offset, std::uint8_t client,
                                 std::uint8_t server_offset, std::uint8_t server) {
  return std::uint32_t{client_offset} << 24U | std::uint32_t{client} << 16U |
         std::uint32_t{server_offset} << 8U | server;
}

// 1F02h entries (§7.2.3): bit 31 not valid, bit 30 in use, bit 29 29-bit identifier.
constexpr std::uint32_t kNotValid = 0x80000000U;
constexpr std::uint32_t kInUse = 0x40000000U;
constexpr std::uint32_t kIdBits = 0x1FFFFFFFU;
constexpr std::uint8_t kPoolEntries = 9;         // manager.dcf 1F02h sub 0
constexpr std::uint32_t kInvalidPoolId = 0x689;  // sub 9, bit 31 set in the file

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
    options.sdo_manager = true;
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
        [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output&) { d.power_on(now); });
    return slot->engine();
  }
  SimulatedDevice& srd(std::uint8_t node) { return srds_.at(node)->engine(); }
  void unplug_srd(std::uint8_t node) { bus.detach(*srds_.at(node)); }
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

  /// The COB-IDs and node-ID of the SRD's client entry `index` (CiA 301 1280h sub 1..3).
  struct ClientEntry {
    std::uint32_t request;   // sub 1, client -> server
    std::uint32_t response;  // sub 2, server -> client
    std::uint8_t server;     // sub 3
    bool valid() const { return (request & kNotValid) == 0 && (response & kNotValid) == 0; }
  };
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
    config.node_id = entry.server;
    SimEngineNode<SdoClient> client(config);
    std::optional<SdoResult> result;
    client.set_event_handler([&](const SdoResult& r, TimePoint) { result = r; });
    bus.attach(client);
    client.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
      return upload ? c.upload(object, sub, now, out) : c.download(object, sub, data, now, out);
    });
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
  /// request() expecting §7.2.3's refusal: Cnxn 0 with `error`; the client entry stays invalid and
  /// no COB-ID of the pool stays allocated for it.
  void refused(std::uint8_t node, std::uint8_t slave, std::uint16_t index, std::uint8_t error,
               Duration limit = 20s) {
    const auto before = in_use(pool());
    const auto state = request(node, slave, index, limit);
    EXPECT_EQ(cnxn_of(state), 0U) << "1F10h = " << hex_text(state);
    EXPECT_EQ(error_of(state), error) << "1F10h = " << hex_text(state);
    EXPECT_FALSE(client_entry(node, index).valid());
    EXPECT_EQ(in_use(pool()), before) << "no COB-ID stays allocated";
  }
  /// 1F01h from SRD `node`, then runs `settle`.
  void release(std::uint8_t node, std::uint32_t word, Duration settle = 5s) {
    EXPECT_EQ(srd_write_manager(node, kReleaseSdo, word), SdoAbort::None);
    run_for(settle);
  }

  /// Expedited writes the manager sent to `node`'s default SDO, from `from` on.
  std::vector<Write> writes_to(std::uint8_t node, TimePoint from = TimePoint{0}) const {
    std::vector<Write> out;
    for (const auto& s : requests_to(node, from)) {
      if (auto w = expedited_write(s)) out.push_back(*w);
    }
    return out;
  }
  std::vector<Write> writes_to(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                               TimePoint from = TimePoint{0}) const {
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
  /// The pool entry carrying identifier `id` (bits 28-0); nullopt when none does.
  static std::optional<std::uint32_t> pool_entry(const std::vector<std::uint32_t>& pool,
                                                 std::uint32_t id) {
    for (auto e : pool) {
      if ((e & kIdBits) == (id & kIdBits)) return e;
    }
    return std::nullopt;
  }
  /// Both COB-IDs of `entry` come from `pool`, valid, with bit 30 (in use) as `in_use`.
  static void expect_pool_entries(const std::vector<std::uint32_t>& pool, const ClientEntry& entry,
                                  bool in_use) {
    for (auto id : {entry.request, entry.response}) {
      auto e = pool_entry(pool, id);
      ASSERT_TRUE(e.has_value()) << hex_text(id) << " is not from 1F02h";
      EXPECT_EQ(*e & (kNotValid | kInUse), in_use ? kInUse : 0U) << "1F02h entry " << hex_text(*e);
    }
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
  static bool has_row(const std::vector<std::uint32_t>& rows, std::uint32_t row) {
    return std::find(rows.begin(), rows.end(), row) != rows.end();
  }

  /// The manager's own server channel (1201h..127Fh) whose sub 1/2 are `entry`'s COB-IDs.
  std::optional<std::uint16_t> manager_channel_of(const ClientEntry& entry) {
    for (std::uint16_t index = 0x1201; index <= 0x127F; ++index) {
      auto sub1 = engine().dictionary().get_unsigned(index, 1);
      auto sub2 = engine().dictionary().get_unsigned(index, 2);
      if (sub1 && sub2 && *sub1 == entry.request && *sub2 == entry.response) return index;
    }
    return std::nullopt;
  }

 private:
  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<SimulatedDevice>>> srds_;
};

// The position of the first write to (index, sub) (with `value`, when given) in `writes`; -1
// when there is none.
std::ptrdiff_t position_of(const std::vector<Write>& writes, std::uint16_t index, std::uint8_t sub,
                           std::optional<std::uint32_t> value = std::nullopt) {
  for (std::size_t i = 0; i < writes.size(); ++i) {
    if (writes[i].index == index && writes[i].sub == sub && (!value || writes[i].value == *value)) {
      return static_cast<std::ptrdiff_t>(i);
    }
  }
  return -1;
}

// ------------------------------------------------------------------------------------------------
// §7.2.1 registration

// §7.2.1: "After receiving such a request, the SDO Manager scans the network ... reads the object
// 1F10h ... of all possible Node-IDs which are not yet registered"; §7.2.4 guideline 2: the scan
// starts at 127 and goes down; "It stops the scan at the first unregistered SRD it finds."
TEST(SdoManagerSpec, DynamicSdoRequestScans1F10hFrom127DownAndStopsAtTheFirstOpenRequest) {
  ManagerRig rig;
  constexpr std::uint8_t kLowSrd = 125;  // 127 and 126 are not on the bus
  rig.start_network({kLowSrd});
  const TimePoint from = rig.bus.now();
  const auto confirmed = rig.register_srd(kLowSrd);
  EXPECT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1))) << hex_text(confirmed);
  rig.run_for(2s);
  std::vector<std::uint8_t> scanned;
  for (std::uint8_t node = 1; node <= 127; ++node) {
    if (!rig.uploads_of(node, kConnectionState, 0, from).empty()) scanned.push_back(node);
  }
  EXPECT_EQ(scanned, (std::vector<std::uint8_t>{125, 126, 127}));
  const auto at = [&](std::uint8_t node) {
    auto u = rig.uploads_of(node, kConnectionState, 0, from);
    return u.empty() ? TimePoint::max() : u.front().at;
  };
  EXPECT_LT(at(127), at(126));
  EXPECT_LT(at(126), at(125));
}

// §7.2.1: "As all nodes are attached to the Manager by default, the Manager uses the default SDO.
// The Manager knows all default SDOs which are already allocated to other nodes": the scan does
// not read 1F10h over a default SDO an SRD holds (node 125's, held by SRD 126), nor that of a
// registered SRD.
TEST(SdoManagerSpec, ScanSkipsDefaultSdosHeldByAConnection) {
  ManagerRig rig;
  constexpr std::uint8_t kHeld = 125;  // a device outside 1F81h, reached through the manager
  rig.add_slave(kHeld);
  rig.start_network({kSrd2, kSrd3});
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd2, kHeld, 0x1281);
  ASSERT_EQ(rig.client_entry(kSrd2, 0x1281).request, 0x600U + kHeld);
  const TimePoint from = rig.bus.now();
  rig.register_ok(kSrd3);
  EXPECT_TRUE(rig.uploads_of(kHeld, kConnectionState, 0, from).empty())
      << "1F10h read over node 125's default SDO, which SRD 126 holds";
  EXPECT_TRUE(rig.uploads_of(kSrd2, kConnectionState, 0, from).empty())
      << "registered node 126 read again";
  EXPECT_FALSE(rig.uploads_of(kSrd, kConnectionState, 0, from).empty()) << "127 was not scanned";
}

// §7.2.1: the scan uses SDO access and stops at the first open request: a second SRD with an
// open request is not registered by the same Dynamic SDO Request, only by its own.
TEST(SdoManagerSpec, OneDynamicSdoRequestRegistersOnlyTheFirstSrdFound) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.set_state(kSrd2, state_word(kClientSdo, 0, kRq));
  const TimePoint from = rig.bus.now();
  rig.register_ok(kSrd);
  rig.run_for(3s);
  EXPECT_TRUE(rig.uploads_of(kSrd2, kConnectionState, 0, from).empty())
      << "the scan went on past node 127, which had an open request";
  EXPECT_EQ(rig.srd_value(kSrd2, kConnectionState, 0), state_word(kClientSdo, 0, kRq));
  // Its own request: the scan skips the registered node 127 ("not yet registered").
  const TimePoint second = rig.bus.now();
  rig.register_ok(kSrd2);
  EXPECT_TRUE(rig.uploads_of(kSrd, kConnectionState, 0, second).empty())
      << "node 127 is registered and is not read again";
}

// §7.2.1: "the Manager uses the value OD Index from the object 1F10h and enables this entry in
// the 'Client SDO parameter' table. Afterwards the object 1F10h is reset by the Manager";
// §7.2.3: the confirmation has Cnxn state 1, Rq indication 0 and the index of the entry.
TEST(SdoManagerSpec, RegistrationEnablesTheClientEntryNamedIn1F10hThenConfirms) {
  ManagerRig rig;
  rig.start_network();
  const TimePoint from = rig.bus.now();
  constexpr std::uint16_t kEntry = 0x1282;  // not the first one: the manager takes the one named
  const auto confirmed = rig.register_srd(kSrd, state_word(kEntry, 0, kRq));
  EXPECT_EQ(confirmed, state_word(kEntry, 0, cnxn(1))) << hex_text(confirmed);

  const auto entry = rig.client_entry(kSrd, kEntry);
  EXPECT_TRUE(entry.valid()) << hex_text(entry.request) << " " << hex_text(entry.response);
  EXPECT_EQ(entry.server, kMaster) << "1282h sub 3: the node-ID of the server, the manager";
  EXPECT_NE(entry.request & kIdBits, entry.response & kIdBits);
  for (const std::uint16_t other :
       {std::uint16_t{0x1280}, std::uint16_t{0x1281}, std::uint16_t{0x1283}}) {
    EXPECT_FALSE(rig.client_entry(kSrd, other).valid()) << hex_text(other) << " was not named";
  }
  // The client entry before the confirmation (the SRD may use the channel once confirmed).
  const auto writes = rig.writes_to(kSrd, from);
  const auto confirm_at = position_of(writes, kConnectionState, 0, confirmed);
  ASSERT_GE(confirm_at, 0) << "no expedited write of 1F10h";
  for (const std::uint8_t sub : {std::uint8_t{1}, std::uint8_t{2}, std::uint8_t{3}}) {
    const auto at = position_of(writes, kEntry, sub);
    EXPECT_GE(at, 0) << "1282h sub " << int{sub} << " not written";
    EXPECT_LT(at, confirm_at) << "1282h sub " << int{sub} << " written after the confirmation";
  }
}

// §7.2.1: "The described registration process results in a SDO connection from the SRD
// (Client) to the SDO-Manager (Server)"; §7.2.3 1F02h: the manager takes its COB-IDs from the
// pool and sets bit 30 ("is actually in use") on the entries it allocates.
TEST(SdoManagerSpec, RegistrationChannelUsesTwoPoolCobIdsMarkedInUseAndServesTheSrd) {
  ManagerRig rig;
  rig.start_network();
  EXPECT_EQ(ManagerRig::in_use(rig.pool()), 0U) << "nothing allocated before a registration";
  rig.register_ok(kSrd);
  const auto entry = rig.client_entry(kSrd, kClientSdo);
  const auto pool = rig.pool();
  ASSERT_EQ(pool.size(), kPoolEntries);
  ManagerRig::expect_pool_entries(pool, entry, true);
  for (auto id : {entry.request, entry.response}) {
    EXPECT_NE(id & kIdBits, kInvalidPoolId) << "an entry marked not valid was used";
  }
  EXPECT_EQ(ManagerRig::in_use(pool), 2U);
  // The manager serves the SRD on one of its own additional server channels with these COB-IDs.
  auto channel = rig.manager_channel_of(entry);
  ASSERT_TRUE(channel.has_value()) << "no server channel 1201h.. of the manager has the COB-IDs";
  EXPECT_EQ(rig.engine().dictionary().get_unsigned(*channel, 3), kSrd)
      << "sub 3: the node-ID of the client";
  // And answers over it: 1F00h is write-only (§7.2.3: wo), 1F02h is readable.
  rig.expect_read(kSrd, kClientSdo, kPool, 0, kPoolEntries);
}

// §7.2.3 1F02h: bit 29 set marks a 29-bit identifier (CAN 2.0B) with bits 28-0 the COB-ID. With
// only such entries valid, the SRD's channel to the manager runs on extended frames.
TEST(SdoManagerSpec, PoolEntriesWith29BitIdentifiersGiveAnExtendedChannel) {
  ManagerRig rig;
  constexpr std::uint32_t k29Bit = 0x20000000U;
  set_value(rig.master, kPool, 1, k29Bit | 0x1234567U);
  set_value(rig.master, kPool, 2, k29Bit | 0x1234568U);
  for (std::uint8_t sub = 3; sub <= 8; ++sub) {
    set_value(rig.master, kPool, sub, kNotValid | (0x680U + sub));
  }
  rig.start_network();
  rig.register_ok(kSrd);
  const auto entry = rig.client_entry(kSrd, kClientSdo);
  EXPECT_EQ((std::set<std::uint32_t>{entry.request, entry.response}),
            (std::set<std::uint32_t>{k29Bit | 0x1234567U, k29Bit | 0x1234568U}));
  const TimePoint from = rig.bus.now();
  rig.expect_read(kSrd, kClientSdo, kPool, 0, kPoolEntries);
  std::size_t extended = 0;
  for (const auto& s : rig.seen) {
    if (s.at >= from && s.frame.extended) {
      EXPECT_TRUE(s.frame.id == 0x1234567U || s.frame.id == 0x1234568U) << s;
      ++extended;
    }
  }
  EXPECT_EQ(extended, 2U) << "the request and its answer, as extended frames";
}

// §7.2.2 "Requesting Access to all default SDOs" and §7.2.3 Cnxn state 2: 1F10h = 00000003h is
// granted with Cnxn 2 when all default SDOs are unused; "In this case the Manager does not have
// to set-up any SDOs on the slaves and on the SRD".
TEST(SdoManagerSpec, AllDefaultSdosRequestIsConfirmedWithCnxn2AndNoClientEntry) {
  ManagerRig rig;
  rig.start_network();
  const TimePoint from = rig.bus.now();
  const auto confirmed = rig.register_srd(kSrd, 0x00000003);
  EXPECT_EQ(cnxn_of(confirmed), 2U) << hex_text(confirmed);
  EXPECT_EQ(confirmed & kRq, 0U) << hex_text(confirmed);
  EXPECT_EQ(error_of(confirmed), 0U) << hex_text(confirmed);
  rig.run_for(1s);
  for (std::uint16_t index = 0x1280; index <= 0x1283; ++index) {
    EXPECT_FALSE(rig.client_entry(kSrd, index).valid()) << hex_text(index);
    EXPECT_LT(position_of(rig.writes_to(kSrd, from), index, 1), 0) << hex_text(index);
  }
  EXPECT_TRUE(rig.all_downloads(kWithChannels, from).empty()) << "nothing is written to slaves";
  EXPECT_TRUE(rig.all_downloads(kDefaultOnly, from).empty()) << "nothing is written to slaves";
  EXPECT_EQ(ManagerRig::in_use(rig.pool()), 0U);
}

// §7.2.3 Cnxn state 2 needs "all default SDOs in the system are unused": with a slave's default
// SDO held by a connection the grant cannot be given.
TEST(SdoManagerSpec, AllDefaultSdosAreNotGrantedWhileOneIsHeld) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);
  const auto answer = rig.register_srd(kSrd, 0x00000003);
  EXPECT_NE(answer, 0x00000003U) << "the manager did not answer";
  EXPECT_NE(cnxn_of(answer), 2U) << hex_text(answer);
}

// §7.2.4 guideline 4: "If the SDO Manager assigned all default SDOs to the SRD ..., it has to
// assume that the SDOs remain in the SRDs ownership": another SRD's connection to a slave is then
// not put on the slave's default SDO (an additional server channel, or a refusal).
TEST(SdoManagerSpec, DefaultSdosOfAnOwnerOfAllAreNotGivenToAnotherSrd) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd2);
  ASSERT_EQ(cnxn_of(rig.register_srd(kSrd, 0x00000003)), 2U);
  const auto state = rig.request(kSrd2, kWithChannels, 0x1281);
  const auto entry = rig.client_entry(kSrd2, 0x1281);
  if (cnxn_of(state) == 3) {
    EXPECT_NE(entry.request, 0x600U + kWithChannels) << "the default SDO belongs to node 127";
    EXPECT_EQ(rig.device_value(kWithChannels, 0x1201, 1), entry.request);
  } else {
    EXPECT_EQ(cnxn_of(state), 0U) << hex_text(state);
    EXPECT_FALSE(entry.valid());
  }
}

// ------------------------------------------------------------------------------------------------
// §7.2.2 requesting connections

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

// §7.1: "If this is occupied it will check the object dictionary of S for free additional SDOs
// (objects 1200h et sqq.). It then establishes the connection by writing into ... the free Client
// SDO table entry on the SRD and 1200h et sqq. of S", with two COB-IDs of 1F02h marked in use.
TEST(SdoManagerSpec, SecondSrdGetsAnAdditionalServerChannelWithPoolCobIds) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  const auto state = rig.request(kSrd2, kWithChannels, 0x1283);
  EXPECT_EQ(state, state_word(0x1283, 0, cnxn(3))) << hex_text(state);
  const auto entry = rig.client_entry(kSrd2, 0x1283);
  EXPECT_TRUE(entry.valid());
  EXPECT_EQ(entry.server, kWithChannels);
  // The slave's first additional server channel: the same COB-IDs, sub 3 the SRD (CiA 301).
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1201, 1), entry.request);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1201, 2), entry.response);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1201, 3), kSrd2);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1202, 1).value_or(0) & kNotValid, kNotValid)
      << "only one channel is needed";
  const auto pool = rig.pool();
  ManagerRig::expect_pool_entries(pool, entry, true);
  EXPECT_EQ(ManagerRig::in_use(pool), 6U) << "two registrations and this connection";
  // Both connections hold at once.
  EXPECT_EQ(rig.client_entry(kSrd, 0x1281).request, 0x600U + kWithChannels);
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

// §7.1: "free additional SDOs": a server channel already valid on the slave (bit 31 of sub 1
// clear, CiA 301) is in use and is skipped.
TEST(SdoManagerSpec, AServerChannelInUseOnTheSlaveIsSkipped) {
  ManagerRig rig;
  cfg::DeviceDescription eds = slave_channels_eds();
  set_value(eds, 0x1201, 1, 0x6A0);  // configured by someone else (outside the pool)
  set_value(eds, 0x1201, 2, 0x6A1);
  rig.start_network({kSrd, kSrd2}, eds);
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);
  const auto entry = rig.client_entry(kSrd2, 0x1281);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1201, 1), 0x6A0U) << "the channel in use is kept";
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1202, 1), entry.request);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1202, 2), entry.response);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1202, 3), kSrd2);
}

// §7.2.3 error code 03h "No more free server SDO entries on slave S": node 3 has only its
// default SDO, which SRD 127 holds.
TEST(SdoManagerSpec, SlaveWithoutAFreeServerChannelGivesError03h) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kDefaultOnly, 0x1281);
  rig.refused(kSrd2, kDefaultOnly, 0x1281, 0x03);
}

// The same when the slave has additional channels but all are in use: 1201h is configured by
// someone else (valid, outside the pool), 1202h is taken by SRD 126; the pool still has two free
// COB-IDs.
TEST(SdoManagerSpec, SlaveWithAllServerChannelsInUseGivesError03h) {
  ManagerRig rig;
  cfg::DeviceDescription eds = slave_channels_eds();
  set_value(eds, 0x1201, 1, 0x6A0);
  set_value(eds, 0x1201, 2, 0x6A1);
  rig.start_network({kSrd, kSrd2}, eds);
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);   // default SDO
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);  // 1202h
  ASSERT_EQ(ManagerRig::in_use(rig.pool()), 6U);
  rig.refused(kSrd2, kWithChannels, 0x1282, 0x03);
}

// §7.2.3 error code 02h "No more free SDO channels available in the network": the pool (1F02h)
// has four valid entries; two registrations take them all. An entry marked not valid (bit 31)
// is never allocated.
TEST(SdoManagerSpec, ExhaustedPoolGivesError02h) {
  ManagerRig rig;
  for (std::uint8_t sub = 5; sub <= 8; ++sub)
    set_value(rig.master, kPool, sub, kNotValid | (0x680U + sub));
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);  // the default SDO needs no COB-ID
  rig.refused(kSrd2, kWithChannels, 0x1281, 0x02);
  EXPECT_EQ(rig.device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, kNotValid);
  // Entries 5-8 (685h-688h) are not valid: never given out, to the slave or to an SRD.
  for (auto node : {kWithChannels, kSrd, kSrd2}) {
    for (const auto& w : rig.writes_to(node)) {
      const bool cob_id = (w.index >= 0x1200 && w.index <= 0x12FF) && (w.sub == 1 || w.sub == 2);
      if (cob_id) {
        EXPECT_FALSE((w.value & kIdBits) >= 0x685 && (w.value & kIdBits) <= 0x689)
            << "node " << int{node} << " got " << hex_text(w.value) << " from a not-valid entry";
      }
    }
  }
}

// §7.2.3 error code 01h "No SDO channel free for connection from SRD to SDO manager": with one
// own server channel for SRDs, the second SRD cannot register.
TEST(SdoManagerSpec, NoFreeManagerChannelGivesRegistrationError01h) {
  ManagerRig rig;
  rig.options.sdo_manager_channels = 1;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  const auto state = rig.register_srd(kSrd2);
  EXPECT_EQ(cnxn_of(state), 0U) << hex_text(state);
  EXPECT_EQ(error_of(state), 0x01) << hex_text(state);
  EXPECT_FALSE(rig.client_entry(kSrd2, kClientSdo).valid());
}

// §7.2.3 error code 04h "Slave S not available": the manager must configure an additional
// channel on the slave (its default SDO is held) and the slave does not answer.
TEST(SdoManagerSpec, SilentSlaveGivesError04h) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.unplug(kWithChannels);
  rig.refused(kSrd2, kWithChannels, 0x1281, 0x04, 30s);
}

// §7.2.3: "If the Manager refuses the request this will be done by the Service 'Abort domain
// transfer' with abort code 060A 0023h"; "Any registered SRD may write to one of those objects":
// a node that is not registered is refused.
TEST(SdoManagerSpec, RequestFromAnUnregisteredNodeIsAborted060A0023) {
  ManagerRig rig;
  rig.start_network({kSrd});
  // Node 127 writes over the manager's default SDO without registering first.
  EXPECT_EQ(rig.tool_write_u(kRequestSdo, 0, request_word(0x1281, kSrd, kWithChannels), 4),
            SdoAbort::ResourceNotAvailable);
  rig.run_for(2s);
  EXPECT_FALSE(rig.client_entry(kSrd, 0x1281).valid());
}

// §7.2.3: "The requested Node-ID must not be 0."
TEST(SdoManagerSpec, RequestForSlave0IsAborted060A0023) {
  ManagerRig rig;
  rig.start_network();
  rig.register_ok(kSrd);
  EXPECT_EQ(rig.srd_write_manager(kSrd, kRequestSdo, request_word(0x1281, kSrd, 0)),
            SdoAbort::ResourceNotAvailable);
}

// §7.2.3 1F00h bits 15-8 "the SRD's Node-ID": a registered SRD asking in another node's name
// over its own channel is refused.
TEST(SdoManagerSpec, RequestInAnotherSrdsNameIsAborted060A0023) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  EXPECT_EQ(rig.srd_write_manager(kSrd, kRequestSdo, request_word(0x1281, kSrd2, kWithChannels)),
            SdoAbort::ResourceNotAvailable);
  rig.run_for(2s);
  EXPECT_FALSE(rig.client_entry(kSrd2, 0x1281).valid());
}

// §7.2.3: 1F00h and 1F01h are wo; 1F03h-1F06h are ro ("The SDO Connections table is ro"), 254
// rows in part 1.
TEST(SdoManagerSpec, ObjectAccessIsAsTheSpecTablesSay) {
  ManagerRig rig;
  rig.start_network();
  EXPECT_EQ(rig.tool_read(kRequestSdo, 0).abort, SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(rig.tool_read(kReleaseSdo, 0).abort, SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(rig.tool_read_u(kConnections, 0), 254U);
  EXPECT_EQ(rig.tool_write_u(kConnections, 1, row_word(1, kSrd, 0, 2), 4),
            SdoAbort::WriteOfReadOnly);
  EXPECT_EQ(rig.tool_read_u(kConnections, 1), 0U) << "no connection yet, and the write failed";
  EXPECT_EQ(rig.tool_read_u(kPool, 1), 0x681U) << "1F02h as the DCF configured it";
}

// §7.2.3 1F03h rows: client offset (from 1280h), client node-ID, server offset (from 1200h),
// server node-ID, one per running connection.
TEST(SdoManagerSpec, ConnectionTableRowsFollowTheSpecLayout) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);   // default SDO: server offset 0
  rig.connect_ok(kSrd2, kWithChannels, 0x1283);  // 1201h: server offset 1
  const auto rows = rig.rows();
  EXPECT_TRUE(ManagerRig::has_row(rows, row_word(0x01, kSrd, 0x00, kWithChannels)))
      << "no row 017F0002h";
  EXPECT_TRUE(ManagerRig::has_row(rows, row_word(0x03, kSrd2, 0x01, kWithChannels)))
      << "no row 037E0102h";
  // Rows of connections to the manager itself name its own channel.
  for (auto row : rows) {
    if ((row & 0xFF) != kMaster) continue;
    const std::uint8_t client = (row >> 16U) & 0xFF;
    const auto entry = rig.client_entry(client, static_cast<std::uint16_t>(0x1280 + (row >> 24U)));
    EXPECT_EQ(rig.manager_channel_of(entry), 0x1200 + ((row >> 8U) & 0xFF)) << hex_text(row);
  }
}

// ------------------------------------------------------------------------------------------------
// §7.2.2 / §7.2.3 releasing

// §7.2.3 1F01h: "If the value points to a valid SDO connection, this connection is released";
// the SRD observes the release in 1280h-12FFh; 1F02h bit 30 is reset "if the corresponding SDO
// connection is released"; the row is freed.
TEST(SdoManagerSpec, ReleaseByIndexInvalidatesBothSidesAndFreesItsPoolEntries) {
  ManagerRig rig;
  rig.start_network({kSrd, kSrd2});
  rig.register_ok(kSrd);
  rig.register_ok(kSrd2);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd2, kWithChannels, 0x1281);
  const auto entry = rig.client_entry(kSrd2, 0x1281);
  ASSERT_EQ(ManagerRig::in_use(rig.pool()), 6U);
  rig.release(kSrd2, request_word(0x1281, kSrd2, kWithChannels));
  const auto after = rig.client_entry(kSrd2, 0x1281);
  EXPECT_NE(after.request & kNotValid, 0U) << "SRD 1281h sub 1 = " << hex_text(after.request);
  EXPECT_NE(after.response & kNotValid, 0U) << "SRD 1281h sub 2 = " << hex_text(after.response);
  EXPECT_NE(rig.device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U);
  EXPECT_NE(rig.device_value(kWithChannels, 0x1201, 2).value_or(0) & kNotValid, 0U);
  const auto pool = rig.pool();
  ManagerRig::expect_pool_entries(pool, entry, false);
  EXPECT_EQ(ManagerRig::in_use(pool), 4U);
  const auto rows = rig.rows();
  EXPECT_FALSE(ManagerRig::has_row(rows, row_word(0x01, kSrd2, 0x01, kWithChannels)));
  // The other SRD's connection stays.
  EXPECT_TRUE(ManagerRig::has_row(rows, row_word(0x01, kSrd, 0x00, kWithChannels)));
  EXPECT_TRUE(rig.client_entry(kSrd, 0x1281).valid());
}

// §7.2.3 1F01h bits 16-31: "If this value is 0, all SDO connections to the slave are released"
// (and only those to that slave).
TEST(SdoManagerSpec, ReleaseWithIndex0ReleasesEveryConnectionToThatSlave) {
  ManagerRig rig;
  rig.start_network();
  rig.register_ok(kSrd);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd, kWithChannels, 0x1282);
  rig.connect_ok(kSrd, kDefaultOnly, 0x1283);
  rig.release(kSrd, request_word(0, kSrd, kWithChannels));
  EXPECT_FALSE(rig.client_entry(kSrd, 0x1281).valid());
  EXPECT_FALSE(rig.client_entry(kSrd, 0x1282).valid());
  EXPECT_NE(rig.device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U);
  EXPECT_TRUE(rig.client_entry(kSrd, 0x1283).valid()) << "the connection to node 3 stays";
  EXPECT_TRUE(rig.client_entry(kSrd, kClientSdo).valid()) << "the SRD stays registered";
  EXPECT_EQ(ManagerRig::in_use(rig.pool()), 2U) << "only the registration's COB-IDs";
  // The released default SDO is free again: a new request gets it without a write to the slave.
  const TimePoint from = rig.bus.now();
  rig.connect_ok(kSrd, kWithChannels, 0x1282);
  EXPECT_EQ(rig.client_entry(kSrd, 0x1282).request, 0x600U + kWithChannels);
  EXPECT_TRUE(rig.all_downloads(kWithChannels, from).empty());
}

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

// §7.2.1 De-registration: 1F01h with slave node-ID 0; §7.2.3: "If the SRD wants to release the
// SDO connections to all nodes and also to de-register, the value must be set to 0."
TEST(SdoManagerSpec, DeregistrationReleasesEverythingOfTheSrdAndItCanRegisterAgain) {
  ManagerRig rig;
  rig.start_network();
  rig.register_ok(kSrd);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
  rig.connect_ok(kSrd, kWithChannels, 0x1282);
  rig.connect_ok(kSrd, kDefaultOnly, 0x1283);
  rig.release(kSrd, request_word(0, kSrd, 0));
  for (std::uint16_t index = 0x1280; index <= 0x1283; ++index) {
    EXPECT_FALSE(rig.client_entry(kSrd, index).valid()) << hex_text(index);
  }
  EXPECT_NE(rig.device_value(kWithChannels, 0x1201, 1).value_or(0) & kNotValid, 0U);
  EXPECT_EQ(ManagerRig::in_use(rig.pool()), 0U);
  EXPECT_TRUE(rig.rows().empty());
  // Registered again from scratch.
  rig.register_ok(kSrd);
  rig.connect_ok(kSrd, kWithChannels, 0x1281);
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
  if ((confirmed & kReqEc) == 0) {
    EXPECT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1)));
    GTEST_SKIP() << "the manager does not support Req EC (it reset bit 3, §7.2.3)";
  }
  EXPECT_EQ(confirmed, state_word(kClientSdo, 0, cnxn(1) | kReqEc));
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
  EXPECT_TRUE(rig.writes_to(kSrd, kSlaveFailed, 0, from).size() == 1)
      << "one report for one failure";
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
    options.sdo_manager = sdo_manager;
    auto created = NmtMaster::create(dcf, id(node), options);
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
  EXPECT_FALSE(rig.uploads_of(kSrd, kConnectionState, 0, from).empty());
}

// Without the SDO manager (MasterOptions::sdo_manager false and no 1F00h in the DCF) the
// Dynamic SDO Request is not answered: the guideline-1 case of §7.2.4.
TEST(SdoManagerSpec, MasterWithoutSdoManagerDoesNotScan) {
  ManagerRig rig;
  rig.master = master_dcf();
  rig.options.sdo_manager = false;
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
