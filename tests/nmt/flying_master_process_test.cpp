// The NMT flying master and NMT master detection alone (master/flying_master.hpp): CiA 302-2
// §3.7, §5.1-§5.5 with the COB-IDs and bytes of DSP 302 §5.5 (Figures 15-19: 71h priority and
// node-ID, 72h, 73h, 74h, 75h, 76h without data). The engine is driven frame by frame and at its
// deadlines, so times are exact; a fake port stands for the NMT master and records what the
// engine asks of it. After a reset communication of this device (port.restart) the tests start
// the engine again, as the master's boot-up and start-up do.
// The composition with the master (NMT start-up after a win, the reset frames, slaves, 1F90h
// over SDO) is tested in flying_master_spec_test.cpp and flying_master_test.cpp.
#include "master/flying_master.hpp"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "nmt_master_spec_test_rig.hpp"

namespace nmt {
namespace {

using master_spec::reply_71;

using namespace std::chrono_literals;
using namespace cfg::literals;
using Kind = MasterEvent::Kind;
using Phase = FlyingMasterProcess::Phase;

Duration ms(std::int64_t value) {
  return std::chrono::milliseconds(value);
}

TimePoint at_ms(std::int64_t value) {
  return TimePoint{ms(value)};
}

// 1F90h with the CiA 302-2 §6.13 Table 50 defaults (sub 6: 4000 + 10 x node-ID).
FlyingTiming timing_of(std::uint8_t node, std::uint16_t priority) {
  return {ms(100), ms(500), priority, ms(1500), ms(10), ms(4000 + 10 * node)};
}

// 1F91h with the §6.14 Table 52 defaults.
constexpr DetectionTiming kDetectionDefaults{100ms, 500ms, 15ms};

// §5.3.1: waiting time = priority level x priority time slot + node-ID x device time slot.
Duration waiting_time(const FlyingTiming& t, std::uint8_t node) {
  return t.priority * t.priority_slot + node * t.node_slot;
}

// What the engine asked of the NMT master.
struct FakePort final : FlyingMasterPort {
  void became_active(TimePoint now, Output& /*out*/) override { active_at.push_back(now); }
  void set_startup(StartupState state) override { startup = state; }
  void restart(TimePoint now) override { restart_at = now; }
  void reset_all_nodes() override { ++resets; }
  void queue_nmt(NmtCommand command, NmtTarget target) override {
    queued.emplace_back(command, target.byte());  // as the frame writes it: 0 all nodes
  }
  void obey(NmtCommand command, TimePoint /*now*/, Output& /*out*/) override {
    obeyed.push_back(command);
  }
  bool master_capable() const override { return capable; }
  std::optional<Duration> heartbeat_time(cfg::NodeId node) const override {
    auto it = consumer.find(node);
    if (it == consumer.end()) return std::nullopt;
    return it->second;
  }
  std::uint32_t own_heartbeat_ms() const override { return heartbeat_ms; }

  bool capable = true;
  std::map<std::uint8_t, Duration> consumer;  // 1016h
  std::uint32_t heartbeat_ms = 100;           // 1017h
  StartupState startup = StartupState::Off;
  std::vector<TimePoint> active_at;
  std::optional<TimePoint> restart_at;
  int resets = 0;
  std::vector<std::pair<NmtCommand, std::uint8_t>> queued;
  std::vector<NmtCommand> obeyed;
};

struct Sent {
  TimePoint at;
  std::string text;
};

class Rig {
 public:
  Rig(std::uint8_t node, std::uint16_t priority)
      : node_(node), timing(timing_of(node, priority)), engine(*cfg::NodeId::from(node), port) {}

