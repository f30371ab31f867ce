// Simulated bus: frame lengths per ISO 11898-1 (field sizes: SOF 1, identifier 11 (+ SRR, IDE,
// 18 for 29-bit ids), RTR 1, IDE/r1/r0, DLC 4, data 8n, CRC 15, CRC delimiter 1, ACK 2, EOF 7,
// intermission 3; stuffing from SOF to the end of the CRC sequence), arbitration, scheduling and
// fault injection. Bit counts were worked out by hand from those field sizes; where a CRC is
// involved, the CRC and stuff-bit count were cross-checked with an independent script (CRC-15
// by polynomial long division over the bit string, stuffing by scanning for runs of five).
#include "nmt/sim/sim_bus.hpp"

#include "cfg/hex.hpp"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace nmt {
namespace {

using namespace std::chrono_literals;

CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

std::vector<std::uint8_t> bits(std::string_view text) {
  std::vector<std::uint8_t> out;
  for (char c : text) out.push_back(c == '1' ? 1 : 0);
  return out;
}

// Records what it receives: candump text and the time in microseconds.
struct Recorder : SimNode {
  std::vector<std::pair<std::string, std::int64_t>> received;
  void on_frame(const CanFrame& f, TimePoint now) override {
    received.emplace_back(to_candump(f), now.time_since_epoch().count());
  }
  void on_timer(TimePoint) override {}
  using SimNode::send;
};

// --- frame length ----------------------------------------------------------------------------

TEST(SimBusTiming, StandardFrameWithEightBytesIs108BitsPlusIntermissionBeforeStuffing) {
  // 1 + 11 + 1 (RTR) + 1 (IDE) + 1 (r0) + 4 + 64 + 15 = 98 stuffable bits; + 1 + 2 + 7 = 108;
  // + 3 intermission = 111 (the "111 bits" usually quoted for an 8-byte frame).
  const auto b = frame_bits(frame("123#1122334455667788"));
  EXPECT_EQ(b.stuffed_region, 98u);
  EXPECT_EQ(b.stuffed_region + b.trailer, 108u);
  EXPECT_EQ(b.stuffed_region + b.trailer + b.intermission, 111u);
}

TEST(SimBusTiming, ExtendedFrameWithEightBytesIs128BitsPlusIntermissionBeforeStuffing) {
  // 1 + 11 + 1 (SRR) + 1 (IDE) + 18 + 1 (RTR) + 2 (r1, r0) + 4 + 64 + 15 = 118; + 10 = 128.
  const auto b = frame_bits(frame("1ABCDEF0#0102030405060708"));
  EXPECT_EQ(b.stuffed_region, 118u);
  EXPECT_EQ(b.stuffed_region + b.trailer, 128u);
}

TEST(SimBusTiming, AllZeroFrameGetsAStuffBitEveryFiveBits) {
  // 000# is 34 dominant bits (CRC of all-zero bits is 0): a stuff bit after bits 5, 10, ... 30.
  const auto b = frame_bits(frame("000#"));
  EXPECT_EQ(b.stuffed_region, 34u);
  EXPECT_EQ(b.stuff_bits, 6u);
  EXPECT_EQ(b.until_eof(), 50u);
  EXPECT_EQ(b.total(), 53u);
}

TEST(SimBusTiming, StuffBitsCountedOnTheRealBitsOfKnownFrames) {
  // 7FF#: 0 11111111111 000 0000 + CRC 0x272F (100111001011111): stuff after ones 5 and 10 and
  // after the fifth of the seven zeros of RTR/IDE/r0/DLC = 3.
  EXPECT_EQ(frame_bits(frame("7FF#")).stuff_bits, 3u);
  EXPECT_EQ(frame_bits(frame("7FF#")).total(), 50u);
  // 123#1122334455667788: CRC 0x4237, one stuff bit: 112 bits with intermission.
  EXPECT_EQ(frame_bits(frame("123#1122334455667788")).stuff_bits, 1u);
  EXPECT_EQ(frame_bits(frame("123#1122334455667788")).total(), 112u);
  // The SDO request 605#2B171000E8030000: CRC 0x5A33, 8 stuff bits, 119 bits.
  EXPECT_EQ(frame_bits(frame("605#2B171000E8030000")).stuff_bits, 8u);
  EXPECT_EQ(frame_bits(frame("605#2B171000E8030000")).total(), 119u);
  // 000#0000000000000000: CRC 0x145B, 16 stuff bits.
  EXPECT_EQ(frame_bits(frame("000#0000000000000000")).stuff_bits, 16u);
  // Extended 1ABCDEF0#0102030405060708: CRC 0x136D, 11 stuff bits, 142 bits.
  EXPECT_EQ(frame_bits(frame("1ABCDEF0#0102030405060708")).stuff_bits, 11u);
  EXPECT_EQ(frame_bits(frame("1ABCDEF0#0102030405060708")).total(), 142u);
}

TEST(SimBusTiming, RemoteFrameHasNoDataFieldWhateverItsDlc) {
  // 705#R: 34 stuffable bits (RTR recessive), CRC 0x71AC, 2 stuff bits.
  EXPECT_EQ(frame_bits(frame("705#R")).stuffed_region, 34u);
  EXPECT_EQ(frame_bits(frame("705#R")).stuff_bits, 2u);
  // A DLC of 8 in a remote frame changes the DLC bits, not the length of the data field.
  EXPECT_EQ(frame_bits(frame("705#R8")).stuffed_region, 34u);
}

TEST(SimBusTiming, StuffBitStartsTheNextRun) {
  EXPECT_EQ(count_stuff_bits(bits("0000")), 0u);
  EXPECT_EQ(count_stuff_bits(bits("00000")), 1u);
  EXPECT_EQ(count_stuff_bits(bits("0101010101")), 0u);
  EXPECT_EQ(count_stuff_bits(bits("1111111111")), 2u);
  // 00000[1]1111[0]0000[1]: the stuff bit plus four equal bits make the next run of five.
  EXPECT_EQ(count_stuff_bits(bits("0000011110000")), 3u);
}

TEST(SimBusTiming, Crc15OfKnownBits) {
  EXPECT_EQ(can_crc15(bits("")), 0u);
  EXPECT_EQ(can_crc15(bits("0000000000")), 0u);
  // A single 1 bit leaves the generator polynomial without its x^15 term: 0x4599.
  EXPECT_EQ(can_crc15(bits("1")), 0x4599u);
}

// The bus computes lengths a byte at a time; the bit-at-a-time functions above define them.
TEST(SimBusTiming, FrameBitsAgreeWithBitByBitComputationForManyFrames) {
  std::mt19937 rng(7);
  for (int n = 0; n < 5000; ++n) {
    CanFrame f;
    f.extended = (rng() & 1) != 0;
    f.rtr = (rng() % 8) == 0;
    f.id = static_cast<std::uint32_t>(rng()) & (f.extended ? 0x1FFFFFFFu : 0x7FFu);
    f.dlc = static_cast<std::uint8_t>(rng() % 9);
    // Runs of equal bytes make long runs of equal bits.
    for (auto& byte : f.data) byte = (rng() & 1) != 0 ? 0x00 : static_cast<std::uint8_t>(rng());
    std::vector<std::uint8_t> b;
    auto put = [&](std::uint32_t v, int width) {
      for (int i = width - 1; i >= 0; --i) b.push_back(static_cast<std::uint8_t>(v >> i & 1));
    };
    put(0, 1);  // SOF
    if (f.extended) {
      put(f.id >> 18, 11);
      put(0b11, 2);  // SRR, IDE
      put(f.id & 0x3FFFF, 18);
      put(f.rtr, 1);
      put(0, 2);  // r1, r0
    } else {
      put(f.id, 11);
      put(f.rtr, 1);
      put(0, 2);  // IDE, r0
    }
    put(f.dlc, 4);
    for (int i = 0; i < (f.rtr ? 0 : f.dlc); ++i) put(f.data[i], 8);
    put(can_crc15(b), 15);
    const auto bits_of_f = frame_bits(f);
    ASSERT_EQ(bits_of_f.stuffed_region, b.size()) << to_candump(f);
    ASSERT_EQ(bits_of_f.stuff_bits, count_stuff_bits(b)) << to_candump(f);
  }
}

TEST(SimBus, DeliversAtEndOfFrameAndFreesBusAfterIntermission) {
  SimBus bus(1'000'000);
  Recorder a, b;
  bus.attach(a);
  bus.attach(b);
  a.send(frame("000#"));
  EXPECT_TRUE(bus.run_until_idle());
  // 50 bits to the end of EOF at 1 us per bit.
  ASSERT_EQ(b.received.size(), 1u);
  EXPECT_EQ(b.received[0], (std::pair<std::string, std::int64_t>{"000#", 50}));
  EXPECT_TRUE(a.received.empty());  // the sender does not receive its own frame
  EXPECT_EQ(bus.statistics().busy_ns, 53'000);
}

TEST(SimBus, BitTimeFollowsTheBitRate) {
  SimBus bus(125'000);  // 8 us per bit
  Recorder a, b;
  bus.attach(a);
  bus.attach(b);
  a.send(frame("000#"));
  bus.run_until_idle();
  ASSERT_EQ(b.received.size(), 1u);
  EXPECT_EQ(b.received[0].second, 400);
}

TEST(SimBus, LowestIdentifierWinsWhenThreeNodesSendAtOnce) {
  SimBus bus(1'000'000);
  Recorder n1, n2, n3, listener;
  for (auto* n : {&n1, &n2, &n3, &listener}) bus.attach(*n);
  n1.send(frame("300#"));
  n2.send(frame("100#"));
  n3.send(frame("200#"));
  bus.run_until_idle();
  // Each of 100#, 200#, 300# is 48 bits to EOF, 51 with intermission (4 stuff bits each).
  const std::vector<std::pair<std::string, std::int64_t>> expected{
      {"100#", 48}, {"200#", 51 + 48}, {"300#", 102 + 48}};
  EXPECT_EQ(listener.received, expected);
}

TEST(SimBus, StandardFrameBeatsExtendedFrameWithTheSameBaseId) {
  SimBus bus;
  Recorder n1, n2, n3, listener;
  for (auto* n : {&n1, &n2, &n3, &listener}) bus.attach(*n);
  // 04000000 has base id 0x100. SRR and IDE are recessive, so the standard data frame and even
  // the standard remote frame (RTR recessive, then IDE dominant) win against it.
  n1.send(frame("04000000#"));
  n2.send(frame("100#R"));
  n3.send(frame("100#"));
  bus.run_until_idle();
  ASSERT_EQ(listener.received.size(), 3u);
  EXPECT_EQ(listener.received[0].first, "100#");
  EXPECT_EQ(listener.received[1].first, "100#R");
  EXPECT_EQ(listener.received[2].first, "04000000#");
  EXPECT_LT(arbitration_key(frame("100#")), arbitration_key(frame("100#R")));
  EXPECT_LT(arbitration_key(frame("100#R")), arbitration_key(frame("04000000#")));
  EXPECT_LT(arbitration_key(frame("04000000#")), arbitration_key(frame("101#")));
}

TEST(SimBus, FrameSentWhileBusIsBusyWaitsForIntermission) {
  SimBus bus;
  Recorder a, b, listener;
  for (auto* n : {&a, &b, &listener}) bus.attach(*n);
  a.send(frame("000#"));  // 0..53 us on the bus
  bus.schedule_at(TimePoint{Duration{10}}, [&](TimePoint) { b.send(frame("080#")); });
  bus.run_until_idle();
  ASSERT_EQ(listener.received.size(), 2u);
  EXPECT_EQ(listener.received[1], (std::pair<std::string, std::int64_t>{"080#", 53 + 48}));
}

TEST(SimBus, EachNodeSendsItsFramesInOrder) {
  SimBus bus;
  Recorder a, b, listener;
  for (auto* n : {&a, &b, &listener}) bus.attach(*n);
  a.send(frame("300#"));
  a.send(frame("100#"));  // queued behind 300#: it cannot compete before 300# is sent
  b.send(frame("200#"));
  bus.run_until_idle();
  ASSERT_EQ(listener.received.size(), 3u);
  EXPECT_EQ(listener.received[0].first, "200#");
  EXPECT_EQ(listener.received[1].first, "300#");
  EXPECT_EQ(listener.received[2].first, "100#");
}

TEST(SimBus, ObserversSeeEveryFrameWithItsTime) {
  SimBus bus;
  Recorder a, b;
  bus.attach(a);
  bus.attach(b);
  std::vector<std::pair<std::string, std::int64_t>> seen;
  auto h = bus.add_observer([&](const CanFrame& f, TimePoint t) {
    seen.emplace_back(to_candump(f), t.time_since_epoch().count());
  });
  a.send(frame("000#"));
  b.send(frame("080#"));
  bus.run_until_idle();
  EXPECT_EQ(seen.size(), 2u);
  bus.remove_observer(h);
  a.send(frame("000#"));
  bus.run_until_idle();
  EXPECT_EQ(seen.size(), 2u);
}

TEST(SimBus, TimersFireAtTheirDeadlineAndMayBeReplacedOrCancelled) {
  SimBus bus;
  std::vector<std::int64_t> fired;
  FunctionNode n(
      {}, [&](FunctionNode&, TimePoint t) { fired.push_back(t.time_since_epoch().count()); });
  bus.attach(n);
  n.set_timer(TimePoint{Duration{500}});
  n.set_timer(TimePoint{Duration{300}});  // replaces 500
  bus.run_until(TimePoint{Duration{1000}});
  EXPECT_EQ(fired, (std::vector<std::int64_t>{300}));
  n.set_timer(TimePoint{Duration{2000}});
  n.set_timer(std::nullopt);
  EXPECT_TRUE(bus.idle());
  EXPECT_TRUE(bus.run_until_idle());
  EXPECT_EQ(bus.now(), TimePoint{Duration{1000}});  // a cancelled timer does not move time
  n.set_timer(TimePoint{Duration{5}});              // in the past: fires now
  bus.run_until_idle();
  EXPECT_EQ(fired, (std::vector<std::int64_t>{300, 1000}));
}

TEST(SimBus, RunUntilStopsAtPredicateOrLimit) {
  SimBus bus;
  int ticks = 0;
  FunctionNode n({}, [&](FunctionNode& self, TimePoint t) {
    ++ticks;
    self.set_timer(t + 100us);
  });
  bus.attach(n);
  n.set_timer(TimePoint{Duration{100}});
  EXPECT_TRUE(bus.run_until([&] { return ticks == 5; }));
  EXPECT_EQ(bus.now(), TimePoint{Duration{500}});
  EXPECT_FALSE(bus.run_until([] { return false; }, TimePoint{Duration{1000}}));
  EXPECT_EQ(ticks, 10);
  EXPECT_FALSE(bus.run_until_idle(TimePoint{Duration{2000}}));  // a periodic timer never goes idle
  bus.run_for(10ms);
  EXPECT_EQ(bus.now(), TimePoint{Duration{2000 + 10000}});
}

TEST(SimBus, BusLoadIsBusyTimeOverElapsedTime) {
  SimBus bus(1'000'000);
  Recorder rx;
  FunctionNode tx({}, [](FunctionNode& self, TimePoint t) {
    self.send(CanFrame{});  // 000#: 53 us
    self.set_timer(t + 100us);
  });
  bus.attach(tx);
  bus.attach(rx);
  tx.set_timer(TimePoint{});
  bus.run_until(TimePoint{Duration{100'000 - 1}});
  const auto s = bus.statistics();
  EXPECT_EQ(s.frames, 1000u);
  EXPECT_EQ(s.bits, 53'000u);
  EXPECT_NEAR(s.load(), 0.53, 0.001);
  bus.reset_statistics();
  EXPECT_EQ(bus.statistics().frames, 0u);
}

TEST(SimBusFaults, LossRateIsDeterministicForASeed) {
  auto run = [](std::uint64_t seed) {
    SimBus bus;
    Recorder a, b;
    bus.attach(a);
    bus.attach(b);
    bus.set_loss_rate(0.3, seed);
    for (int i = 0; i < 200; ++i) a.send(CanFrame::make(static_cast<std::uint32_t>(i), {}));
    bus.run_until_idle();
    EXPECT_EQ(bus.statistics().frames, 200u);
    EXPECT_EQ(bus.statistics().frames_dropped, 200u - b.received.size());
    return b.received;
  };
  const auto first = run(42);
  EXPECT_EQ(first, run(42));
  EXPECT_NE(first, run(43));
  EXPECT_GT(first.size(), 100u);  // about 140 of 200 expected
  EXPECT_LT(first.size(), 180u);
}

TEST(SimBusFaults, LossRateOneDropsEverythingZeroNothing) {
  SimBus bus;
  Recorder a, b;
  bus.attach(a);
  bus.attach(b);
  bus.set_loss_rate(1.0);
  a.send(frame("000#"));
  bus.run_until_idle();
  EXPECT_TRUE(b.received.empty());
  bus.set_loss_rate(0.0);
  a.send(frame("000#"));
  bus.run_until_idle();
  EXPECT_EQ(b.received.size(), 1u);
}

TEST(SimBusFaults, FilterDropsOrDelaysChosenFrames) {
  SimBus bus;
  Recorder a, b;
  bus.attach(a);
  bus.attach(b);
  bus.set_filter([](const CanFrame& f, TimePoint) {
    if (f.id == 0x100) return FrameFate::drop();
    if (f.id == 0x200) return FrameFate::delayed(1000us);
    return FrameFate::deliver();
  });
  a.send(frame("200#"));  // 48 us to EOF, delivered 1000 us later
  a.send(frame("100#"));
  a.send(frame("300#"));  // starts at 102, delivered at 150
  bus.run_until_idle();
  const std::vector<std::pair<std::string, std::int64_t>> expected{{"300#", 150}, {"200#", 1048}};
  EXPECT_EQ(b.received, expected);
  EXPECT_EQ(bus.statistics().frames_dropped, 1u);
}

TEST(SimBus, NodesMayDetachFromInsideCallbacks) {
  SimBus bus;
  Recorder a;
  auto b = std::make_unique<FunctionNode>();
  FunctionNode c([&](FunctionNode&, const CanFrame&, TimePoint) { bus.detach(*b); });
  bus.attach(a);
  bus.attach(c);
  bus.attach(*b);
  b->send(frame("000#"));  // c detaches b (the sender) while the frame is delivered
  b->set_timer(TimePoint{Duration{10'000}});
  bus.run_until_idle();
  EXPECT_EQ(b->bus(), nullptr);
  EXPECT_EQ(a.received.size(), 1u);
  EXPECT_EQ(bus.now().time_since_epoch().count(), 53);  // b's timer went with it
  b.reset();
}

TEST(SimBus, DestroyedNodeDetachesItself) {
  SimBus bus;
  Recorder a;
  bus.attach(a);
  {
    Recorder gone;
    bus.attach(gone);
    gone.send(frame("123#"));
  }
  bus.run_until_idle();
  EXPECT_TRUE(a.received.empty());  // its queued frame was discarded
}

// --- SimEngineNode: the simulated-bus driver of any nmt::Engine ------------------------------

// A toy engine: answers 100#xx with 101#xx and reports xx; a timer set through arm() sends
// 7FF#01 and reports -1 when due.
struct EchoEngine {
  using Event = int;
  using Output = Outbox<int>;
  std::optional<TimePoint> deadline;
  int timers = 0;

  bool on_frame(const CanFrame& f, TimePoint /*now*/, Output& out) {
    if (f.id != 0x100 || f.dlc == 0) return false;
    out.send(*from_candump("101#" + cfg::hex_digits(f.data[0], 2)));
    out.report(f.data[0]);
    return true;
  }
  void on_timer(TimePoint now, Output& out) {
    ++timers;
    if (!deadline || now < *deadline) return;
    deadline.reset();
    out.send(*from_candump("7FF#01"));
    out.report(-1);
  }
  std::optional<TimePoint> next_deadline() const { return deadline; }
  // An API call in the engine shape: sends at once and sets a deadline.
  int arm(TimePoint at, TimePoint /*now*/, Output& out) {
    deadline = at;
    out.send(*from_candump("102#"));
    return 7;
  }
  // An API call that sends 103# and reports `value`.
  int note(int value, TimePoint /*now*/, Output& out) {
    out.send(*from_candump("103#"));
    out.report(value);
    return value;
  }
};
static_assert(Engine<EchoEngine>);

TEST(SimEngineNode, AnswersFramesAndHandsEventsToTheHandler) {
  SimBus bus(1'000'000);
  SimEngineNode<EchoEngine> node;
  FunctionNode peer;
  std::vector<std::pair<TimePoint, std::string>> seen;
  std::vector<std::pair<int, TimePoint>> events;
  bus.attach(node);
  bus.attach(peer);
  bus.add_observer([&](const CanFrame& f, TimePoint t) { seen.emplace_back(t, to_candump(f)); });
  node.set_event_handler([&](const int& e, TimePoint t) { events.emplace_back(e, t); });
  peer.send(*from_candump("100#2A"));
  ASSERT_TRUE(bus.run_until_idle(TimePoint{Duration{1'000'000}}));
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].second, "100#2A");
  EXPECT_EQ(seen[1].second, "101#2A");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].first, 0x2A);
  EXPECT_EQ(events[0].second, seen[0].first);  // the time of the call: 100#2A's end of frame
  EXPECT_EQ(node.engine().timers, 0);          // nothing was due: no timer call
}

TEST(SimEngineNode, ApplySendsAtOnceAndTheTimerFollowsTheNewDeadline) {
  SimBus bus(1'000'000);
  SimEngineNode<EchoEngine> node;
  FunctionNode peer;
  std::vector<std::pair<TimePoint, std::string>> seen;
  std::vector<int> events;
  bus.attach(node);
  bus.attach(peer);
  bus.add_observer([&](const CanFrame& f, TimePoint t) { seen.emplace_back(t, to_candump(f)); });
  node.set_event_handler([&](const int& e, TimePoint) { events.push_back(e); });
  const int r = node.apply([](EchoEngine& e, TimePoint now, EchoEngine::Output& out) {
    return e.arm(now + std::chrono::milliseconds(5), now, out);
  });
  EXPECT_EQ(r, 7);
  ASSERT_TRUE(bus.run_until_idle(TimePoint{Duration{1'000'000}}));
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0].second, "102#");
  EXPECT_LT(seen[0].first,
            TimePoint{Duration{100}});  // at once: one frame time, no timer before it
  EXPECT_EQ(seen[1].second, "7FF#01");
  EXPECT_GE(seen[1].first, TimePoint{Duration{5000}});
  EXPECT_EQ(node.engine().timers, 1);  // exactly at the deadline
  EXPECT_EQ(events, std::vector<int>{-1});
}

TEST(SimEngineNode, TheEventHandlerMayApply) {
  SimBus bus(1'000'000);
  SimEngineNode<EchoEngine> node;
  FunctionNode peer;
  std::vector<std::string> seen;
  bus.attach(node);
  bus.attach(peer);
  bus.add_observer([&](const CanFrame& f, TimePoint) { seen.push_back(to_candump(f)); });
  node.set_event_handler([&](const int& event, TimePoint) {
    if (event == -1) return;  // the timer's own event
    node.apply([](EchoEngine& e, TimePoint now, EchoEngine::Output& out) {
      return e.arm(now + std::chrono::milliseconds(1), now, out);
    });
  });
  peer.send(*from_candump("100#01"));
  ASSERT_TRUE(bus.run_until_idle(TimePoint{Duration{1'000'000}}));
  // The answer, then what the handler started, then its timer's frame.
  EXPECT_EQ(seen, (std::vector<std::string>{"100#01", "101#01", "102#", "7FF#01"}));
}

TEST(SimEngineNode, AnExceptionOfTheEventHandlerInApplyReachesTheCaller) {
  SimBus bus(1'000'000);
  SimEngineNode<EchoEngine> node;
  std::vector<std::string> seen;
  std::vector<int> events;
  bus.attach(node);
  bus.add_observer([&](const CanFrame& f, TimePoint) { seen.push_back(to_candump(f)); });
  node.set_event_handler([&](const int& event, TimePoint) {
    events.push_back(event);
    if (event == 5) throw std::runtime_error("the handler refuses 5");
  });
  auto note = [](int value) {
    return [value](EchoEngine& e, TimePoint now, EchoEngine::Output& out) {
      return e.note(value, now, out);
    };
  };
  EXPECT_THROW(node.apply(note(5)), std::runtime_error);
  // The node goes on: the next call's event reaches the handler.
  EXPECT_EQ(node.apply(note(6)), 6);
  EXPECT_EQ(events, (std::vector<int>{5, 6}));
  ASSERT_TRUE(bus.run_until_idle(TimePoint{Duration{1'000'000}}));
  // Both calls' frames were sent (before their events were handed out).
  EXPECT_EQ(seen, (std::vector<std::string>{"103#", "103#"}));
}

TEST(SimEngineNode, AnExceptionOfTheCallItselfReachesTheCallerAfterItsFramesAreSent) {
  SimBus bus(1'000'000);
  SimEngineNode<EchoEngine> node;
  std::vector<std::string> seen;
  bus.attach(node);
  bus.add_observer([&](const CanFrame& f, TimePoint) { seen.push_back(to_candump(f)); });
  EXPECT_THROW(node.apply([](EchoEngine& e, TimePoint now, EchoEngine::Output& out) {
    e.note(1, now, out);
    throw std::runtime_error("after the engine call");
  }),
               std::runtime_error);
  ASSERT_TRUE(bus.run_until_idle(TimePoint{Duration{1'000'000}}));
  EXPECT_EQ(seen, std::vector<std::string>{"103#"});
}

}  // namespace
}  // namespace nmt
