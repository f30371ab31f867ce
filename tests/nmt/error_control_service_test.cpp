// The NMT master's error control service alone (master/error_control_service.hpp): heartbeat
// consumer and node guarding (CiA 301 §7.2.8.3.2) for two watchers, the master (CiA 302-2 §4.1
// start error control, §6.5 request node guarding) and the SDO manager (DSP 302 §7.2.1 SRDs,
// §7.2.2 slaves with Req EC). Frames as candump strings: a heartbeat "705#05" (node 5,
// operational), a guarding request "705#R1" and its reply "705#85"/"705#05" (toggle bit 7,
// spec/002). Times are exact: the consumer's timer starts with monitoring (§4.1), a guarded
// node is lost after life time factor unanswered requests.
#include "master/error_control_service.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace nmt {
namespace {

using std::chrono::milliseconds;
using Kind = ErrorControlEvent::Kind;

TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}
cfg::NodeId id(std::uint8_t node) {
  return cfg::NodeId::from(node).value();
}
CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

constexpr Watchers kMaster{.master = true};
constexpr Watchers kManager{.manager = true};
constexpr Watchers kBoth{.master = true, .manager = true};

ErrorControlEvent lost(std::uint8_t node, ErrorControlProtocol protocol, Watchers watchers,
                       std::int64_t ms) {
  return {id(node), Kind::Lost, protocol, watchers, at_ms(ms)};
}

// The service as its owner drives it: what one call put out, frames as candump strings.
struct Rig {
  ErrorControlService service;
  std::vector<std::string> frames;
  std::vector<ErrorControlEvent> events;

  void take(const ErrorControlService::Output& out) {
    for (const auto& f : out.frames) frames.push_back(to_candump(f));
    events.insert(events.end(), out.events.begin(), out.events.end());
  }
  void tick(std::int64_t ms) {
    ErrorControlService::Output out;
    service.on_timer(at_ms(ms), out);
    take(out);
  }
  void feed(std::string_view candump, std::int64_t ms) {
    ErrorControlService::Output out;
    (void)service.on_frame(frame(candump), at_ms(ms), out);
    take(out);
  }
  void end_of_call(std::int64_t ms) {
    ErrorControlService::Output out;
    service.send_due_requests(at_ms(ms), out);
    take(out);
  }
};

// A loss is reported once, to every watcher of the node: CiA 302-2 §4.1 (the consumer's timer
// starts with monitoring, 300 ms) for the master's error handler and DSP 302 §7.2.2 for the
// manager's 1F11h.
TEST(ErrorControlService, HeartbeatLossIsReportedOnceToBothWatchers) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  EXPECT_TRUE(rig.service.join(id(5), Watcher::Manager));
  EXPECT_EQ(rig.service.watchers(id(5)), kBoth);
  EXPECT_EQ(rig.service.next_deadline(), at_ms(300));
  rig.tick(299);
  EXPECT_TRUE(rig.events.empty());
  rig.tick(300);
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Heartbeat, kBoth, 300)}));
  rig.tick(900);
  EXPECT_EQ(rig.events.size(), 1U) << "reported again";
  EXPECT_TRUE(rig.frames.empty()) << "a heartbeat consumer sends nothing";
}

// The master stops its own error control (a boot error, CiA 302-2 §3.4; a boot-up, §4.3): the
// manager's watch goes on, and the loss that follows reaches the manager alone.
TEST(ErrorControlService, MasterStopLeavesTheManagersWatchRunning) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  EXPECT_TRUE(rig.service.join(id(5), Watcher::Manager));
  rig.feed("705#05", 100);  // the next heartbeat is due within 300 ms: by 400 ms
  rig.service.stop(id(5), Watcher::Master);
  EXPECT_TRUE(rig.service.monitors(id(5)));
  EXPECT_EQ(rig.service.watchers(id(5)), kManager);
  EXPECT_EQ(rig.service.next_deadline(), at_ms(400));
  rig.tick(400);
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Heartbeat, kManager, 400)}));
}

// The same the other way round: the manager lets the node go (it released the SRD's
// connections), the master's error control of its slave stays as it was.
TEST(ErrorControlService, ManagerStopLeavesTheMastersWatchRunning) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  EXPECT_TRUE(rig.service.join(id(5), Watcher::Manager));
  rig.service.stop(id(5), Watcher::Manager);
  EXPECT_EQ(rig.service.watchers(id(5)), kMaster);
  rig.tick(300);
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Heartbeat, kMaster, 300)}));
}

// The last watcher's stop ends the watch: no deadline, no loss.
TEST(ErrorControlService, StopOfTheLastWatcherEndsTheWatch) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  rig.service.stop(id(5), Watcher::Manager);  // not a watcher of node 5: nothing changes
  EXPECT_TRUE(rig.service.monitors(id(5)));
  rig.service.stop(id(5), Watcher::Master);
  EXPECT_FALSE(rig.service.watches(id(5)));
  EXPECT_EQ(rig.service.next_deadline(), std::nullopt);
  rig.tick(1000);
  EXPECT_TRUE(rig.events.empty());
}

