// NMT flying master (CiA 302-2 §3.7, §5.1-§5.5, §6.13; COB-IDs and bytes of DSP 302 §5.5):
// several NmtMaster engines with 1F80h bit 5 on one simulated bus, with simulated slaves, in
// simulated time. Times in the assertions are sums of the 1F90h values the spec defines
// (defaults of §6.13 unless a test sets others) and the heartbeat consumer time the header
// documents (2 x 1017h + 100 ms).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "nmt_master_spec_test_rig.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using namespace cfg::literals;
using master_spec::le;
using master_spec::Seen;
using master_spec::slave_eds;
using master_spec::Startup;
using master_spec::TestConfigurations;
using Kind = MasterEvent::Kind;

constexpr std::uint16_t kHeartbeatMs = 100;
// Header: the standby masters' consumer time for the active master: 2 x 1017h + 100 ms.
constexpr Duration kWatch = 2 * std::chrono::milliseconds(kHeartbeatMs) + 100ms;
// §6.13 defaults.
constexpr Duration kTimeout = 100ms;
constexpr Duration kDelay = 500ms;
constexpr Duration kPrioritySlot = 1500ms;
constexpr Duration kNodeSlot = 10ms;

/// §5.3: waiting time = priority x priority time slot + node-ID x device time slot.
Duration waiting_time(std::uint16_t priority, std::uint8_t node) {
  return priority * kPrioritySlot + node * kNodeSlot;
}

struct MasterEventAt {
  std::uint8_t master;
  MasterEvent event;
};

/// Masters (node-IDs 10..) built from tests/data/master/master.dcf, which assigns slaves 2 and 3
/// (1F81h = 05h); 1F80h = 23h (master, start all nodes, flying master), 1017h = 100 ms.
class FlyingRig {
 public:
  FlyingRig() {
    bus2.add_observer([this](const CanFrame& f, TimePoint t) { seen2.push_back({t, f}); });
  }
  ~FlyingRig() {
    if (std::getenv("MASTER_SPEC_DUMP") == nullptr) return;
    for (const auto& s : seen)
      std::cerr << s.at.time_since_epoch().count() << "us " << s.text() << "\n";
    for (const auto& e : events) {
      std::cerr << "EVENT " << int{e.master} << " " << e.event.at.time_since_epoch().count()
                << "us " << to_string(e.event.kind) << ": " << describe(e.event) << "\n";
    }
  }
  FlyingRig(const FlyingRig&) = delete;
  FlyingRig& operator=(const FlyingRig&) = delete;

  NmtMaster& add_master(std::uint8_t node, std::uint16_t priority) {
    auto created = NmtMaster::create(master_spec::master_dcf(), *cfg::NodeId::from(node), options);
    EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
    auto slot = std::make_unique<SimEngineNode<NmtMaster>>(std::move(created).value());
    auto& dict = slot->engine().dictionary();
    EXPECT_EQ(write(dict, 0x1F80, 0,
                    Startup::kMaster | Startup::kStartAllNodes | Startup::kFlyingMaster, 4),
              SdoAbort::None);
    EXPECT_EQ(write(dict, 0x1017, 0, kHeartbeatMs, 2), SdoAbort::None);
    EXPECT_EQ(write(dict, 0x1F90, 3, priority, 2), SdoAbort::None);
    slot->set_event_handler([this, node](const MasterEvent& e, TimePoint) {
      events.push_back({node, e});
    });
    auto& engine = slot->engine();
    masters_[node] = std::move(slot);
    return engine;
  }
  static SdoAbort write(LocalDictionary& dict, std::uint16_t index, std::uint8_t sub,
                        std::uint64_t value, std::size_t size) {
    return dict.write(index, sub, le(value, size), TimePoint{});
  }
  NmtMaster& master(std::uint8_t node) { return masters_.at(node)->engine(); }
  /// Power-on of a master on the (main) bus.
  void start(std::uint8_t node) {
    auto& slot = *masters_.at(node);
    bus.attach(slot);
    slot.apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  }
  /// Runs an API call of master `node` at the bus time.
  template <class Fn>
  decltype(auto) call(std::uint8_t node, Fn&& fn) {
    return masters_.at(node)->apply(std::forward<Fn>(fn));
  }
  void start_all(std::initializer_list<std::uint8_t> nodes) {
    for (auto node : nodes) start(node);
  }
  /// The master stops: no frame of it any more (SIGKILL, power cut).
  void kill(std::uint8_t node) { masters_.at(node)->bus()->detach(*masters_.at(node)); }