  /// Power-on (or the master's start-up after a reset communication) at `at`.
  void start(TimePoint at) {
    now = at;
    engine.start(timing, now, out_);
    collect();
  }
  /// A frame of another device at `at`; true when the engine took it.
  bool hear(std::string_view candump, TimePoint at) {
    run_until(at);
    auto f = from_candump(candump);
    EXPECT_TRUE(f.has_value()) << candump;
    const bool taken = engine.on_frame(*f, now, out_);
    collect();
    return taken;
  }
  /// Runs the engine's deadlines up to `end`.
  void run_until(TimePoint end) {
    for (int guard = 0; guard < 10000; ++guard) {
      const auto due = engine.next_deadline();
      if (!due || *due > end) break;
      now = std::max(now, *due);
      engine.on_timer(now, out_);
      collect();
    }
    now = std::max(now, end);
  }
  void run_for(Duration d) { run_until(now + d); }

  /// The frames sent from `from` on with this candump text's COB-ID prefix ("073#").
  std::vector<Sent> sent_on(std::string_view prefix, TimePoint from = TimePoint{}) const {
    std::vector<Sent> result;
    for (const auto& s : sent) {
      if (s.at >= from && s.text.rfind(prefix, 0) == 0) result.push_back(s);
    }
    return result;
  }
  std::optional<Sent> first_on(std::string_view prefix, TimePoint from = TimePoint{}) const {
    auto all = sent_on(prefix, from);
    if (all.empty()) return std::nullopt;
    return all.front();
  }
  std::vector<MasterEvent> events_of(Kind kind) const {
    std::vector<MasterEvent> result;
    for (const auto& e : events) {
      if (e.kind == kind) result.push_back(e);
    }
    return result;
  }

  /// Power-on at `at` with nobody answering: §3.7 d's reset, then warm: the 72h at the returned
  /// time, the negotiation running.
  TimePoint negotiate_alone(TimePoint at) {
    start(at);
    run_until(at + timing.delay + timing.timeout);
    EXPECT_EQ(port.resets, 1);
    EXPECT_EQ(port.restart_at, at + timing.delay + timing.timeout);
    start(now);
    run_until(now + timing.delay + timing.timeout);
    auto trigger = first_on("072#");
    EXPECT_TRUE(trigger.has_value());
    EXPECT_EQ(engine.phase(), Phase::Negotiate);
    return trigger ? trigger->at : TimePoint{};
  }
  /// The same, on to the win: the 71h at the returned time.
  TimePoint win_alone(TimePoint at) {
    const TimePoint trigger = negotiate_alone(at);
    run_until(trigger + waiting_time(timing, node_));
    EXPECT_EQ(engine.phase(), Phase::Active);
    return trigger + waiting_time(timing, node_);
  }

  std::uint8_t node_;
  FakePort port;
  FlyingTiming timing;
  FlyingMasterProcess engine;
  TimePoint now{};
  std::vector<Sent> sent;
  std::vector<MasterEvent> events;

 private:
  void collect() {
    for (const auto& f : out_.frames) sent.push_back({now, to_candump(f)});
    for (const auto& e : out_.events) events.push_back(e);
    out_.clear();
  }

