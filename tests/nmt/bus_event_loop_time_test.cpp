// BusEventLoop judges by when frames arrived (bus_event_loop.hpp,
// "Time"): frames already queued are handed to the engines, in
// arrival order and at their arrival time, before the timers due after them; a frame that
// arrived after a deadline does not stop the timer; the time engines are given never goes back
// (engine.hpp rule 1). A scripted bus with a fake clock stands for the socket: frames arrive at
// given times and wait in its queue while the loop is stalled.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "fake_clock_bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/protocol/error_control.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;

// An engine that records what it is given, with a deadline the test sets.
struct Recorder {
  using Event = NoEvent;
  using Output = Outbox<NoEvent>;
  struct Call {
    std::string what;  // "timer" or the frame
    TimePoint now;
    bool operator==(const Call&) const = default;
  };
  bool on_frame(const CanFrame& f, TimePoint now, Output& /*out*/) {
    calls.push_back({to_candump(f), now});
    return true;
  }
  void on_timer(TimePoint now, Output& /*out*/) {
    if (deadline && *deadline <= now) {
      calls.push_back({"timer", now});
      deadline.reset();
    }
  }
  std::optional<TimePoint> next_deadline() const { return deadline; }

  std::optional<TimePoint> deadline;
  std::vector<Call> calls;
};

TimePoint at(Duration d) {
  return TimePoint{} + d;
}

TEST(BusEventLoop, FramesQueuedBeforeADeadlineAreDeliveredBeforeItsTimer) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Recorder recorder;
  recorder.deadline = at(500ms);
  EngineRef ref(recorder);
  loop.add(ref);
  // The frames arrive while the process is stopped (the clock jumps from 0 to 2 s).
  bus.arrive(at(100ms), "701#05");
  bus.arrive(at(499ms), "702#05");
  bus.arrive(at(500ms), "703#05");  // at the deadline: not before it
  bus.arrive(at(1500ms), "704#05");
  bus.now = at(2s);
  ASSERT_TRUE(loop.run_until(at(2s + 1ms)).ok());
  // Each at its arrival time, the timer between the frames that came before and after it.
  EXPECT_EQ(recorder.calls, (std::vector<Recorder::Call>{{"701#05", at(100ms)},
                                                         {"702#05", at(499ms)},
                                                         {"timer", at(500ms)},
                                                         {"703#05", at(500ms)},
                                                         {"704#05", at(1500ms)}}));
}

// CiA 301 §7.2.8.3.2.2: the consumer's heartbeat event fires when no heartbeat was received
// within the consumer heartbeat time. A node that heartbeats every 100 ms against 500 ms did
// send in time, even if the consumer's process was stopped for 2 s.
TEST(BusEventLoop, HeartbeatsThatArrivedDuringAStallOfTheLoopCountAsInTime) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  HeartbeatConsumer consumer;
  std::vector<HeartbeatEvent> events;
  EngineRef<HeartbeatConsumer> ref(consumer);
  loop.add(ref);
  ref.apply([](HeartbeatConsumer& c, TimePoint now, auto&) {
    c.monitor(HeartbeatConsumerEntry{5, 500}, now);
  });
  bus.arrive_every(100ms, at(100ms), at(6s), "705#05");  // the last one at 5.9 s
  std::vector<TimePoint> reported;
  ref.set_event_handler([&](const HeartbeatEvent& e, TimePoint now) {
    events.push_back(e);
    reported.push_back(now);
  });
  ASSERT_TRUE(loop.run_until(at(1s)).ok());
  // Stalled for 2 s inside the loop: the observer sleeps while the frame of 1.1 s is handled.
  bool stalled = false;
  loop.set_observer([&](const CanFrame&, TimePoint t, BusEventLoop::Direction) {
    if (!stalled && t > at(1s)) {
      stalled = true;
      bus.now += 2s;
    }
  });
  ASSERT_TRUE(loop.run_until(at(3200ms)).ok());
  ASSERT_TRUE(stalled);
  EXPECT_EQ(events, std::vector<HeartbeatEvent>{}) << "a live node was reported lost";
  // Stalled for 2 s between two run*() calls.
  bus.now += 2s;
  ASSERT_TRUE(loop.run_until(at(5500ms)).ok());
  EXPECT_EQ(events, std::vector<HeartbeatEvent>{}) << "a live node was reported lost";
  // The node stops after its heartbeat of 5.9 s: the loss is seen one consumer time later.
  ASSERT_TRUE(loop.run_until(at(7s)).ok());
  ASSERT_EQ(events.size(), 1U);
  EXPECT_EQ(events[0].kind, HeartbeatEventKind::Timeout);
  EXPECT_EQ(events[0].at, at(6400ms));
  EXPECT_EQ(reported[0], at(6400ms));
}

