// BusEventLoop's transmit path and the controller's error frames (bus_event_loop.hpp,
// "Transmit": the path survives a real controller): a full transmit queue is
// back-pressure (in order, nothing lost, the loop goes on receiving), other send failures are
// reported and retried, only a vanished interface ends the run; error frames are counted and
// reported, and bus-off stops sending without charging the engines' timers. A scripted bus on a
// fake clock answers each send attempt as a driver would (SocketCanBus::try_send: ENOBUFS is
// QueueFull, ENODEV is InterfaceGone); the error frames are linux/can/error.h's, as candump
// shows them.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "fake_clock_bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/protocol/error_control.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Status = SendResult::Status;

TimePoint at(Duration d) {
  return TimePoint{} + d;
}

// Sends what the test asks through apply(); records the frames it is given.
struct Talker {
  using Event = NoEvent;
  using Output = Outbox<NoEvent>;
  bool on_frame(const CanFrame& f, TimePoint now, Output& /*out*/) {
    heard.emplace_back(now, to_candump(f));
    return true;
  }
  void on_timer(TimePoint /*now*/, Output& /*out*/) {}
  std::optional<TimePoint> next_deadline() const { return std::nullopt; }
  std::vector<std::pair<TimePoint, std::string>> heard;
};

void say(EngineRef<Talker>& ref, const std::vector<std::string>& frames) {
  ref.apply([&](Talker&, TimePoint, Talker::Output& out) {
    for (const auto& f : frames) out.send(*from_candump(f));
  });
}

struct Rig {
  Rig() : loop(bus, {}, [this] { return bus.now; }), ref(talker) {
    loop.add(ref);
    loop.set_bus_event_handler([this](const BusEvent& e, TimePoint) { events.push_back(e); });
  }
  std::vector<BusEvent::Kind> kinds() const {
    std::vector<BusEvent::Kind> out;
    for (const auto& e : events) out.push_back(e.kind);
    return out;
  }
  FakeClockBus bus;
  BusEventLoop loop;
  Talker talker;
  EngineRef<Talker> ref;
  std::vector<BusEvent> events;
};

TEST(BusEventLoopTransmit, AFullQueueIsBackPressureFramesGoOutInOrderWhileFramesAreReceived) {
  Rig rig;
  for (int i = 0; i < 6; ++i) rig.bus.answers.push_back(Status::QueueFull);
  rig.bus.arrive(at(1ms), "181#01");  // arrives while the first frame waits for room
  say(rig.ref, {"601#40", "602#40", "603#40"});
  EXPECT_TRUE(rig.bus.sent.empty());
  ASSERT_TRUE(rig.loop.run_until(at(50ms)).ok());
  EXPECT_EQ(rig.bus.sent, (std::vector<std::string>{"601#40", "602#40", "603#40"}));
  EXPECT_EQ(rig.talker.heard,
            (std::vector<std::pair<TimePoint, std::string>>{{at(1ms), "181#01"}}));
  EXPECT_EQ(rig.loop.counters().queue_full, 6U);
  EXPECT_EQ(rig.loop.counters().max_queued, 3U);
  EXPECT_EQ(rig.loop.counters().queued, 0U);
  EXPECT_TRUE(rig.events.empty());  // back-pressure is no failure
  // Retried with a backoff (50 us doubling), not in a busy loop.
  ASSERT_EQ(rig.bus.attempts.size(), 9U);
  for (std::size_t i = 1; i < 7; ++i) {
    EXPECT_EQ(rig.bus.attempts[i].second, "601#40");
    EXPECT_GT(rig.bus.attempts[i].first, rig.bus.attempts[i - 1].first);
  }
}

TEST(BusEventLoopTransmit, RunUntilSentEndsOnceTheQueuedFramesWentOut) {
  Rig rig;
  rig.bus.answers = {Status::QueueFull, Status::QueueFull, Status::QueueFull};
  say(rig.ref, {"605#A100000000000000"});  // a client's last frame
  ASSERT_TRUE(rig.loop.run_until_sent(1s).ok());
  EXPECT_EQ(rig.bus.sent, std::vector<std::string>{"605#A100000000000000"});
  EXPECT_LT(rig.bus.now, at(1ms));  // 50 + 100 + 200 us of backoff, not the limit
}

TEST(BusEventLoopTransmit, ASendFailureIsReportedAndRetried) {
  Rig rig;
  rig.bus.answers = {Status::Failed, Status::Failed};
  say(rig.ref, {"701#05", "702#05"});
  ASSERT_TRUE(rig.loop.run_until(at(100ms)).ok());
  EXPECT_EQ(rig.bus.sent, (std::vector<std::string>{"701#05", "702#05"}));
  EXPECT_EQ(rig.kinds(),
            (std::vector<BusEvent::Kind>{BusEvent::Kind::SendFailed, BusEvent::Kind::SendFailed}));
  EXPECT_EQ(to_candump(rig.events[0].frame), "701#05");
  EXPECT_EQ(rig.events[0].text, "scripted 701#05");
  EXPECT_EQ(rig.loop.counters().send_failures, 2U);
  // 10 ms, then 20 ms later.
  ASSERT_GE(rig.bus.attempts.size(), 3U);
  EXPECT_EQ(rig.bus.attempts[1].first, at(10ms));
  EXPECT_EQ(rig.bus.attempts[2].first, at(30ms));
}