  /// A slave from slave.eds, powered on now.
  SimulatedDevice& add_slave(std::uint8_t node) {
    auto& device = net_.add_slave(node);
    net_.start(node);
    return device;
  }
  SimulatedDevice& slave(std::uint8_t node) { return net_.slave(node); }

  // --- a network split: `node` alone on a second bus, both buses on one clock --------------
  void split(std::uint8_t node) {
    bus2.run_until(bus.now());
    move(node, bus2);
  }
  void heal(std::uint8_t node) {
    bus2.run_until(bus.now());
    move(node, bus);
  }
  void run_for(Duration d) {
    const auto end = bus.now() + d;
    while (bus.now() < end) {
      const auto step = std::min<Duration>(1ms, end - bus.now());
      bus.run_for(step);
      bus2.run_until(bus.now());
    }
  }

  // --- observation ---------------------------------------------------------------------------
  /// The masters that consider themselves the active master.
  std::vector<std::uint8_t> actives() {
    std::vector<std::uint8_t> out;
    for (auto& [node, slot] : masters_) {
      if (slot->bus() == nullptr) continue;
      if (slot->engine().active_master() == *cfg::NodeId::from(node)) out.push_back(node);
    }
    return out;
  }
  std::vector<MasterEventAt> events_of(Kind kind, std::optional<std::uint8_t> master = {},
                                       TimePoint from = TimePoint{}) const {
    std::vector<MasterEventAt> out;
    for (const auto& e : events) {
      if (e.event.kind == kind && (!master || e.master == *master) && e.event.at >= from) {
        out.push_back(e);
      }
    }
    return out;
  }
  std::vector<Seen> on_id(std::uint32_t cob, TimePoint from = TimePoint{}) const {
    std::vector<Seen> out;
    for (const auto& s : seen) {
      if (s.at >= from && !s.frame.extended && s.frame.id == cob) out.push_back(s);
    }
    return out;
  }
  bool run_until(const std::function<bool()>& done, Duration limit) {
    const auto end = bus.now() + limit;
    while (bus.now() < end) {
      if (done()) return true;
      run_for(1ms);
    }
    return done();
  }