TEST(BusEventLoop, AFrameThatArrivedAfterTheDeadlineDoesNotPreventTheTimer) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  HeartbeatConsumer consumer;
  std::vector<std::pair<HeartbeatEvent, TimePoint>> events;
  EngineRef ref(consumer,
                [&](const HeartbeatEvent& e, TimePoint now) { events.emplace_back(e, now); });
  loop.add(ref);
  ref.apply([](HeartbeatConsumer& c, TimePoint now, auto&) {
    c.monitor(HeartbeatConsumerEntry{5, 500}, now);
  });
  bus.arrive(at(100ms), "705#05");
  bus.arrive(at(700ms), "705#05");  // 600 ms after the last one: too late
  bus.now = at(2s);                 // both read after a stall
  ASSERT_TRUE(loop.run_until(at(2s + 1ms)).ok());
  ASSERT_EQ(events.size(), 3U);
  EXPECT_EQ(events[0].first.kind, HeartbeatEventKind::Timeout);
  EXPECT_EQ(events[0].first.at, at(600ms));
  EXPECT_EQ(events[0].second, at(700ms));  // reported as the late frame arrived
  EXPECT_EQ(events[1].first.kind, HeartbeatEventKind::Resolved);
  EXPECT_EQ(events[1].second, at(700ms));
  // And nothing came after it: lost again at 1.2 s, seen once the queue was read (at 2 s).
  EXPECT_EQ(events[2].first.kind, HeartbeatEventKind::Timeout);
  EXPECT_EQ(events[2].first.at, at(1200ms));
  EXPECT_EQ(events[2].second, at(2s));
}

TEST(BusEventLoop, TimeGivenToEnginesNeverGoesBackAndNeverPassesTheClock) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Recorder recorder;
  EngineRef ref(recorder);
  loop.add(ref);
  bus.arrive(at(300ms), "701#");
  // A driver stamp earlier than one already given (a wall-clock step, a driver's own queue).
  bus.arrivals.push_back({at(310ms), "702#", StampClock::Loop, at(200ms)});
  // A stamp after the clock.
  bus.arrivals.push_back({at(320ms), "703#", StampClock::Loop, at(9s)});
  bus.arrive(at(330ms), "704#");
  bus.now = at(400ms);
  recorder.deadline = at(350ms);
  ASSERT_TRUE(loop.run_until(at(401ms)).ok());
  EXPECT_EQ(recorder.calls, (std::vector<Recorder::Call>{{"701#", at(300ms)},
                                                         {"702#", at(300ms)},
                                                         {"timer", at(400ms)},
                                                         {"703#", at(400ms)},
                                                         {"704#", at(400ms)}}));
}

TEST(BusEventLoop, ApplyFromAHandlerRunsAtTheTimeOfTheFrameBeingHandled) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  HeartbeatConsumer consumer;
  std::vector<TimePoint> apply_times;
  EngineRef<HeartbeatConsumer> ref(consumer);
  ref.set_event_handler([&](const HeartbeatEvent&, TimePoint) {
    ref.apply([&](HeartbeatConsumer&, TimePoint now, auto&) { apply_times.push_back(now); });
  });
  loop.add(ref);
  ref.apply([](HeartbeatConsumer& c, TimePoint now, auto&) {
    c.monitor(HeartbeatConsumerEntry{5, 500}, now);
  });
  bus.arrive(at(100ms), "705#05");
  bus.arrive(at(200ms), "705#7F");  // state change: an event
  bus.now = at(300ms);
  ASSERT_TRUE(loop.run_until(at(301ms)).ok());
  EXPECT_EQ(apply_times, std::vector<TimePoint>{at(200ms)});
}

TEST(BusEventLoop, TimersFireUnderAFloodOfFramesAndTheRunEnds) {
  FakeClockBus bus;
  bus.flood = true;
  BusEventLoopOptions options;
  options.max_frames_per_pass = 16;
  BusEventLoop loop(bus, options, [&] { return bus.now; });
  Recorder recorder;
  recorder.deadline = at(50ms);
  EngineRef ref(recorder);
  loop.add(ref);
  ASSERT_TRUE(loop.run_until(at(100ms)).ok());
  const auto timer =
      std::find(recorder.calls.begin(), recorder.calls.end(), Recorder::Call{"timer", at(50ms)});
  ASSERT_NE(timer, recorder.calls.end());
  // Between the frames that arrived before and after it.
  ASSERT_NE(timer, recorder.calls.begin());
  EXPECT_EQ((timer - 1)->now, at(50ms) - 100us);
  ASSERT_NE(timer + 1, recorder.calls.end());
  EXPECT_EQ((timer + 1)->now, at(50ms));
}

TEST(ArrivalOnLoopClock, ARealtimeStampKeepsItsAgeOnTheLoopClock) {
  const TimePoint loop_now = at(1000s);
  const TimePoint wall_now = at(1'700'000'000s);
  const ReceivedFrame two_seconds_old{CanFrame{}, wall_now - 2s, StampClock::Realtime};
  EXPECT_EQ(arrival_on_loop_clock(two_seconds_old, loop_now, wall_now, TimePoint::min()),
            loop_now - 2s);
  // Clamped: not before the last time given, not after the loop's now.
  EXPECT_EQ(arrival_on_loop_clock(two_seconds_old, loop_now, wall_now, loop_now - 1s),
            loop_now - 1s);
  const ReceivedFrame from_the_future{CanFrame{}, wall_now + 5s, StampClock::Realtime};
  EXPECT_EQ(arrival_on_loop_clock(from_the_future, loop_now, wall_now, TimePoint::min()), loop_now);
  // A stamp on the loop's own clock is taken as it is.
  const ReceivedFrame on_loop_clock{CanFrame{}, loop_now - 3s, StampClock::Loop};
  EXPECT_EQ(arrival_on_loop_clock(on_loop_clock, loop_now, wall_now, TimePoint::min()),
            loop_now - 3s);
}

}  // namespace
}  // namespace nmt