  FlyingMasterProcess::Output out_;
};

// ------------------------------------------------------------ §3.7: start-up of one master --

// §3.7 b-c: "After initialization the CANopen device shall wait until the NMT master negotiation
// time delay (1F90h sub-index 02h) has expired. The CANopen device shall request the service
// active NMT master detection." DSP 302 Figure 15: ID = 73h, no data.
TEST(FlyingMasterProcess, PowerOnWaitsNegotiationDelayThenRequests73hWithoutData_3_7) {
  for (std::int64_t delay : {500, 200}) {
    SCOPED_TRACE(delay);
    Rig rig(4, 1);
    rig.timing.delay = ms(delay);
    const TimePoint t0 = at_ms(50);
    rig.start(t0);
    EXPECT_EQ(rig.port.startup, StartupState::Negotiating);
    EXPECT_EQ(rig.engine.next_deadline(), t0 + ms(delay));
    rig.run_until(t0 + ms(delay) + 50ms);
    auto request = rig.first_on("073#");
    ASSERT_TRUE(request.has_value());
    EXPECT_EQ(request->text, "073#");
    EXPECT_EQ(request->at - t0, ms(delay));
    // Nothing of the negotiation, and no NMT command, before the detection ran.
    EXPECT_FALSE(rig.first_on("072#").has_value());
    EXPECT_FALSE(rig.first_on("071#").has_value());
    EXPECT_EQ(rig.port.resets, 0);
    EXPECT_TRUE(rig.port.queued.empty());
  }
}

// §3.7 d: no confirmation within 1F90h sub 1 after power-on: reset communication of all nodes,
// this device included; §3.7 e: after it (warm) the detection again, then the trigger 72h
// without data (DSP 302 Figure 16); §3.7 h: after the waiting time the 71h with priority and
// node-ID, and NMT start-up of the master.
TEST(FlyingMasterProcess, PowerOnWithoutActiveMasterResetsAllThenNegotiatesWarm_3_7_d_e_h) {
  Rig rig(4, 1);
  rig.timing.timeout = 150ms;
  const TimePoint t0 = at_ms(50);
  rig.start(t0);
  rig.run_until(t0 + 500ms + 150ms);
  EXPECT_EQ(rig.port.resets, 1);
  ASSERT_TRUE(rig.port.restart_at.has_value());
  EXPECT_EQ(*rig.port.restart_at, t0 + 500ms + 150ms);
  EXPECT_EQ(rig.sent_on("072#").size(), 0U);

  const TimePoint reset = *rig.port.restart_at;
  rig.start(reset);  // the master's boot-up and start-up after the reset
  rig.run_for(5s);
  auto request2 = rig.first_on("073#", reset);
  ASSERT_TRUE(request2.has_value());
  EXPECT_EQ(request2->at - reset, 500ms);
  auto trigger = rig.first_on("072#");
  ASSERT_TRUE(trigger.has_value());
  EXPECT_EQ(trigger->text, "072#");
  EXPECT_EQ(trigger->at - request2->at, 150ms);
  auto won = rig.first_on("071#");
  ASSERT_TRUE(won.has_value());
  EXPECT_EQ(won->text, reply_71(1, 4));
  EXPECT_EQ(won->at - trigger->at, waiting_time(rig.timing, 4));
  EXPECT_EQ(rig.port.resets, 1);
  EXPECT_EQ(rig.port.active_at, std::vector<TimePoint>{won->at});
  EXPECT_EQ(rig.engine.active_master(), 4_node);
  EXPECT_EQ(rig.events_of(Kind::ActiveMaster).size(), 1U);
}

// §5.3.1 / DSP 302 §5.5.1.3: "waiting time = Priority level x Priority time slot + Node-ID x
// CANopen device time slot", counted from the trigger (72h); the device then answers with its
// priority and node-ID (71h, Figure 16).
TEST(FlyingMasterProcess, NegotiationWaitsPriorityTimesSlotPlusNodeIdTimesSlot_5_3_1) {
  struct Case {
    std::uint16_t priority;
    std::uint8_t node;
    std::int64_t priority_slot;
    std::int64_t device_slot;
  };
  for (const Case& c : {Case{0, 1, 1500, 10}, Case{1, 4, 1500, 10}, Case{2, 9, 1300, 10},
                        Case{0, 127, 2000, 15}, Case{2, 100, 1300, 10}, Case{1, 64, 700, 5}}) {
    SCOPED_TRACE("priority " + std::to_string(c.priority) + " node " + std::to_string(c.node));
    Rig rig(c.node, c.priority);
    rig.timing.priority_slot = ms(c.priority_slot);
    rig.timing.node_slot = ms(c.device_slot);
    const TimePoint trigger = rig.negotiate_alone(at_ms(50));
    rig.run_for(10s);
    auto won = rig.first_on("071#");
    ASSERT_TRUE(won.has_value());
    EXPECT_EQ(won->text, reply_71(c.priority, c.node));
    EXPECT_EQ(won->at - trigger,
              ms(std::int64_t{c.priority} * c.priority_slot + c.node * c.device_slot));
  }
}

// §5.2.1: the active master confirms active NMT master detection with its node-ID and priority,
// within 1F90h sub 1 (here at once); DSP 302 Figure 15: "ID = 71h, Data Byte [0] NMT master
// priority level, Data Byte [1] Node ID". A standby master stays silent (§5.2.1: the service
// checks for a device "in NMT master mode").
TEST(FlyingMasterProcess, OnlyTheActiveMasterAnswers73hWith71hPriorityAndNodeId_5_2) {
  Rig active(9, 2);
  active.timing.priority_slot = 1300ms;
  const TimePoint won = active.win_alone(at_ms(50));
  const TimePoint asked = won + 200ms;
  EXPECT_TRUE(active.hear("073#", asked));
  auto answer = active.first_on("071#", asked);
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(answer->text, reply_71(2, 9));
  EXPECT_EQ(answer->at, asked);

  Rig standby(4, 1);
  standby.start(at_ms(50));
  standby.run_until(at_ms(550));
  EXPECT_TRUE(standby.hear(reply_71(0, 5), at_ms(560)));
  ASSERT_EQ(standby.engine.phase(), Phase::Standby);
  EXPECT_FALSE(standby.hear("073#", at_ms(800)));
  EXPECT_TRUE(standby.sent_on("071#").empty());
}

// §5.1 / DSP 302 §5.5.3.1: "Any device with NMT master capability will reply with a reserved
// identifier frame and zero data field": 75h asks, 74h answers (Figure 19), whether the device
// takes part in the flying master process or not (Table 15, bit 5), and in standby too (Table
// 15: bit 0 "shall stay 1b always, even in case it loses the flying NMT master negotiation").
TEST(FlyingMasterProcess, MasterCapableDevicesAnswer75hWith74h_5_1_Table15) {
  {
    SCOPED_TRACE("no flying master (1F80h bit 5 clear)");
    Rig rig(4, 1);
    EXPECT_TRUE(rig.hear("075#", at_ms(10)));
    ASSERT_EQ(rig.sent.size(), 1U);
    EXPECT_EQ(rig.sent[0].text, "074#");
    EXPECT_EQ(rig.sent[0].at, at_ms(10));
  }
  {
    SCOPED_TRACE("standby");
    Rig rig(5, 1);
    rig.start(at_ms(0));
    rig.run_until(at_ms(500));
    EXPECT_TRUE(rig.hear(reply_71(0, 4), at_ms(510)));
    ASSERT_EQ(rig.engine.phase(), Phase::Standby);
    EXPECT_TRUE(rig.hear("075#", at_ms(600)));
    EXPECT_EQ(rig.sent_on("074#", at_ms(600)).size(), 1U);
  }
  {
    SCOPED_TRACE("not master-capable (1F80h bit 0 clear)");
    Rig rig(4, 1);
    rig.port.capable = false;
    EXPECT_FALSE(rig.hear("075#", at_ms(10)));
    EXPECT_TRUE(rig.sent.empty());
  }
}

// §5.3 / DSP 302 §5.5.1.3: "If the device receives again an 'ID trigger timeslot' the timers
// have to be restarted." A foreign 72h during the wait postpones the 71h by as much.
TEST(FlyingMasterProcess, AnotherTriggerRestartsTheWaitingTime_DSP302_5_5_1_3) {
  Rig rig(4, 1);
  const TimePoint first = rig.negotiate_alone(at_ms(50));
  const auto began = rig.events_of(Kind::NegotiationBegan).size();
  EXPECT_TRUE(rig.hear("072#", first + 700ms));
  rig.run_for(5s);
  auto won = rig.first_on("071#");
  ASSERT_TRUE(won.has_value());
  EXPECT_EQ(won->at, first + 700ms + waiting_time(rig.timing, 4));
  // The same negotiation: the second trigger begins no other.
  EXPECT_EQ(rig.events_of(Kind::NegotiationBegan).size(), began);
}

// ---------------------------------------------------------- §3.7 f, g, i / §5.4: answers --

// §3.7 f: a confirmation of the detection from a master with a higher or the same priority
// level: NMT slave mode, no force (76h), no reset, no negotiation; the active master's
// heartbeat is watched (§5.5.2).
TEST(FlyingMasterProcess, DetectionAnsweredByAHigherOrEqualLevelStandsBy_3_7_f) {
  for (std::uint16_t level : {std::uint16_t{0}, std::uint16_t{2}}) {
    SCOPED_TRACE(level);
    Rig rig(4, 2);
    rig.start(at_ms(0));
    rig.run_until(at_ms(500));
    ASSERT_EQ(rig.sent_on("073#").size(), 1U);
    EXPECT_TRUE(rig.hear(reply_71(level, 6), at_ms(501)));
    EXPECT_EQ(rig.engine.phase(), Phase::Standby);
    EXPECT_EQ(rig.port.startup, StartupState::Standby);
    EXPECT_EQ(rig.engine.active_master(), 6_node);
    rig.run_for(150ms);  // past the detection's timeout: still nothing
    EXPECT_TRUE(rig.sent_on("076#").empty());
    EXPECT_TRUE(rig.sent_on("072#").empty());
    EXPECT_EQ(rig.port.resets, 0);
    auto standby = rig.events_of(Kind::Standby);
    ASSERT_EQ(standby.size(), 1U);
    EXPECT_EQ(standby[0].node_id, 6);
    EXPECT_EQ(standby[0].priority, level);
    // Why: level 0 is higher than this device's 2, level 2 the same (Table 48: 0 is high).
    ASSERT_TRUE(standby[0].flying.has_value());
    EXPECT_EQ(standby[0].flying->reason,
              level == 2 ? FlyingMasterReason::SamePriority : FlyingMasterReason::HigherPriority);
    EXPECT_EQ(standby[0].flying->own_priority, 2U);
    EXPECT_TRUE(rig.events_of(Kind::ForceNegotiation).empty());
  }
}

// §3.7 g, §5.4: the active master's priority level is lower than the own: force NMT flying
// master negotiation (76h, no data, DSP 302 Figure 18) at once, and wait for its reset.
TEST(FlyingMasterProcess, DetectionAnsweredByALowerLevelForcesNegotiation_3_7_g_5_4) {
  Rig rig(4, 0);
  rig.start(at_ms(0));
  rig.run_until(at_ms(500));
  EXPECT_TRUE(rig.hear(reply_71(2, 6), at_ms(501)));
  auto force = rig.first_on("076#");
  ASSERT_TRUE(force.has_value());
  EXPECT_EQ(force->text, "076#");
  EXPECT_EQ(force->at, at_ms(501));
  EXPECT_EQ(rig.engine.phase(), Phase::Forced);
  EXPECT_EQ(rig.port.startup, StartupState::Negotiating);
  auto forced = rig.events_of(Kind::ForceNegotiation);
  ASSERT_EQ(forced.size(), 1U);
  EXPECT_EQ(forced[0].node_id, 6);
  EXPECT_EQ(forced[0].priority, 2U);
  ASSERT_TRUE(forced[0].flying.has_value());
  EXPECT_EQ(forced[0].flying->reason, FlyingMasterReason::LowerPriority);
  EXPECT_EQ(forced[0].flying->own_priority, 0U);
  // The active master's reset communication restarts this device (DSP 302 §5.5.1.2).
  EXPECT_TRUE(rig.hear("000#8200", at_ms(510)));
  EXPECT_EQ(rig.port.restart_at, at_ms(510));
  EXPECT_EQ(rig.port.resets, 0);
}

// §3.7 i: "In case a confirmation for the service NMT flying master negotiation is received and
// the priority of the active NMT master is lower then the own priority" it forces; a winner of the
// same level (a 71h sooner than the node-ID slots say, timing parameters that differ) is taken.
TEST(FlyingMasterProcess, NegotiationWonByEqualLevelIsTakenByLowerLevelForced_3_7_i) {
  for (std::uint16_t winner : {std::uint16_t{1}, std::uint16_t{2}}) {
    SCOPED_TRACE(winner);
    Rig rig(4, 1);
    const TimePoint trigger = rig.negotiate_alone(at_ms(50));
    const TimePoint sent = trigger + 100ms;
    EXPECT_TRUE(rig.hear(reply_71(winner, 9), sent));
    rig.run_for(50ms);
    if (winner == 1) {
      EXPECT_TRUE(rig.sent_on("076#", sent).empty());
      EXPECT_EQ(rig.port.startup, StartupState::Standby);
      EXPECT_EQ(rig.engine.active_master(), 9_node);
    } else {
      auto force = rig.first_on("076#", sent);
      ASSERT_TRUE(force.has_value());
      EXPECT_EQ(force->text, "076#");
      EXPECT_EQ(force->at, sent);
      EXPECT_EQ(rig.events_of(Kind::ForceNegotiation).size(), 1U);
    }
    EXPECT_TRUE(rig.events_of(Kind::ActiveMaster).empty());
  }
}

// DSP 302 §5.5.2 hint: no second force after one that a worse master won again (wrongly
// configured timing parameters), else the network never settles.
TEST(FlyingMasterProcess, LoserDoesNotForceAgainAfterLosingTwice_DSP302_5_5_2_Hint) {
  // Node 100 has priority 0 but waits 100 x 100 ms; node 5 (priority 1, defaults) 1550 ms.
  Rig rig(100, 0);
  rig.timing.priority_slot = 13000ms;
  rig.timing.node_slot = 100ms;
  rig.start(at_ms(0));
  rig.run_until(at_ms(500));
  EXPECT_TRUE(rig.hear(reply_71(1, 5), at_ms(501)));
  ASSERT_EQ(rig.sent_on("076#").size(), 1U);
  // The active master resets all nodes; node 5 wins the negotiation again.
  EXPECT_TRUE(rig.hear("000#8200", at_ms(510)));
  rig.start(at_ms(510));
  rig.run_until(at_ms(1110));  // 73h at 1010, no answer: 72h at 1110
  ASSERT_EQ(rig.sent_on("072#").size(), 1U);
  EXPECT_TRUE(rig.hear(reply_71(1, 5), at_ms(1110) + 1550ms));
  EXPECT_EQ(rig.engine.phase(), Phase::Standby);
  // After the next reset (its start-up) and the detection, 5's answer makes it stand by again.
  EXPECT_TRUE(rig.hear("000#8200", at_ms(2800)));
  rig.start(at_ms(2800));
  rig.run_until(at_ms(3300));
  EXPECT_TRUE(rig.hear(reply_71(1, 5), at_ms(3301)));
  EXPECT_EQ(rig.engine.phase(), Phase::Standby);
  EXPECT_EQ(rig.sent_on("076#").size(), 1U);
  EXPECT_EQ(rig.events_of(Kind::ForceNegotiation).size(), 1U);
}

// ------------------------------------------------------------- §5.5: detection of failures --

// §5.5.3: "Active NMT masters shall cyclically initiate the service force NMT flying master
// negotiation without itself initiating the NMT service Reset communication", every 1F90h sub 6
// (default 4000 + 10 x node-ID ms).
TEST(FlyingMasterProcess, ActiveMasterSends76hEvery1F90Sub6WithoutResettingItself_5_5_3) {
  for (std::int64_t cycle : {4040, 1500}) {
    SCOPED_TRACE(cycle);
    Rig rig(4, 1);
    rig.timing.cycle = ms(cycle);
    const TimePoint active = rig.win_alone(at_ms(50));
    rig.run_for(15s);
    auto forces = rig.sent_on("076#", active);
    ASSERT_GE(forces.size(), 3U);
    for (std::size_t i = 0; i < forces.size(); ++i) {
      EXPECT_EQ(forces[i].text, "076#");
      EXPECT_EQ(forces[i].at, active + static_cast<std::int64_t>(i + 1) * ms(cycle)) << i;
    }
    EXPECT_EQ(rig.port.resets, 1);  // §3.7 d's, before it won
    EXPECT_FALSE(rig.port.restart_at > active);
    EXPECT_TRUE(rig.sent_on("072#", active).empty());
    EXPECT_EQ(rig.events_of(Kind::ActiveMaster).size(), 1U);
  }
}

// §5.5.3 / §5.4: an active master that hears a 76h resets communication of all nodes, itself
// included, and negotiates again; a standby master ignores it.
TEST(FlyingMasterProcess, ActiveMasterAnswers76hWithResetOfAllNodes_5_4_5_5_3) {
  Rig rig(4, 1);
  const TimePoint active = rig.win_alone(at_ms(50));
  EXPECT_TRUE(rig.hear("076#", active + 1s));
  EXPECT_EQ(rig.port.resets, 2);
  EXPECT_EQ(rig.port.restart_at, active + 1s);
  EXPECT_EQ(rig.events_of(Kind::MultipleMasters).size(), 1U);

  Rig standby(5, 1);
  standby.start(at_ms(0));
  standby.run_until(at_ms(500));
  EXPECT_TRUE(standby.hear(reply_71(0, 4), at_ms(501)));
  EXPECT_FALSE(standby.hear("076#", at_ms(700)));  // within its heartbeat watch (300 ms)
  EXPECT_EQ(standby.port.resets, 0);
}

// §5.5.2: "The loss of the active NMT master shall be detected by every NMT master capable
// CANopen device by monitoring the heartbeat of the active NMT master", with the consumer time
// of 1016h (NOTE 2), else 2 x 1017h + 100 ms (nmt_master.hpp); then reset communication of all
// nodes and negotiation. Each heartbeat of the active master starts the watch again; its
// boot-up does not.
TEST(FlyingMasterProcess, StandbyWatchesTheActiveMastersHeartbeat_5_5_2) {
  struct Case {
    std::optional<Duration> consumer;
    Duration watch;
  };
  for (const Case& c : {Case{std::nullopt, 300ms}, Case{250ms, 250ms}}) {
    SCOPED_TRACE(c.watch.count());
    Rig rig(5, 1);
    if (c.consumer) rig.port.consumer[11] = *c.consumer;
    rig.start(at_ms(0));
    rig.run_until(at_ms(500));
    EXPECT_TRUE(rig.hear(reply_71(0, 11), at_ms(501)));
    ASSERT_EQ(rig.engine.phase(), Phase::Standby);
    EXPECT_FALSE(rig.hear("70B#05", at_ms(600)));
    EXPECT_FALSE(rig.hear("70B#00", at_ms(650)));  // a boot-up: not a heartbeat
    rig.run_until(at_ms(600) + c.watch - 1ms);
    EXPECT_EQ(rig.port.resets, 0);
    rig.run_until(at_ms(600) + c.watch);
    EXPECT_EQ(rig.port.resets, 1);
    EXPECT_EQ(rig.port.restart_at, at_ms(600) + c.watch);
    auto lost = rig.events_of(Kind::ActiveMasterLost);
    ASSERT_EQ(lost.size(), 1U);
    EXPECT_EQ(lost[0].node_id, 11);
    EXPECT_EQ(lost[0].at, at_ms(600) + c.watch);
  }
}

// A standby master is an NMT slave: it obeys the active master's NMT commands for it or for
// all; a reset communication starts its flying master start-up again (DSP 302 §5.5.1.2).
TEST(FlyingMasterProcess, StandbyMasterObeysNmtCommandsAndNegotiatesAfterAReset_5_5_1_2) {
  Rig rig(5, 1);
  rig.start(at_ms(0));
  rig.run_until(at_ms(500));
  EXPECT_TRUE(rig.hear(reply_71(0, 4), at_ms(501)));
  EXPECT_TRUE(rig.hear("000#0100", at_ms(600)));
  EXPECT_TRUE(rig.hear("000#0205", at_ms(700)));
  EXPECT_FALSE(rig.hear("000#8006", at_ms(800)));  // another node's
  EXPECT_EQ(rig.port.obeyed, (std::vector<NmtCommand>{NmtCommand::Start, NmtCommand::Stop}));
  EXPECT_TRUE(rig.hear("000#8105", at_ms(900)));
  EXPECT_EQ(rig.port.restart_at, at_ms(900));
  EXPECT_EQ(rig.engine.phase(), Phase::Delay);
}

// ------------------------------------------------ §5.1: NMT master detection (1F91h) --------

// §5.1: "The service shall be initiated by the CANopen device after the CANopen device switched
// into the NMT state Pre-operational and an additional time delay (see object 1F91h sub-index
// 02h) ... In case no confirmation is received [within 1F91h sub 1] the CANopen device ... may
// execute the NMT service Start remote node ... after ... wait time = Node-ID x Node time slot"
// (1F91h sub 3; defaults 100, 500, 15 ms, Table 52); DSP 302 Figure 19: 75h without data.
TEST(FlyingMasterProcess, StartingDeviceDetectsMastersBeforeStartingAll_5_1) {
  Rig rig(4, 1);
  rig.engine.detect_master(kDetectionDefaults, at_ms(50));
  rig.now = at_ms(50);
  rig.run_until(at_ms(50) + 500ms + 100ms + 4 * 15ms - 1ms);
  auto request = rig.first_on("075#");
  ASSERT_TRUE(request.has_value());
  EXPECT_EQ(request->text, "075#");
  EXPECT_EQ(request->at, at_ms(50) + 500ms);
  EXPECT_TRUE(rig.port.queued.empty());
  rig.run_until(at_ms(50) + 500ms + 100ms + 4 * 15ms);
  EXPECT_EQ(rig.port.queued,
            (std::vector<std::pair<NmtCommand, std::uint8_t>>{{NmtCommand::Start, 0}}));
  EXPECT_EQ(rig.events_of(Kind::MasterDetection).size(), 1U);
  EXPECT_EQ(rig.engine.next_deadline(), std::nullopt);
}

// Without 1F91h the device starts all nodes at once (Table 16, 00000010b).
TEST(FlyingMasterProcess, StartingDeviceWithout1F91hStartsAllAtOnce_Table16) {
  Rig rig(4, 1);
  rig.engine.detect_master(std::nullopt, at_ms(50));
  EXPECT_EQ(rig.port.queued,
            (std::vector<std::pair<NmtCommand, std::uint8_t>>{{NmtCommand::Start, 0}}));
  EXPECT_EQ(rig.engine.next_deadline(), std::nullopt);
}

// DSP 302 §5.5.3.1: "If one or more devices answer ... the requesting device knows that there
// exist at least one device with the capability to become NMT master": no start.
TEST(FlyingMasterProcess, StartingDeviceLeavesTheNetworkToAnAnsweringMaster_5_1) {
  Rig rig(4, 1);
  rig.engine.detect_master(kDetectionDefaults, at_ms(0));
  rig.run_until(at_ms(500));
  EXPECT_TRUE(rig.hear("074#", at_ms(520)));
  rig.run_for(3s);
  EXPECT_TRUE(rig.port.queued.empty());
  EXPECT_EQ(rig.events_of(Kind::MasterDetection).size(), 1U);
}

// DSP 302 §5.5.3.1: "the devices have a node-ID-based waiting period": one that hears another's
// start of all nodes while it waits sends none.
TEST(FlyingMasterProcess, StartingDeviceThatHearsAStartAllSendsNone_DSP302_5_5_3_1) {
  Rig rig(6, 1);
  rig.engine.detect_master(kDetectionDefaults, at_ms(0));
  rig.run_until(at_ms(600));  // 75h at 500, no answer by 600: waiting 6 x 15 ms
  EXPECT_FALSE(rig.hear("000#0100", at_ms(660)));
  rig.run_for(3s);
  EXPECT_TRUE(rig.port.queued.empty());
  EXPECT_EQ(rig.events_of(Kind::MasterDetection).size(), 2U);
}

// 1F90h written while the engine runs: the next steps use it (set_timing, from the master's
// write check), here the priority of its answer to a detection.
TEST(FlyingMasterProcess, WrittenTimingGovernsTheNextSteps_6_13) {
  Rig rig(4, 1);
  const TimePoint active = rig.win_alone(at_ms(50));
  auto timing = rig.timing;
  timing.priority = 0;
  rig.engine.set_timing(timing);
  EXPECT_TRUE(rig.hear("073#", active + 10ms));
  EXPECT_EQ(rig.first_on("071#", active + 10ms)->text, reply_71(0, 4));
}

}  // namespace
}  // namespace nmt