  // The slaves, a 500 kbit/s bus and its frames (`seen`) come from the NmtMasterSpec rig.
  master_spec::MasterRig net_;
  SimBus& bus = net_.bus;
  std::vector<Seen>& seen = net_.seen;
  SimBus bus2{500'000};
  MasterOptions options;
  std::vector<Seen> seen2;
  std::vector<MasterEventAt> events;

 private:
  void move(std::uint8_t node, SimBus& to) {
    auto& slot = *masters_.at(node);
    to.attach(slot);
    // The engine's timer stayed with the old bus: arm it on the new one.
    slot.apply([](NmtMaster&, TimePoint, NmtMaster::Output&) {});
  }
  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<NmtMaster>>> masters_;
};

/// Every master started and the network running: `winner` active, the others standing by it.
void expect_settled(FlyingRig& rig, std::uint8_t winner,
                    std::initializer_list<std::uint8_t> others) {
  EXPECT_EQ(rig.actives(), std::vector<std::uint8_t>{winner});
  EXPECT_EQ(rig.master(winner).startup_state(), StartupState::Operational);
  for (auto node : others) {
    EXPECT_EQ(rig.master(node).startup_state(), StartupState::Standby) << "master " << int{node};
    EXPECT_EQ(rig.master(node).active_master(), *cfg::NodeId::from(winner))
        << "master " << int{node};
  }
}

// ------------------------------------------------------------------------------ start-up -------

// §3.7 and §5.3: two masters switched on together. Power-on: delay (sub 2), 73h, no answer within
// sub 1: reset communication of all nodes (§3.7 d); warm: delay, 73h, no answer: 72h, then the
// waiting time; the higher priority (0 at node 11, against 1 at node 10) answers first with 71h
// (byte 0 priority, byte 1 node-ID) and the other stands by.
TEST(FlyingMaster, TwoMastersStartTogetherHigherPriorityWins) {
  FlyingRig rig;
  rig.add_slave(2);
  rig.add_slave(3);
  rig.add_master(10, 1);
  rig.add_master(11, 0);
  rig.start(10);
  rig.start(11);
  ASSERT_TRUE(rig.run_until([&] { return !rig.events_of(Kind::StartupComplete).empty(); }, 10s));
  rig.run_for(1s);

  const auto won = rig.on_id(0x71);
  ASSERT_FALSE(won.empty());
  EXPECT_EQ(won.front().text(), "071#000B");
  const TimePoint expected{2 * (kDelay + kTimeout) + waiting_time(0, 11)};
  EXPECT_GE(won.front().at, expected);
  EXPECT_LT(won.front().at, expected + 5ms);
  expect_settled(rig, 11, {10});
  EXPECT_EQ(rig.events_of(Kind::ActiveMaster).size(), 1U);
  auto standby = rig.events_of(Kind::Standby, 10);
  ASSERT_FALSE(standby.empty());
  EXPECT_EQ(standby.front().event.node_id, 11);
  EXPECT_EQ(standby.front().event.priority, 0);
  EXPECT_EQ(rig.slave(2).node().state(), NmtState::Operational);
  EXPECT_EQ(rig.slave(3).node().state(), NmtState::Operational);
  // Only the active master sends NMT start.
  for (const auto& s : rig.on_id(0x000)) EXPECT_NE(s.text(), "000#0200");
}

// §5.3: at equal priority the node-ID decides: the lowest node-ID has the shortest waiting time.
TEST(FlyingMaster, ThreeMastersOfEqualPriorityLowestNodeIdWins) {
  FlyingRig rig;
  rig.add_slave(2);
  rig.add_master(12, 1);
  rig.add_master(10, 1);
  rig.add_master(11, 1);
  rig.start_all({12, 10, 11});
  ASSERT_TRUE(rig.run_until([&] { return !rig.events_of(Kind::StartupComplete).empty(); }, 10s));
  rig.run_for(1s);

  const auto won = rig.on_id(0x71);
  ASSERT_FALSE(won.empty());
  EXPECT_EQ(won.front().text(), "071#010A");
  const TimePoint expected{2 * (kDelay + kTimeout) + waiting_time(1, 10)};
  EXPECT_GE(won.front().at, expected);
  EXPECT_LT(won.front().at, expected + 5ms);
  expect_settled(rig, 10, {11, 12});
}

// ------------------------------------------------------------------------------ failover ------

struct Running {
  FlyingRig rig;
  Running() {
    rig.add_slave(2);
    rig.add_slave(3);
    rig.add_master(10, 1);
    rig.add_master(11, 0);
    rig.add_master(12, 1);
    rig.start_all({10, 11, 12});
    EXPECT_TRUE(rig.run_until([&] { return !rig.events_of(Kind::StartupComplete).empty(); }, 10s));
    rig.run_for(2s);
    expect_settled(rig, 11, {10, 12});
  }
};

// §5.5.2: the active master dies; the others miss its heartbeat (consumer time 2 x 1017h + 100
// ms), reset communication of all nodes, negotiate again (delay, 73h, timeout, 72h, waiting
// time); the best remaining master (priority 1, node 10) wins and configures the network.
TEST(FlyingMaster, ActiveMasterDiesAndTheNextTakesOverWithinTheSpecifiedTime) {
  Running net;
  auto& rig = net.rig;
  rig.kill(11);
  const auto died = rig.bus.now();
  ASSERT_TRUE(
      rig.run_until([&] { return !rig.events_of(Kind::StartupComplete, 10, died).empty(); }, 10s));
  rig.run_for(1s);

  // Its last frame: a heartbeat (its cyclic 76h come every 4110 ms, before start-up ended).
  const auto last = rig.on_id(0x70B).back().at;
  ASSERT_LE(last, died);
  auto lost = rig.events_of(Kind::ActiveMasterLost, std::nullopt, died);
  ASSERT_FALSE(lost.empty());
  EXPECT_EQ(lost.front().event.node_id, 11);
  EXPECT_LE(lost.front().event.at - last, kWatch + 1ms);
  const auto won = rig.on_id(0x71, died);
  ASSERT_FALSE(won.empty());
  EXPECT_EQ(won.front().text(), "071#010A");
  // Last heartbeat -> loss (kWatch) -> reset, delay, detection timeout -> waiting time.
  const auto bound = kWatch + kDelay + kTimeout + waiting_time(1, 10);
  EXPECT_LE(won.front().at - last, bound + 5ms);
  EXPECT_GE(won.front().at - last, bound - 5ms);
  // The new master's first NMT command after it won: its start-up's reset communication.
  const auto nmt = rig.on_id(0x000, won.front().at);
  ASSERT_FALSE(nmt.empty());
  EXPECT_EQ(nmt.front().text(), "000#8200");
  expect_settled(rig, 10, {12});
  EXPECT_EQ(rig.slave(2).node().state(), NmtState::Operational);
  EXPECT_EQ(rig.slave(3).node().state(), NmtState::Operational);
}

// §3.5 through the new master: the masters share the network description (one configuration
// source, 1F26h/1F27h equal), so after a takeover the slaves' 1020h matches and nothing is
// downloaded again (the boot reports configured = false).
TEST(FlyingMaster, TakeoverDoesNotDownloadMatchingConfigurationsAgain) {
  FlyingRig rig;
  auto configs = std::make_shared<TestConfigurations>();
  configs->writes[2] = {master_spec::write_of(0x2000, 0, 0x1234, 2)};
  rig.options.configurations = configs;
  rig.add_slave(2);
  for (auto [node, priority] : {std::pair<std::uint8_t, std::uint16_t>{10, 1}, {11, 0}}) {
    auto& m = rig.add_master(node, priority);
    EXPECT_EQ(FlyingRig::write(m.dictionary(), 0x1F26, 2, 15000, 4), SdoAbort::None);
    EXPECT_EQ(FlyingRig::write(m.dictionary(), 0x1F27, 2, 3'600'000, 4), SdoAbort::None);
    rig.start(node);
  }
  ASSERT_TRUE(rig.run_until([&] { return !rig.events_of(Kind::SlaveBooted, 11).empty(); }, 10s));
  EXPECT_TRUE(rig.events_of(Kind::SlaveBooted, 11).front().event.configured);
  rig.run_for(2s);
  rig.kill(11);
  const auto died = rig.bus.now();
  ASSERT_TRUE(
      rig.run_until([&] { return !rig.events_of(Kind::SlaveBooted, 10, died).empty(); }, 10s));
  const auto booted = rig.events_of(Kind::SlaveBooted, 10, died).front().event;
  EXPECT_FALSE(booted.configured);
  for (const auto& s : rig.on_id(0x602, died)) {
    EXPECT_FALSE(master_spec::is_download_initiate(s.frame) &&
                 master_spec::addresses(s.frame, 0x2000, 0))
        << s;
  }
  EXPECT_EQ(rig.slave(2).node().dictionary().get_unsigned(0x2000, 0), 0x1234U);
}

// §3.1 d with keep-alive (1F81h bit 4): the failover's reset and the new master's start-up reset
// every other node individually, so an operational keep-alive slave is never reset; the new
// master's boot finds it operational (status L, §3.4) and it stays operational throughout.
TEST(FlyingMaster, TakeoverKeepsOperationalKeepAliveSlavesRunning) {
  FlyingRig rig;
  rig.add_slave(2);
  rig.add_slave(3);
  for (auto [node, priority] : {std::pair<std::uint8_t, std::uint16_t>{10, 1}, {11, 0}}) {
    auto& m = rig.add_master(node, priority);
    const auto keep =
        cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave |
                                   cfg::SlaveAssignment::kKeepAlive);
    EXPECT_EQ(FlyingRig::write(m.dictionary(), 0x1F81, 3, keep.value, 4), SdoAbort::None);
    rig.start(node);
  }
  ASSERT_TRUE(
      rig.run_until([&] { return !rig.events_of(Kind::StartupComplete, 11).empty(); }, 10s));
  rig.run_for(1s);
  ASSERT_EQ(rig.slave(3).node().state(), NmtState::Operational);
  rig.kill(11);
  const auto died = rig.bus.now();
  bool left_operational = false;
  ASSERT_TRUE(rig.run_until(
      [&] {
        if (rig.slave(3).node().state() != NmtState::Operational) left_operational = true;
        return !rig.events_of(Kind::StartupComplete, 10, died).empty();
      },
      10s));
  rig.run_for(1s);
  EXPECT_FALSE(left_operational);
  for (const auto& s : rig.on_id(0x000, died)) {
    EXPECT_NE(s.text(), "000#8200") << s;
    EXPECT_NE(s.text(), "000#8203") << s;
  }
  EXPECT_EQ(rig.master(10).last_error(3_node), BootError::L);
  EXPECT_EQ(rig.slave(2).node().state(), NmtState::Operational);
}

