// EngineRef, the event-loop driver of any nmt::Engine (nmt/engine.hpp): frames out at once,
// events to the handler, apply() from outside and from inside the handler. A fake bus with a
// fake clock makes the order exact.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "cfg/hex.hpp"
#include "fake_clock_bus.hpp"
#include "nmt/io/bus_event_loop.hpp"

namespace nmt {
namespace {

// Sends 200#xx through its API; answers 200#xx with 201#xx and reports xx.
struct Echo {
  using Event = int;
  using Output = Outbox<int>;
  bool on_frame(const CanFrame& f, TimePoint /*now*/, Output& out) {
    if (f.id != 0x200 || f.dlc == 0) return false;
    out.send(*from_candump("201#" + cfg::hex_digits(f.data[0], 2)));
    out.report(f.data[0]);
    return true;
  }
  void on_timer(TimePoint /*now*/, Output& /*out*/) {}
  std::optional<TimePoint> next_deadline() const { return std::nullopt; }
  int say(std::uint8_t b, TimePoint /*now*/, Output& out) {
    out.send(*from_candump("200#" + cfg::hex_digits(b, 2)));
    return b;
  }
  // An API call that sends 202#xx and reports xx.
  int note(std::uint8_t b, TimePoint /*now*/, Output& out) {
    out.send(*from_candump("202#" + cfg::hex_digits(b, 2)));
    out.report(b);
    return b;
  }
};

TEST(EngineRef, ApplySendsAtOnceAndTheLoopsOtherEnginesHearIt) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Echo a;
  Echo b;
  std::vector<int> heard_by_b;
  EngineRef ref_a(a);
  EngineRef ref_b(b, [&](const int& e, TimePoint) { heard_by_b.push_back(e); });
  loop.add(ref_a);
  loop.add(ref_b);
  const int r =
      ref_a.apply([](Echo& e, TimePoint now, Echo::Output& out) { return e.say(5, now, out); });
  EXPECT_EQ(r, 5);
  // No run() in between: the frame is on the bus, b answered it through the loop's echo.
  EXPECT_EQ(bus.sent, (std::vector<std::string>{"200#05", "201#05"}));
  EXPECT_EQ(heard_by_b, std::vector<int>{5});
}

TEST(EngineRef, TheEventHandlerMayApply) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Echo a;
  Echo b;
  EngineRef ref_a(a);
  EngineRef<Echo> ref_b(b);
  ref_b.set_event_handler([&](const int& e, TimePoint) {
    if (e == 1)
      ref_b.apply([](Echo& x, TimePoint now, Echo::Output& out) { return x.say(2, now, out); });
  });
  loop.add(ref_a);
  loop.add(ref_b);
  ref_a.apply([](Echo& e, TimePoint now, Echo::Output& out) { return e.say(1, now, out); });
  // b answers 1, its handler says 2, a answers 2: every frame in the order it was sent.
  EXPECT_EQ(bus.sent, (std::vector<std::string>{"200#01", "201#01", "200#02", "201#02"}));
}

TEST(EngineRef, AnExceptionOfTheEventHandlerInApplyReachesTheCaller) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Echo a;
  std::vector<int> events;
  EngineRef ref(a, [&](const int& e, TimePoint) {
    events.push_back(e);
    if (e == 5) throw std::runtime_error("the handler refuses 5");
  });
  loop.add(ref);
  auto note = [](std::uint8_t b) {
    return [b](Echo& e, TimePoint now, Echo::Output& out) { return e.note(b, now, out); };
  };
  EXPECT_THROW(ref.apply(note(5)), std::runtime_error);
  EXPECT_EQ(ref.apply(note(6)), 6);
  EXPECT_EQ(events, (std::vector<int>{5, 6}));
  // Each call's frame was sent before its event was handed out.
  EXPECT_EQ(bus.sent, (std::vector<std::string>{"202#05", "202#06"}));
}

TEST(EngineRef, AnExceptionOfTheCallItselfReachesTheCallerAfterItsFramesAreSent) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Echo a;
  EngineRef ref(a);
  loop.add(ref);
  EXPECT_THROW(ref.apply([](Echo& e, TimePoint now, Echo::Output& out) {
    e.say(1, now, out);
    throw std::runtime_error("after the engine call");
  }),
               std::runtime_error);
  EXPECT_EQ(bus.sent, std::vector<std::string>{"200#01"});
}

TEST(EngineRef, ApplyBeforeAddIsAProgrammingError) {
  Echo a;
  EngineRef ref(a);
  EXPECT_THROW(
      ref.apply([](Echo& e, TimePoint now, Echo::Output& out) { return e.say(1, now, out); }),
      std::logic_error);
}

TEST(EngineRef, AFrameTheBusFailsToSendInApplyIsSentLaterNotLost) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  Echo a;
  EngineRef ref(a);
  loop.add(ref);
  std::vector<std::string> reported;
  loop.set_bus_event_handler([&](const BusEvent& e, TimePoint) { reported.push_back(e.text); });
  bus.fail_sends = true;
  ref.apply([](Echo& e, TimePoint now, Echo::Output& out) { return e.say(1, now, out); });
  ASSERT_TRUE(loop.run_for(std::chrono::milliseconds(10)).ok());
  EXPECT_TRUE(bus.sent.empty());
  ASSERT_FALSE(reported.empty());
  EXPECT_NE(reported[0].find("transmit queue full"), std::string::npos) << reported[0];
  bus.fail_sends = false;
  ASSERT_TRUE(loop.run_for(std::chrono::milliseconds(100)).ok());
  EXPECT_EQ(bus.sent, std::vector<std::string>{"200#01"});
}

}  // namespace
}  // namespace nmt