// A watcher that joins a running watch restarts nothing: the loss comes when it would have
// come (the heartbeat at 100 ms + 300 ms), not a consumer time after the join.
TEST(ErrorControlService, JoinKeepsTheRunningTimer) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  rig.feed("705#05", 100);
  EXPECT_TRUE(rig.service.join(id(5), Watcher::Manager));
  EXPECT_EQ(rig.service.next_deadline(), at_ms(400));
  // Joining a node nobody watches starts nothing: the watcher starts it with its own values.
  EXPECT_FALSE(rig.service.join(id(6), Watcher::Manager));
  EXPECT_FALSE(rig.service.watches(id(6)));
  rig.tick(400);
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Heartbeat, kBoth, 400)}));
}

// The master's start error control of a slave the manager already watches (§4.1 after a new
// boot) restarts the consumer's timer from `now`, as a first start does.
TEST(ErrorControlService, MastersStartRestartsTheTimerTheManagerWatches) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Manager, milliseconds(300), at_ms(0));
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(200));
  EXPECT_EQ(rig.service.watchers(id(5)), kBoth);
  EXPECT_EQ(rig.service.next_deadline(), at_ms(500));
  rig.tick(300);
  EXPECT_TRUE(rig.events.empty());
  rig.tick(500);
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Heartbeat, kBoth, 500)}));
}

// CiA 301: a heartbeat after the heartbeat event resolves it, for the same watchers.
TEST(ErrorControlService, HeartbeatAfterTheLossResolvesIt) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Manager, milliseconds(300), at_ms(0));
  rig.tick(300);
  rig.feed("705#7F", 350);
  ASSERT_EQ(rig.events.size(), 2U);
  EXPECT_EQ(rig.events[1],
            (ErrorControlEvent{id(5), Kind::Resolved, ErrorControlProtocol::Heartbeat, kManager,
                               at_ms(350)}));
}

// Node guarding (CiA 301 §7.2.8.3.2.1): the first request is due when guarding starts and leaves
// at the end of the owner's call (send_due_requests), the next ones every guard time (100 ms);
// life time factor 3 requests without a reply are the node guarding event, for both watchers.
// The master's stop leaves the manager's guarding running, requests and all.
TEST(ErrorControlService, GuardingGoesOnForTheManagerAfterTheMastersStop) {
  Rig rig;
  ASSERT_TRUE(rig.service.guard(id(5), Watcher::Master, 100, 3, at_ms(0)));
  EXPECT_TRUE(rig.service.join(id(5), Watcher::Manager));
  EXPECT_TRUE(rig.service.guards(id(5)));
  EXPECT_EQ(rig.service.next_deadline(), at_ms(0));
  rig.end_of_call(0);
  EXPECT_EQ(rig.frames, std::vector<std::string>{"705#R1"});
  rig.feed("705#05", 5);  // toggle bit 0: answered
  rig.tick(100);
  rig.service.stop(id(5), Watcher::Master);
  EXPECT_TRUE(rig.service.guards(id(5)));
  rig.tick(200);  // 100 ms's request unanswered: 1
  rig.tick(300);  // 2
  EXPECT_TRUE(rig.events.empty());
  rig.tick(400);  // 3: life time over
  EXPECT_EQ(rig.frames,
            (std::vector<std::string>{"705#R1", "705#R1", "705#R1", "705#R1", "705#R1"}));
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Guarding, kManager, 400)}));
  rig.service.stop(id(5), Watcher::Manager);
  EXPECT_EQ(rig.service.next_deadline(), std::nullopt);
}

// CiA 302-2 §6.3: a guard time or retry factor of 0 disables guarding: refused, no watcher.
TEST(ErrorControlService, GuardingWithZeroGuardTimeWatchesNothing) {
  Rig rig;
  EXPECT_FALSE(rig.service.guard(id(5), Watcher::Master, 0, 3, at_ms(0)));
  EXPECT_FALSE(rig.service.guard(id(5), Watcher::Master, 100, 0, at_ms(0)));
  EXPECT_FALSE(rig.service.watches(id(5)));
  EXPECT_EQ(rig.service.next_deadline(), std::nullopt);
}

// §6.5 Table 31 "Stop node guarding" ends guarding, not the heartbeat consumer of the node.
TEST(ErrorControlService, StopGuardingLeavesTheHeartbeatConsumer) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  ASSERT_TRUE(rig.service.guard(id(5), Watcher::Master, 100, 3, at_ms(0)));
  rig.service.stop_guarding(id(5), Watcher::Master);
  EXPECT_FALSE(rig.service.guards(id(5)));
  EXPECT_TRUE(rig.service.monitors(id(5)));
  EXPECT_EQ(rig.service.next_deadline(), at_ms(300));
}

// The consumer sends nothing and the service ignores frames of nodes it does not watch.
TEST(ErrorControlService, FramesOfUnwatchedNodesChangeNothing) {
  Rig rig;
  rig.service.monitor(id(5), Watcher::Master, milliseconds(300), at_ms(0));
  rig.feed("706#05", 100);
  rig.feed("705#R1", 100);  // a request (another master's), no heartbeat
  rig.tick(300);
  EXPECT_EQ(rig.events, (std::vector{lost(5, ErrorControlProtocol::Heartbeat, kMaster, 300)}));
}

}  // namespace
}  // namespace nmt
