// Heartbeat, node guarding and life guarding (CiA 301 §7.2.8.3.2) and the start-error-control
// timing rule of CiA 302-2 §4.1. Frame bytes: spec/002_*.txt (heartbeat "705 1 7F", guarding
// replies "701 7F" then "701 FF", state values 04/05/7F).
#include "nmt/protocol/error_control.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

namespace nmt {
namespace {

using namespace cfg::literals;

using std::chrono::milliseconds;

TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}

CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

// The engines through their one shape (nmt/engine.hpp), read back as what each call produced.

// A frame fed to an engine that answers no frames: the events it reported.
template <class E>
std::vector<typename E::Event> feed(E& engine, const CanFrame& f, TimePoint now) {
  typename E::Output out;
  (void)engine.on_frame(f, now, out);
  EXPECT_TRUE(out.frames.empty());
  return out.events;
}
// A timer call of an engine that sends no frames from it: the events it reported.
template <class E>
std::vector<typename E::Event> tick(E& engine, TimePoint now) {
  typename E::Output out;
  engine.on_timer(now, out);
  EXPECT_TRUE(out.frames.empty());
  return out.events;
}
// The guarding master's timer: requests are appended to `frames`, events returned.
std::vector<NodeGuardingEvent> tick(NodeGuardingMaster& m, TimePoint now,
                                    std::vector<CanFrame>& frames) {
  NodeGuardingMaster::Output out;
  m.on_timer(now, out);
  frames.insert(frames.end(), out.frames.begin(), out.frames.end());
  return out.events;
}
// The guarding master's start: its first request goes out with it (engine.hpp rule 5) and is
// appended to `frames`.
void start(NodeGuardingMaster& m, std::uint8_t node, std::uint16_t guard_time_ms,
           std::uint8_t life_time_factor, TimePoint now, std::vector<CanFrame>& frames) {
  NodeGuardingMaster::Output out;
  EXPECT_TRUE(m.start(*cfg::NodeId::from(node), guard_time_ms, life_time_factor, now, out));
  EXPECT_TRUE(out.events.empty());
  frames.insert(frames.end(), out.frames.begin(), out.frames.end());
}
// The heartbeat the producer sends at `now` for `node` in `state`, if one is due.
std::optional<CanFrame> beat(HeartbeatProducer& p, TimePoint now, std::uint8_t node,
                             NmtState state) {
  p.set_node_id(*cfg::NodeId::from(node));
  p.set_state(state);
  HeartbeatProducer::Output out;
  p.on_timer(now, out);
  EXPECT_LE(out.frames.size(), 1u);
  if (out.frames.empty()) return std::nullopt;
  return out.frames.front();
}
// What the guarded slave does with a frame: its reply and its life guarding event.
struct GuardResult {
  std::optional<CanFrame> reply;
  std::optional<LifeGuardingEvent> event;
};
GuardResult guard(NodeGuardingSlave& g, const CanFrame& f, TimePoint now, std::uint8_t node,
                  NmtState state) {
  g.set_node_id(*cfg::NodeId::from(node));
  g.set_state(state);
  NodeGuardingSlave::Output out;
  const bool taken = g.on_frame(f, now, out);
  EXPECT_EQ(taken, !out.frames.empty());
  EXPECT_LE(out.frames.size(), 1u);
  EXPECT_LE(out.events.size(), 1u);
  GuardResult r;
  if (!out.frames.empty()) r.reply = out.frames.front();
  if (!out.events.empty()) r.event = out.events.front();
  return r;
}
std::optional<LifeGuardingEvent> life(NodeGuardingSlave& g, TimePoint now) {
  auto events = tick(g, now);
  EXPECT_LE(events.size(), 1u);
  if (events.empty()) return std::nullopt;
  return events.front();
}

static_assert(Engine<HeartbeatProducer>);
static_assert(Engine<HeartbeatConsumer>);
static_assert(Engine<NodeGuardingSlave>);
static_assert(Engine<NodeGuardingMaster>);

// --- heartbeat producer ---

TEST(HeartbeatProducer, SendsStateEveryPeriodAfterBootUp) {
  HeartbeatProducer p(1_node);
  p.set_period(100, at_ms(0));
  p.on_boot_up(at_ms(0));  // the boot-up message counts as the first heartbeat
  EXPECT_EQ(p.next_deadline(), at_ms(100));
  EXPECT_FALSE(beat(p, at_ms(99), 5, NmtState::PreOperational).has_value());
  auto hb = beat(p, at_ms(100), 5, NmtState::PreOperational);
  ASSERT_TRUE(hb.has_value());
  EXPECT_EQ(to_candump(*hb), "705#7F");
  EXPECT_EQ(p.next_deadline(), at_ms(200));
  auto op = beat(p, at_ms(200), 5, NmtState::Operational);
  ASSERT_TRUE(op.has_value());
  EXPECT_EQ(to_candump(*op), "705#05");
  EXPECT_EQ(to_candump(*beat(p, at_ms(300), 5, NmtState::Stopped)), "705#04");
}

TEST(HeartbeatProducer, ZeroPeriodDisablesTheProducer) {
  HeartbeatProducer p(1_node);
  p.on_boot_up(at_ms(0));
  EXPECT_FALSE(p.next_deadline().has_value());
  p.set_period(50, at_ms(10));
  EXPECT_EQ(p.next_deadline(), at_ms(10));  // CiA 301: starts immediately when written at run time
  p.set_period(0, at_ms(20));
  EXPECT_FALSE(p.next_deadline().has_value());
  EXPECT_FALSE(beat(p, at_ms(1000), 1, NmtState::Operational).has_value());
}

TEST(HeartbeatProducer, DoesNotBurstAfterStall) {
  HeartbeatProducer p(1_node);
  p.set_period(10, at_ms(0));
  p.on_boot_up(at_ms(0));
  ASSERT_TRUE(beat(p, at_ms(95), 1, NmtState::Operational).has_value());
  EXPECT_EQ(p.next_deadline(), at_ms(105));
  EXPECT_FALSE(beat(p, at_ms(96), 1, NmtState::Operational).has_value());
}

// --- heartbeat consumer ---

TEST(HeartbeatConsumer, EntryEncodingIsNodeIdInBits16To23AndTimeInBits0To15) {
  // CiA 301 §7.5.2.33: 0x00050064 = node 5, 100 ms.
  auto e = HeartbeatConsumerEntry::decode(0x00050064);
  EXPECT_EQ(e.node_id, 5);
  EXPECT_EQ(e.time_ms, 100);
  EXPECT_TRUE(e.active());
  EXPECT_EQ(e.encode(), 0x00050064u);
  EXPECT_FALSE(HeartbeatConsumerEntry::decode(0x00000064).active());  // node-ID 0: unused
  EXPECT_FALSE(HeartbeatConsumerEntry::decode(0x00050000).active());  // time 0: unused
}

TEST(HeartbeatConsumer, Cia301MonitoringStartsWithFirstHeartbeat) {
  HeartbeatConsumer c;  // timeout_from_start = false
  c.monitor({5, 100}, at_ms(0));
  EXPECT_FALSE(c.next_deadline().has_value());
  EXPECT_TRUE(tick(c, at_ms(10'000)).empty());  // silent node: no event without a heartbeat
  EXPECT_TRUE(feed(c, frame("705#7F"), at_ms(10'000)).empty());
  EXPECT_EQ(c.next_deadline(), at_ms(10'100));
  EXPECT_TRUE(tick(c, at_ms(10'099)).empty());
  auto ev = tick(c, at_ms(10'100));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, HeartbeatEventKind::Timeout);
  EXPECT_EQ(ev[0].node_id, 5);
  EXPECT_EQ(ev[0].at, at_ms(10'100));
}

TEST(HeartbeatConsumer, Cia302StartErrorControlTimesOutSilentNodeFromStart) {
  // CiA 302-2 §4.1: "The timer for timeout checking shall be started immediately with the
  // process itself."
  HeartbeatConsumer c({.timeout_from_start = true});
  c.monitor({5, 100}, at_ms(0));
  EXPECT_EQ(c.next_deadline(), at_ms(100));
  auto ev = tick(c, at_ms(100));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, HeartbeatEventKind::Timeout);
  EXPECT_TRUE(tick(c, at_ms(500)).empty());  // reported once
}

TEST(HeartbeatConsumer, Cia302HeartbeatInTimeEndsStartErrorControlSuccessfully) {
  HeartbeatConsumer c({.timeout_from_start = true});
  c.monitor({5, 100}, at_ms(0));
  EXPECT_TRUE(feed(c, frame("705#7F"), at_ms(60)).empty());
  EXPECT_TRUE(tick(c, at_ms(100)).empty());
  EXPECT_EQ(c.next_deadline(), at_ms(160));
}

TEST(HeartbeatConsumer, HeartbeatAfterTimeoutResolvesAndRearms) {
  HeartbeatConsumer c;
  c.monitor({7, 50}, at_ms(0));
  (void)feed(c, frame("707#05"), at_ms(0));
  ASSERT_EQ(tick(c, at_ms(50)).size(), 1u);
  auto ev = feed(c, frame("707#05"), at_ms(300));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, HeartbeatEventKind::Resolved);
  EXPECT_EQ(ev[0].state, NmtState::Operational);
  EXPECT_EQ(c.next_deadline(), at_ms(350));
}

TEST(HeartbeatConsumer, ReportsStateChangesAndBootUp) {
  HeartbeatConsumer c;
  c.monitor({7, 50}, at_ms(0));
  EXPECT_TRUE(feed(c, frame("707#7F"), at_ms(0)).empty());
  auto changed = feed(c, frame("707#05"), at_ms(10));
  ASSERT_EQ(changed.size(), 1u);
  EXPECT_EQ(changed[0].kind, HeartbeatEventKind::StateChanged);
  EXPECT_EQ(changed[0].state, NmtState::Operational);
  auto boot = feed(c, frame("707#00"), at_ms(20));
  ASSERT_EQ(boot.size(), 1u);
  EXPECT_EQ(boot[0].kind, HeartbeatEventKind::BootUp);
  EXPECT_FALSE(c.next_deadline().has_value());  // waits for a heartbeat again
}

TEST(HeartbeatConsumer, IgnoresUnmonitoredNodesAndOtherFrames) {
  HeartbeatConsumer c({.timeout_from_start = true});
  c.monitor({7, 50}, at_ms(0));
  EXPECT_TRUE(feed(c, frame("708#05"), at_ms(10)).empty());
  EXPECT_TRUE(feed(c, frame("707#R1"), at_ms(10)).empty());
  EXPECT_TRUE(feed(c, frame("707#0500"), at_ms(10)).empty());
  EXPECT_TRUE(feed(c, frame("707#12"), at_ms(10)).empty());  // 0x12 is no NMT state
  EXPECT_EQ(tick(c, at_ms(50)).size(), 1u);  // none of these was a heartbeat of node 7
}

TEST(HeartbeatConsumer, InactiveEntryStopsMonitoring) {
  HeartbeatConsumer c({.timeout_from_start = true});
  c.monitor({7, 50}, at_ms(0));
  c.monitor({7, 0}, at_ms(10));
  EXPECT_FALSE(c.monitors(7_node));
  EXPECT_TRUE(tick(c, at_ms(100)).empty());
}

TEST(HeartbeatConsumer, MonitorsSeveralNodesIndependently) {
  HeartbeatConsumer c({.timeout_from_start = true});
  c.monitor({1, 100}, at_ms(0));
  c.monitor({2, 200}, at_ms(0));
  (void)feed(c, frame("701#05"), at_ms(90));
  (void)feed(c, frame("701#05"), at_ms(150));
  auto ev = tick(c, at_ms(200));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].node_id, 2);
  EXPECT_EQ(c.next_deadline(), at_ms(250));
}

// Engine rule 4 with all 127 nodes monitored: each times out at its own consumer time, earliest
// first, and one late timer call reports the overdue ones in the order their times expired.
TEST(HeartbeatConsumer, ManyNodesTimeOutInTheOrderOfTheirConsumerTimes) {
  HeartbeatConsumer c({.timeout_from_start = true});
  // Node n: (228 - n) ms, so node 127 expires first and node 1 last.
  for (int n = 1; n <= 127; ++n) {
    c.monitor({static_cast<std::uint8_t>(n), static_cast<std::uint16_t>(228 - n)}, at_ms(0));
  }
  for (int n = 127; n >= 21; --n) {
    ASSERT_EQ(c.next_deadline(), at_ms(228 - n));
    EXPECT_TRUE(tick(c, at_ms(227 - n)).empty());
    auto ev = tick(c, at_ms(228 - n));
    ASSERT_EQ(ev.size(), 1u) << "node " << n;
    EXPECT_EQ(ev[0].node_id, n);
    EXPECT_EQ(ev[0].at, at_ms(228 - n));
  }
  auto late = tick(c, at_ms(1000));  // nodes 20..1 all overdue
  ASSERT_EQ(late.size(), 20u);
  for (int i = 0; i < 20; ++i) {
    EXPECT_EQ(late[i].node_id, 20 - i);
    EXPECT_EQ(late[i].at, at_ms(208 + i));
    EXPECT_EQ(late[i].kind, HeartbeatEventKind::Timeout);
  }
  EXPECT_EQ(c.next_deadline(), std::nullopt);
}

TEST(HeartbeatConsumer, NextDeadlineIsTheEarliestAfterHeartbeatsRestartsAndStops) {
  HeartbeatConsumer c({.timeout_from_start = true});
  c.monitor({1, 100}, at_ms(0));
  c.monitor({2, 200}, at_ms(0));
  c.monitor({3, 300}, at_ms(0));
  c.monitor({4, 400}, at_ms(0));
  EXPECT_EQ(c.next_deadline(), at_ms(100));
  (void)feed(c, frame("701#05"), at_ms(150));  // node 1 re-armed: 250
  EXPECT_EQ(c.next_deadline(), at_ms(200));
  c.stop(2_node);
  EXPECT_EQ(c.next_deadline(), at_ms(250));
  (void)feed(c, frame("701#00"), at_ms(160));  // boot-up: node 1 waits for a heartbeat
  EXPECT_EQ(c.next_deadline(), at_ms(300));
  c.monitor({3, 0}, at_ms(170));  // an inactive entry stops node 3
  EXPECT_EQ(c.next_deadline(), at_ms(400));
  c.monitor({4, 50}, at_ms(170));  // a restart replaces node 4's time
  EXPECT_EQ(c.next_deadline(), at_ms(220));
  EXPECT_TRUE(tick(c, at_ms(219)).empty());
  auto ev = tick(c, at_ms(400));
  ASSERT_EQ(ev.size(), 1u);  // node 4 at 220, once; nothing left of its 400
  EXPECT_EQ(ev[0].node_id, 4);
  EXPECT_EQ(ev[0].at, at_ms(220));
  EXPECT_EQ(c.next_deadline(), std::nullopt);
  c.monitor({5, 10}, at_ms(500));
  c.stop_all();
  EXPECT_EQ(c.next_deadline(), std::nullopt);
  EXPECT_TRUE(tick(c, at_ms(1000)).empty());
}

// --- node guarding / life guarding ---

TEST(NodeGuardingSlave, RepliesWithToggleBitStartingAtZero) {
  NodeGuardingSlave g(1_node);
  const CanFrame rtr = frame("705#R1");
  auto r1 = guard(g, rtr, at_ms(0), 5, NmtState::Operational);
  ASSERT_TRUE(r1.reply.has_value());
  EXPECT_EQ(to_candump(*r1.reply), "705#05");
  EXPECT_EQ(to_candump(*guard(g, rtr, at_ms(10), 5, NmtState::Operational).reply), "705#85");
  EXPECT_EQ(to_candump(*guard(g, rtr, at_ms(20), 5, NmtState::Operational).reply), "705#05");
}

TEST(NodeGuardingSlave, PreOperationalRepliesMatchSpecExample) {
  // spec/002: "701 7F" then "701 FF" for node 1 in pre-operational.
  NodeGuardingSlave g(1_node);
  const CanFrame rtr = frame("701#R");
  EXPECT_EQ(to_candump(*guard(g, rtr, at_ms(0), 1, NmtState::PreOperational).reply), "701#7F");
  EXPECT_EQ(to_candump(*guard(g, rtr, at_ms(1), 1, NmtState::PreOperational).reply), "701#FF");
}

TEST(NodeGuardingSlave, StoppedStateIsFour) {
  NodeGuardingSlave g(1_node);
  EXPECT_EQ(to_candump(*guard(g, frame("705#R1"), at_ms(0), 5, NmtState::Stopped).reply), "705#04");
}

TEST(NodeGuardingSlave, ResetReturnsToggleToZero) {
  NodeGuardingSlave g(1_node);
  (void)guard(g, frame("705#R1"), at_ms(0), 5, NmtState::Operational);
  g.reset();
  EXPECT_EQ(to_candump(*guard(g, frame("705#R1"), at_ms(1), 5, NmtState::PreOperational).reply),
            "705#7F");
}

TEST(NodeGuardingSlave, IgnoresOtherNodesAndDataFrames) {
  NodeGuardingSlave g(1_node);
  EXPECT_FALSE(guard(g, frame("706#R1"), at_ms(0), 5, NmtState::Operational).reply);
  EXPECT_FALSE(guard(g, frame("705#05"), at_ms(0), 5, NmtState::Operational).reply);
  EXPECT_FALSE(g.toggle());
}

TEST(NodeGuardingSlave, LifeGuardingStartsWithFirstRequestAndFiresAfterLifeTime) {
  NodeGuardingSlave g(1_node);
  g.configure(100, 3);                          // life time 300 ms
  EXPECT_FALSE(g.next_deadline().has_value());  // spec/002: starts with the first remote frame
  (void)guard(g, frame("705#R1"), at_ms(1000), 5, NmtState::Operational);
  EXPECT_EQ(g.next_deadline(), at_ms(1300));
  (void)guard(g, frame("705#R1"), at_ms(1100), 5, NmtState::Operational);
  EXPECT_FALSE(life(g, at_ms(1399)).has_value());
  EXPECT_EQ(life(g, at_ms(1400)), LifeGuardingEvent::Occurred);
  EXPECT_FALSE(life(g, at_ms(2000)).has_value());  // reported once
  auto again = guard(g, frame("705#R1"), at_ms(2000), 5, NmtState::Operational);
  EXPECT_EQ(again.event, LifeGuardingEvent::Resolved);
  EXPECT_EQ(g.next_deadline(), at_ms(2300));
}

TEST(NodeGuardingSlave, LifeGuardingNeedsBothGuardTimeAndLifeTimeFactor) {
  NodeGuardingSlave g(1_node);
  g.configure(100, 0);
  (void)guard(g, frame("705#R1"), at_ms(0), 5, NmtState::Operational);
  EXPECT_FALSE(g.next_deadline().has_value());
  g.configure(0, 3);
  EXPECT_FALSE(g.next_deadline().has_value());
  EXPECT_FALSE(life(g, at_ms(100'000)).has_value());
}

TEST(ErrorControl, FramesAreEncodedAsTheSpecExamples) {
  EXPECT_EQ(to_candump(make_heartbeat(5_node, NmtState::PreOperational)), "705#7F");
  EXPECT_EQ(to_candump(make_guarding_request(1_node)), "701#R1");
  auto msg = parse_error_control(frame("701#FF"));
  ASSERT_TRUE(msg.has_value());
  EXPECT_EQ(msg->node_id, 1);
  EXPECT_TRUE(msg->toggle());
  EXPECT_EQ(msg->state(), NmtState::PreOperational);
  EXPECT_FALSE(parse_error_control(frame("700#05")).has_value());  // node-ID 0
  EXPECT_FALSE(parse_error_control(frame("780#05")).has_value());
}

// --- node guarding, master side ---

std::vector<std::string> texts(const std::vector<CanFrame>& frames) {
  std::vector<std::string> out;
  for (const auto& f : frames) out.push_back(to_candump(f));
  return out;
}

TEST(NodeGuardingMaster, SendsARequestEveryGuardTime) {
  NodeGuardingMaster m;
  std::vector<CanFrame> out;
  start(m, 5, 100, 3, at_ms(0), out);  // the first request goes out with the start
  EXPECT_EQ(texts(out), std::vector<std::string>{"705#R1"});
  EXPECT_EQ(m.next_deadline(), at_ms(100));
  EXPECT_TRUE(tick(m, at_ms(0), out).empty());  // a second call at `now` sends nothing more
  (void)tick(m, at_ms(50), out);
  EXPECT_EQ(texts(out), std::vector<std::string>{"705#R1"});
  (void)tick(m, at_ms(100), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"705#R1", "705#R1"}));
  EXPECT_EQ(m.next_deadline(), at_ms(200));
}

// CiA 302-2 §6.3: a guard time or retry factor of 0 disables guarding; a start with one is
// refused and leaves everything as it was (engine.hpp rule 5, "could not start").
TEST(NodeGuardingMaster, StartWithZeroGuardTimeOrLifeTimeFactorIsRefused) {
  NodeGuardingMaster m;
  NodeGuardingMaster::Output out;
  EXPECT_FALSE(m.start(5_node, 0, 3, at_ms(0), out));
  EXPECT_FALSE(m.start(5_node, 100, 0, at_ms(0), out));
  EXPECT_TRUE(out.empty());
  EXPECT_FALSE(m.guards(5_node));
  EXPECT_EQ(m.next_deadline(), std::nullopt);

  std::vector<CanFrame> frames;
  start(m, 6, 100, 3, at_ms(0), frames);
  EXPECT_FALSE(m.start(6_node, 0, 3, at_ms(10), out));
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(m.guards(6_node));
  EXPECT_EQ(m.next_deadline(), at_ms(100));
}

// guard() is start() as a parameter write (engine.hpp rule 5): nothing goes out at once, the
// first request is due at `now` and leaves at the next on_timer, the next one guard time later.
TEST(NodeGuardingMaster, GuardMakesTheFirstRequestDueAtNow) {
  NodeGuardingMaster m;
  EXPECT_TRUE(m.guard(5_node, 100, 3, at_ms(20)));
  EXPECT_TRUE(m.guards(5_node));
  EXPECT_EQ(m.next_deadline(), at_ms(20));
  std::vector<CanFrame> out;
  EXPECT_TRUE(tick(m, at_ms(20), out).empty());
  EXPECT_EQ(texts(out), std::vector<std::string>{"705#R1"});
  EXPECT_EQ(m.next_deadline(), at_ms(120));
  EXPECT_FALSE(m.guard(6_node, 0, 3, at_ms(20)));  // §6.3: refused as start() refuses it
  EXPECT_FALSE(m.guards(6_node));
}

TEST(NodeGuardingMaster, AlternatingRepliesKeepTheNodeGuarded) {
  NodeGuardingMaster m;
  std::vector<CanFrame> out;
  start(m, 5, 100, 1, at_ms(0), out);
  const char* replies[] = {"705#7F", "705#FF", "705#7F", "705#FF"};  // spec/002 sequence
  for (int i = 0; i < 4; ++i) {
    EXPECT_TRUE(tick(m, at_ms(100 * i), out).empty());
    EXPECT_TRUE(feed(m, frame(replies[i]), at_ms(100 * i + 5)).empty());
  }
  EXPECT_TRUE(tick(m, at_ms(400), out).empty());
}

TEST(NodeGuardingMaster, TimesOutAfterLifeTimeFactorMissedReplies) {
  NodeGuardingMaster m;
  std::vector<CanFrame> out;
  start(m, 5, 100, 3, at_ms(0), out);
  EXPECT_TRUE(tick(m, at_ms(0), out).empty());
  EXPECT_TRUE(tick(m, at_ms(100), out).empty());  // 1 missed
  EXPECT_TRUE(tick(m, at_ms(200), out).empty());  // 2 missed
  auto ev = tick(m, at_ms(300), out);             // 3 missed: life time over
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, NodeGuardingEventKind::Timeout);
  EXPECT_EQ(ev[0].at, at_ms(300));
  EXPECT_TRUE(tick(m, at_ms(400), out).empty());  // reported once
  EXPECT_EQ(out.size(), 5u);                      // requests go on
  auto back = feed(m, frame("705#05"), at_ms(410));
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].kind, NodeGuardingEventKind::Resolved);
  EXPECT_EQ(back[0].state, NmtState::Operational);
}

TEST(NodeGuardingMaster, ReplyWithRepeatedToggleBitCountsAsMissed) {
  NodeGuardingMaster m;
  std::vector<CanFrame> out;
  start(m, 5, 100, 1, at_ms(0), out);
  EXPECT_TRUE(feed(m, frame("705#85"), at_ms(5)).empty());  // first reply must have toggle 0
  auto ev = tick(m, at_ms(100), out);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, NodeGuardingEventKind::Timeout);
  // Resynchronised: the device's next reply (toggle 0) is valid again.
  EXPECT_EQ(feed(m, frame("705#05"), at_ms(105)).size(), 1u);  // Resolved
}

TEST(NodeGuardingMaster, ReportsStateChanges) {
  NodeGuardingMaster m;
  std::vector<CanFrame> out;
  start(m, 5, 100, 2, at_ms(0), out);
  EXPECT_TRUE(feed(m, frame("705#7F"), at_ms(5)).empty());
  (void)tick(m, at_ms(100), out);
  auto ev = feed(m, frame("705#85"), at_ms(105));
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].kind, NodeGuardingEventKind::StateChanged);
  EXPECT_EQ(ev[0].state, NmtState::Operational);
}

TEST(NodeGuardingMaster, GuardsTheSlaveEngineWithoutEvents) {
  // Master and slave engines exchanging frames directly for 10 s of guarding at 100 ms, life
  // time factor 3 on both sides.
  NodeGuardingMaster m;
  NodeGuardingSlave s(9_node);
  s.configure(100, 3);
  std::vector<CanFrame> first;
  start(m, 9, 100, 3, at_ms(0), first);
  int requests = 0;
  for (int t = 0; t <= 10'000; t += 10) {
    std::vector<CanFrame> out = t == 0 ? first : std::vector<CanFrame>{};
    EXPECT_TRUE(tick(m, at_ms(t), out).empty());
    for (const auto& request : out) {
      ++requests;
      auto r = guard(s, request, at_ms(t), 9, NmtState::Operational);
      ASSERT_TRUE(r.reply.has_value());
      EXPECT_TRUE(feed(m, *r.reply, at_ms(t + 1)).empty());
    }
    EXPECT_FALSE(life(s, at_ms(t)).has_value());
  }
  EXPECT_EQ(requests, 101);
}

// Engine rule 4 with all 127 nodes guarded at different guard times: every request goes out at
// its own time (k x guard time after the start), none early, none twice, calling on_timer only
// at next_deadline().
TEST(NodeGuardingMaster, ManyNodesAreRequestedEachAtItsOwnGuardTime) {
  NodeGuardingMaster m;
  std::vector<CanFrame> first;
  // Node n: (1000 + 7n) ms.
  const auto guard_ms = [](int n) { return 1000 + 7 * n; };
  for (int n = 1; n <= 127; ++n) {
    start(m, static_cast<std::uint8_t>(n), static_cast<std::uint16_t>(guard_ms(n)), 3, at_ms(0),
          first);
  }
  EXPECT_EQ(first.size(), 127u);
  const std::int64_t end_ms = 5000;
  // What the spec asks for: (time, node) of every later request, earliest first.
  std::vector<std::pair<std::int64_t, std::uint32_t>> expected;
  for (int n = 1; n <= 127; ++n) {
    for (std::int64_t t = guard_ms(n); t <= end_ms; t += guard_ms(n)) {
      expected.emplace_back(t, 0x700u + static_cast<std::uint32_t>(n));
    }
  }
  std::sort(expected.begin(), expected.end());
  std::vector<std::pair<std::int64_t, std::uint32_t>> sent;
  while (m.next_deadline() && *m.next_deadline() <= at_ms(end_ms)) {
    const auto now = *m.next_deadline();
    std::vector<CanFrame> out;
    (void)tick(m, now, out);
    ASSERT_FALSE(out.empty()) << "next_deadline() named a time with nothing due";
    for (const auto& f : out) {
      sent.emplace_back(std::chrono::duration_cast<milliseconds>(now.time_since_epoch()).count(),
                        f.id);
    }
  }
  EXPECT_EQ(sent, expected);
}

TEST(NodeGuardingMaster, NextDeadlineIsTheEarliestAfterRestartsAndStops) {
  NodeGuardingMaster m;
  std::vector<CanFrame> out;
  start(m, 1, 100, 3, at_ms(0), out);
  start(m, 2, 200, 3, at_ms(0), out);
  start(m, 3, 300, 3, at_ms(0), out);
  EXPECT_EQ(m.next_deadline(), at_ms(100));
  m.stop(1_node);
  EXPECT_EQ(m.next_deadline(), at_ms(200));
  start(m, 3, 50, 3, at_ms(20), out);  // a restart replaces node 3's request time
  EXPECT_EQ(m.next_deadline(), at_ms(70));
  out.clear();
  (void)tick(m, at_ms(300), out);  // late: node 3 (due 70) and node 2 (due 200), once each
  EXPECT_EQ(texts(out), (std::vector<std::string>{"703#R1", "702#R1"}));
  EXPECT_EQ(m.next_deadline(), at_ms(350));
  m.stop(3_node);
  EXPECT_EQ(m.next_deadline(), at_ms(400));
  m.stop(2_node);
  EXPECT_EQ(m.next_deadline(), std::nullopt);
}

}  // namespace
}  // namespace nmt
