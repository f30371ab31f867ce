// The NMT master's emergency consumer alone (master/emcy_consumer.hpp, CiA 301 §7.2.7). Frames
// as candump strings: "083#3081110000000000" is node 3's EMCY on 80h + 3 with error code 8130h
// (little-endian, §7.2.7.3.1), error register 11h (generic and communication, §7.5.2.2) and
// five manufacturer bytes 00; "083#0000000000000000" is its error reset (code 0000h).
#include "master/emcy_consumer.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace nmt {
namespace {

using std::chrono::milliseconds;
using Kind = EmcyConsumerEvent::Kind;

TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}
cfg::NodeId id(std::uint8_t node) {
  return cfg::NodeId::from(node).value();
}

struct Rig {
  EmcyConsumer consumer;
  std::vector<EmcyConsumerEvent> events;

  explicit Rig(EmcyConsumer::Settings settings = {}) : consumer(settings) {}
  bool feed(std::string_view candump, std::int64_t ms) {
    EmcyConsumer::Output out;
    const auto frame = from_candump(candump);
    EXPECT_TRUE(frame.has_value()) << candump;
    const bool mine = consumer.on_frame(*frame, at_ms(ms), out);
    EXPECT_TRUE(out.frames.empty());  // a consumer never sends
    events.insert(events.end(), out.events.begin(), out.events.end());
    return mine;
  }
  void tick(std::int64_t ms) {
    EmcyConsumer::Output out;
    consumer.on_timer(at_ms(ms), out);
    events.insert(events.end(), out.events.begin(), out.events.end());
  }
};

TEST(EmcyConsumer, DecodesCodeRegisterAndManufacturerBytes) {
  Rig rig;
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  EXPECT_TRUE(rig.feed("083#30811101020304FF", 120));
  ASSERT_EQ(rig.events.size(), 1u);
  const auto& e = rig.events[0];
  EXPECT_EQ(e.kind, Kind::Emergency);
  EXPECT_EQ(e.node, id(3));
  EXPECT_EQ(e.at, at_ms(120));
  EXPECT_EQ(e.emcy.error_code, 0x8130);
  EXPECT_EQ(e.emcy.error_register, 0x11);
  EXPECT_EQ(e.emcy.manufacturer, (std::array<std::uint8_t, 5>{0x01, 0x02, 0x03, 0x04, 0xFF}));
  EXPECT_EQ(rig.consumer.received(id(3)), 1u);
}

TEST(EmcyConsumer, ListensOnlyOnTheCobIdOfEachNode) {
  Rig rig;
  // 1014h of node 5's DCF moved its EMCY to 0A5h; node 3 keeps 80h + 3.
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  rig.consumer.consume(id(5), cfg::CobId::standard(0x0A5));
  EXPECT_FALSE(rig.feed("085#0010010000000000", 10));  // 80h + 5 is not node 5's EMCY now
  EXPECT_FALSE(rig.feed("080#", 11));                  // SYNC
  EXPECT_FALSE(rig.feed("084#0010010000000000", 12));  // node 4 is not consumed
  EXPECT_TRUE(rig.feed("0A5#0010010000000000", 13));
  ASSERT_EQ(rig.events.size(), 1u);
  EXPECT_EQ(rig.events[0].node, id(5));
  EXPECT_EQ(rig.events[0].emcy.error_code, 0x1000);
}

TEST(EmcyConsumer, InvalidCobIdConsumesNothing) {
  Rig rig;
  // CiA 301 §7.5.2.30: bit 31 of the 1028h entry set: not valid.
  rig.consumer.consume(id(3), cfg::CobId::from_word(0x80000083));
  EXPECT_FALSE(rig.consumer.cob_id(id(3)).has_value());
  EXPECT_FALSE(rig.feed("083#3081110000000000", 1));
  EXPECT_TRUE(rig.events.empty());
}

TEST(EmcyConsumer, FrameShorterThanEightBytesIsNoEmergency) {
  Rig rig;
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  EXPECT_TRUE(rig.feed("083#308111", 1));  // on its identifier, but §7.2.7.3.1 says 8 bytes
  EXPECT_TRUE(rig.events.empty());
  EXPECT_EQ(rig.consumer.received(id(3)), 0u);
}

TEST(EmcyConsumer, ErrorResetEndsTheError) {
  Rig rig;
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  rig.feed("083#0000000000000000", 5);  // no error before: a reset that ends nothing
  rig.feed("083#3081110000000000", 10);
  rig.feed("083#0000000000000000", 20);
  ASSERT_EQ(rig.events.size(), 3u);
  EXPECT_FALSE(rig.events[0].ends_error);
  EXPECT_EQ(rig.events[2].emcy.error_code, emcy_code::kErrorReset);
  EXPECT_TRUE(rig.events[2].ends_error);
}