// ------------------------------------------------------------------------------ multiple masters

// §5.5.3: a split: master 12 alone on its side misses the active master's heartbeat and becomes
// active there. When the halves join, the cyclic force (76h every 1F90h sub 6 = 4000 + 10 x
// node-ID ms) of either active master makes the other reset all nodes; the negotiation then
// picks the better master (11) again.
TEST(FlyingMaster, SplitHealsAndMultipleMasterDetectionLeavesOneActiveMaster) {
  Running net;
  auto& rig = net.rig;
  rig.split(12);
  ASSERT_TRUE(rig.run_until([&] { return rig.master(12).active_master() == 12_node; }, 10s));
  rig.run_for(1s);
  EXPECT_EQ(rig.master(11).active_master(), 11_node);
  rig.heal(12);
  const auto healed = rig.bus.now();
  // Worst case: a full cycle of the faster master, then the negotiation after a reset.
  const auto bound = 4110ms + kDelay + kTimeout + waiting_time(0, 11) + 200ms;
  ASSERT_TRUE(rig.run_until(
      [&] { return !rig.events_of(Kind::MultipleMasters, std::nullopt, healed).empty(); }, 4200ms));
  ASSERT_TRUE(
      rig.run_until([&] { return !rig.events_of(Kind::ActiveMaster, 11, healed).empty(); }, bound));
  rig.run_for(2s);
  expect_settled(rig, 11, {10, 12});
}