TEST(BusEventLoopTransmit, AFrameTheDriverRefusesIsReportedAndDroppedAndTheRestGoOut) {
  Rig rig;
  rig.bus.answers = {Status::Refused};
  say(rig.ref, {"7FF#", "701#05"});
  ASSERT_TRUE(rig.loop.run_until(at(1ms)).ok());
  EXPECT_EQ(rig.bus.sent, std::vector<std::string>{"701#05"});
  EXPECT_EQ(rig.kinds(), std::vector<BusEvent::Kind>{BusEvent::Kind::FrameRefused});
  EXPECT_EQ(rig.loop.counters().refused, 1U);
}

TEST(BusEventLoopTransmit, AVanishedInterfaceEndsTheRunSayingSo) {
  Rig rig;
  rig.bus.answers = {Status::QueueFull, Status::InterfaceGone};
  say(rig.ref, {"701#05"});
  auto status = rig.loop.run_until(at(1s));
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("scripted:: the interface is gone"), std::string::npos)
      << status.error().message;
  EXPECT_NE(status.error().message.find("1 frame(s) not sent"), std::string::npos)
      << status.error().message;
  EXPECT_LT(rig.bus.now, at(1s));
}

// linux/can/error.h: CAN_ERR_CRTL (4) with CAN_ERR_CRTL_TX_PASSIVE (20h) in data[1],
// CAN_ERR_LOSTARB (2), CAN_ERR_CRTL with CAN_ERR_CRTL_RX_OVERFLOW (1), CAN_ERR_ACK (20h).
TEST(BusEventLoopTransmit, ErrorFramesAreCountedAndReportedNotDeliveredToEngines) {
  Rig rig;
  rig.bus.arrive(at(1ms), "20000004#0020000000000000");
  rig.bus.arrive(at(2ms), "20000002#0000000000000000");
  rig.bus.arrive(at(3ms), "20000004#0001000000000000");
  rig.bus.arrive(at(4ms), "20000020#0000000000000000");
  ASSERT_TRUE(rig.loop.run_until(at(10ms)).ok());
  EXPECT_TRUE(rig.talker.heard.empty());
  using K = BusEvent::Kind;
  EXPECT_EQ(rig.kinds(), (std::vector<K>{K::ErrorPassive, K::LostArbitration, K::ControllerOverflow,
                                         K::BusError}));
  const BusCounters c = rig.loop.counters();
  EXPECT_EQ(c.error_frames, 4U);
  EXPECT_EQ(c.error_passive, 1U);
  EXPECT_EQ(c.lost_arbitration, 1U);
  EXPECT_EQ(c.controller_overflows, 1U);
  EXPECT_EQ(c.bus_errors, 1U);
  EXPECT_EQ(rig.loop.frames_received(), 4U);
}

// Bus-off (CAN_ERR_BUSOFF, 40h) at 1 s, restarted (CAN_ERR_RESTARTED, 100h) at 3 s. A node that
// heartbeats every 100 ms is not heard in between (the controller takes no part in the bus);
// its consumer (500 ms) is not charged with those 2 s, and what the master wanted to send waits.
TEST(BusEventLoopTransmit, BusOffStopsSendingUntilRestartedAndDoesNotChargeTheTimers) {
  Rig rig;
  HeartbeatConsumer consumer;
  std::vector<HeartbeatEvent> heartbeat_events;
  EngineRef consumer_ref(
      consumer, [&](const HeartbeatEvent& e, TimePoint) { heartbeat_events.push_back(e); });
  rig.loop.add(consumer_ref);
  consumer_ref.apply([](HeartbeatConsumer& c, TimePoint now, auto&) {
    c.monitor(HeartbeatConsumerEntry{5, 500}, now);
  });
  for (auto t = at(100ms); t < at(1s); t += 100ms) rig.bus.arrive(t, "705#05");
  rig.bus.arrive(at(1s), "20000040#0000000000000000");
  rig.bus.arrive(at(3s), "20000100#0000000000000000");
  for (auto t = at(3100ms); t < at(5s); t += 100ms) rig.bus.arrive(t, "705#05");

  ASSERT_TRUE(rig.loop.run_until(at(2s)).ok());
  EXPECT_TRUE(rig.loop.bus_off());
  EXPECT_EQ(rig.loop.now(), at(1s));  // the engines' time stands still
  say(rig.ref, {"000#8105"});
  EXPECT_TRUE(rig.bus.attempts.empty());  // not even tried during bus-off
  ASSERT_TRUE(rig.loop.run_until(at(5s)).ok());
  EXPECT_FALSE(rig.loop.bus_off());
  EXPECT_EQ(rig.bus.sent, std::vector<std::string>{"000#8105"});
  ASSERT_EQ(rig.bus.attempts.size(), 1U);
  EXPECT_EQ(rig.bus.attempts[0].first, at(3s));
  EXPECT_TRUE(heartbeat_events.empty()) << "charged with the bus-off time";
  using K = BusEvent::Kind;
  EXPECT_EQ(rig.kinds(), (std::vector<K>{K::BusOff, K::Restarted}));
  EXPECT_EQ(rig.loop.counters().bus_off, 1U);
  EXPECT_EQ(rig.loop.counters().bus_off_time, Duration{2s});
  EXPECT_EQ(rig.loop.now(), at(3s));  // 5 s less 2 s of bus-off
  // A real loss afterwards is still seen: the last heartbeat at 4.9 s (engine time 2.9 s).
  ASSERT_TRUE(rig.loop.run_until(at(6s)).ok());
  ASSERT_EQ(heartbeat_events.size(), 1U);
  EXPECT_EQ(heartbeat_events[0].kind, HeartbeatEventKind::Timeout);
  EXPECT_EQ(heartbeat_events[0].at, at(3400ms));
}

}  // namespace
}  // namespace nmt