TEST(EmcyConsumer, FloodIsBoundedPerNodeAndCodeThenSummarised) {
  Rig rig({.max_per_window = 3, .window = milliseconds(1000)});
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  // 10 EMCYs 8130h, one every 10 ms, and one 2310h in between: 3 of 8130h reported, 7 counted.
  for (int i = 0; i < 10; ++i) rig.feed("083#3081110000000000", 100 + 10 * i);
  rig.feed("083#1023030000000000", 150);
  ASSERT_EQ(rig.events.size(), 4u);
  EXPECT_EQ(rig.events[3].emcy.error_code, 0x2310);
  EXPECT_EQ(rig.consumer.received(id(3)), 11u);
  // The summary comes when the window of the first (at 100 ms) ends: at 1100 ms.
  EXPECT_EQ(rig.consumer.next_deadline(), at_ms(1100));
  rig.tick(1099);
  EXPECT_EQ(rig.events.size(), 4u);
  rig.tick(1100);
  ASSERT_EQ(rig.events.size(), 5u);
  const auto& flood = rig.events[4];
  EXPECT_EQ(flood.kind, Kind::Flood);
  EXPECT_EQ(flood.node, id(3));
  EXPECT_EQ(flood.emcy.error_code, 0x8130);
  EXPECT_EQ(flood.suppressed, 7u);
  EXPECT_EQ(flood.window_began, at_ms(100));
  EXPECT_EQ(rig.consumer.next_deadline(), std::nullopt);
  // A new window: reported again.
  rig.feed("083#3081110000000000", 1200);
  ASSERT_EQ(rig.events.size(), 6u);
  EXPECT_EQ(rig.events[5].kind, Kind::Emergency);
}

TEST(EmcyConsumer, WindowWithoutSuppressedMessagesEndsSilently) {
  Rig rig({.max_per_window = 3, .window = milliseconds(1000)});
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  rig.feed("083#3081110000000000", 0);
  EXPECT_EQ(rig.consumer.next_deadline(), std::nullopt);
  rig.tick(5000);
  EXPECT_EQ(rig.events.size(), 1u);
}

TEST(EmcyConsumer, ErrorResetSaysTheFloodFirst) {
  Rig rig({.max_per_window = 1, .window = milliseconds(1000)});
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  rig.feed("083#3081110000000000", 0);
  rig.feed("083#3081110000000000", 10);
  rig.feed("083#3081110000000000", 20);
  rig.feed("083#0000000000000000", 30);
  ASSERT_EQ(rig.events.size(), 3u);
  EXPECT_EQ(rig.events[1].kind, Kind::Flood);
  EXPECT_EQ(rig.events[1].suppressed, 2u);
  EXPECT_EQ(rig.events[1].at, at_ms(30));
  EXPECT_EQ(rig.events[2].emcy.error_code, 0x0000);
  EXPECT_TRUE(rig.events[2].ends_error);
  EXPECT_EQ(rig.consumer.next_deadline(), std::nullopt);
}

TEST(EmcyConsumer, EndingTheWindowsSaysEveryOpenFloodAtOnce) {
  // The driver stops 300 ms into a window: its count is said then, not lost with the window.
  Rig rig({.max_per_window = 2, .window = milliseconds(1000)});
  rig.consumer.consume(id(3), default_emcy_cob_id(id(3)));
  rig.consumer.consume(id(4), default_emcy_cob_id(id(4)));
  for (int i = 0; i < 6; ++i) rig.feed("083#3081110000000000", 10 * i);
  rig.feed("084#1023030000000000", 20);  // node 4: one, reported, nothing suppressed
  ASSERT_EQ(rig.events.size(), 3u);
  EmcyConsumer::Output out;
  rig.consumer.end_windows(at_ms(300), out);
  ASSERT_EQ(out.events.size(), 1u);
  EXPECT_EQ(out.events[0].kind, Kind::Flood);
  EXPECT_EQ(out.events[0].node, id(3));
  EXPECT_EQ(out.events[0].suppressed, 4u);
  EXPECT_EQ(out.events[0].at, at_ms(300));
  EXPECT_EQ(out.events[0].window_began, at_ms(0));
  EXPECT_EQ(rig.consumer.next_deadline(), std::nullopt);
  // Said once: the window is gone.
  rig.tick(1000);
  EXPECT_EQ(rig.events.size(), 3u);
}

}  // namespace
}  // namespace nmt