// §3.7 f: a master with a lower priority that joins later asks (73h), gets the active master's
// answer (71h) and stands by, without any NMT command of its own.
TEST(FlyingMaster, LateLowerPriorityMasterStandsBy) {
  FlyingRig rig;
  rig.add_slave(2);
  rig.add_master(10, 0);
  rig.add_master(12, 2);
  rig.start(10);
  ASSERT_TRUE(rig.run_until([&] { return !rig.events_of(Kind::StartupComplete).empty(); }, 10s));
  rig.run_for(1s);
  const auto joined = rig.bus.now();
  rig.start(12);
  rig.run_for(kDelay + kTimeout + 100ms);
  auto standby = rig.events_of(Kind::Standby, 12);
  ASSERT_EQ(standby.size(), 1U);
  EXPECT_EQ(standby.front().event.node_id, 10);
  EXPECT_LE(standby.front().event.at - joined, kDelay + 5ms);
  EXPECT_TRUE(rig.on_id(0x000, joined).empty());
  EXPECT_TRUE(rig.on_id(0x76, joined).empty());
  expect_settled(rig, 10, {12});
}

// §3.7 g, §5.4: a master with a higher priority that joins later forces a negotiation (76h);
// the active master resets all nodes and the newcomer wins.
TEST(FlyingMaster, LateHigherPriorityMasterForcesNegotiationAndWins) {
  FlyingRig rig;
  rig.add_slave(2);
  rig.add_master(11, 1);
  rig.add_master(10, 0);
  rig.start(11);
  ASSERT_TRUE(rig.run_until([&] { return !rig.events_of(Kind::StartupComplete).empty(); }, 10s));
  rig.run_for(1s);
  const auto joined = rig.bus.now();
  rig.start(10);
  ASSERT_TRUE(rig.run_until(
      [&] { return !rig.events_of(Kind::StartupComplete, 10, joined).empty(); }, 10s));
  rig.run_for(1s);
  ASSERT_FALSE(rig.events_of(Kind::ForceNegotiation, 10).empty());
  ASSERT_FALSE(rig.on_id(0x76, joined).empty());
  expect_settled(rig, 10, {11});
}

// 1% of the frames lost during the negotiation (20 seeds): the network still ends with one
// active master, the best one, and the others standing by it.
TEST(FlyingMaster, OnePercentFrameLossStillElectsOneMaster) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    FlyingRig rig;
    rig.options.sdo.retries = 4;
    rig.bus.set_loss_rate(0.01, seed);
    rig.add_slave(2);
    rig.add_master(10, 1);
    rig.add_master(11, 0);
    rig.add_master(12, 2);
    rig.start_all({10, 11, 12});
    rig.run_for(15s);
    EXPECT_EQ(rig.actives(), std::vector<std::uint8_t>{11});
    EXPECT_EQ(rig.master(10).active_master(), 11_node);
    EXPECT_EQ(rig.master(12).active_master(), 11_node);
  }
}

// ------------------------------------------------------------------------------ objects --------

// §6.13 Table 50 defaults (sub 3 manufacturer-specific: 1, header), sub 6 = 4000 + 10 x node-ID;
TEST(FlyingMaster, TimingParametersHaveTheirDefaults) {
  auto m = NmtMaster::create(master_spec::master_dcf(), 5_node).value();
  const auto& dict = m.dictionary();
  EXPECT_EQ(dict.get_unsigned(0x1F90, 0), 6U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 1), 100U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 2), 500U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 3), 1U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 4), 1500U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 5), 10U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 6), 4050U);
  // §6.14 / DSP 302 §5.5.6: 1F91h, the self-starting device's timing.
  EXPECT_EQ(dict.get_unsigned(0x1F91, 0), 3U);
  EXPECT_EQ(dict.get_unsigned(0x1F91, 1), 100U);
  EXPECT_EQ(dict.get_unsigned(0x1F91, 2), 500U);
  EXPECT_EQ(dict.get_unsigned(0x1F91, 3), 15U);
}

// Table 48: priorities 3..FFFFh are reserved; §6.13: priority time slot > 127 x device time slot.
TEST(FlyingMaster, TimingParameterWritesAreChecked) {
  auto m = NmtMaster::create(master_spec::master_dcf(), 5_node).value();
  auto& dict = m.dictionary();
  EXPECT_EQ(FlyingRig::write(dict, 0x1F90, 3, 2, 2), SdoAbort::None);
  EXPECT_EQ(FlyingRig::write(dict, 0x1F90, 3, 3, 2), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(FlyingRig::write(dict, 0x1F90, 4, 1270, 2), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(FlyingRig::write(dict, 0x1F90, 4, 1271, 2), SdoAbort::None);
  EXPECT_EQ(FlyingRig::write(dict, 0x1F90, 5, 11, 2), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(FlyingRig::write(dict, 0x1F90, 5, 5, 2), SdoAbort::None);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 3), 2U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 4), 1271U);
  EXPECT_EQ(dict.get_unsigned(0x1F90, 5), 5U);
}

// Header: a standby master is no NMT master: request NMT (1F82h) is refused with 0800 0022.
TEST(FlyingMaster, StandbyMasterRefusesRequestNmt) {
  Running net;
  auto& rig = net.rig;
  EXPECT_EQ(FlyingRig::write(rig.master(10).dictionary(), 0x1F82, 2, 0x04, 1),
            SdoAbort::DeviceState);
  EXPECT_EQ(FlyingRig::write(rig.master(11).dictionary(), 0x1F82, 2, 0x04, 1), SdoAbort::None);
  // Nor does it boot a slave when its application asks.
  const cfg::Status booting = rig.call(10, [](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.boot_slave(2_node, now, out);
  });
  EXPECT_FALSE(booting.ok());
  EXPECT_EQ(rig.master(10).boot_step(2_node), BootStep::Idle);
}

}  // namespace
}  // namespace nmt

namespace nmt {
namespace {

using master_spec::MasterRig;
using master_spec::Startup;
using namespace std::chrono_literals;
using Kind = MasterEvent::Kind;

// §5.1 and DSP 302 §5.5.3.1 with 1F91h's defaults (§6.14: 100 ms timeout, 500 ms delay, 15 ms
// node slot): a self-starting device with 1F80h bit 1 (Table 16) asks for master-capable devices
// (75h) 500 ms after start-up; nobody answers within 100 ms, so it starts all nodes after
// node-ID (1) x 15 ms. It is operational by itself from the start.
TEST(MasterDetection, SelfStartingDeviceStartsAllNodesWhenNoMasterCapableDeviceAnswers) {
  MasterRig rig;
  rig.startup(Startup::kStartAllNodes);
  rig.add_slave(2);
  auto& device = rig.power_on_network();
  EXPECT_EQ(device.state(), NmtState::Operational);
  rig.run_for(1s);
  const auto asked = rig.on_id(0x75);
  ASSERT_EQ(asked.size(), 1U);
  EXPECT_GE(asked.front().at - rig.started_at, 500ms);  // delivered at its end of frame
  EXPECT_LT(asked.front().at - rig.started_at, 501ms);
  const auto started = rig.nmt_seen();
  ASSERT_EQ(started.size(), 1U);
  EXPECT_EQ(started.front().text(), "000#0100");
  EXPECT_GE(started.front().at - rig.started_at, 615ms);
  EXPECT_LT(started.front().at - rig.started_at, 616ms);
  EXPECT_EQ(rig.slave(2).node().state(), NmtState::Operational);
}

// DSP 302 §5.5.3.1: "If one or more devices answer within [1F91h sub 1], the requesting device
// knows that there exist at least one device with the capability to become NMT master": it
// sends no start.
TEST(MasterDetection, SelfStartingDeviceLeavesTheNetworkToAMasterCapableDevice) {
  MasterRig rig;
  rig.startup(Startup::kStartAllNodes);
  rig.add_slave(2);
  FunctionNode capable([](FunctionNode& self, const CanFrame& f, TimePoint) {
    if (f.id == 0x75) self.send(CanFrame::make(0x74, {}));
  });
  rig.bus.attach(capable);
  rig.power_on_network();
  rig.run_for(2s);
  EXPECT_EQ(rig.on_id(0x74).size(), 1U);
  EXPECT_TRUE(rig.nmt().empty());
  ASSERT_EQ(rig.events_of(Kind::MasterDetection).size(), 1U);
  EXPECT_EQ(rig.slave(2).node().state(), NmtState::PreOperational);
}

// DSP 302 §5.5.3.1: the node-ID slots keep a group of self-starting devices from all sending
// the start: node 1 waits 15 ms, node 4 60 ms and hears node 1's start first.
TEST(MasterDetection, OfTwoSelfStartingDevicesOnlyTheLowerNodeIdStartsTheNetwork) {
  MasterRig rig;
  rig.startup(Startup::kStartAllNodes);
  rig.add_slave(2);
  auto second = NmtMaster::create(rig.master, 4_node).value();
  SimEngineNode<NmtMaster> node4(std::move(second));
  rig.bus.attach(node4);
  rig.power_on_slaves();
  rig.run_for(50ms);
  node4.apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  rig.start_master();
  rig.run_for(2s);
  EXPECT_EQ(rig.on_id(0x75).size(), 2U);
  EXPECT_EQ(rig.nmt(), std::vector<std::string>{"000#0100"});
  EXPECT_EQ(node4.engine().state(), NmtState::Operational);
}

}  // namespace
}  // namespace nmt
