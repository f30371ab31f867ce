// Emergency producer (CiA 301 §7.2.7). The life-guarding frame is the example of
// spec/002_*.txt: "81 8 30 81 11 00 00 00 00 00: node 1 sends an EMCY indicating the lifeguard
// error".
#include "nmt/protocol/emcy.hpp"

#include <gtest/gtest.h>

namespace nmt {
namespace {

using std::chrono::milliseconds;
TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}

cfg::CobId cob(std::uint32_t word) {
  return cfg::CobId::from_word(word);
}

// Raises one emergency that starts (sent or queued); the frames it sent at once (the producer
// reports no events).
std::vector<CanFrame> raise(EmcyProducer& p, const Emergency& e, TimePoint now) {
  EmcyProducer::Output out;
  const auto started = p.raise(e, now, out);
  EXPECT_TRUE(started.ok()) << started.error().message;
  return out.frames;
}
// Raises one emergency the producer refuses (engine.hpp rule 5): why, and nothing in `out`.
std::string refusal(EmcyProducer& p, const Emergency& e, TimePoint now) {
  EmcyProducer::Output out;
  const auto started = p.raise(e, now, out);
  EXPECT_TRUE(out.frames.empty());
  return started.ok() ? std::string("started") : started.error().message;
}
std::vector<CanFrame> timer(EmcyProducer& p, TimePoint now) {
  EmcyProducer::Output out;
  p.on_timer(now, out);
  return out.frames;
}

static_assert(Engine<EmcyProducer>);

const Emergency kLifeGuard{emcy_code::kLifeGuardOrHeartbeat,
                           error_register::kGeneric | error_register::kCommunication,
                           {}};

TEST(Emcy, LifeGuardErrorFrameMatchesSpecExample) {
  EXPECT_EQ(to_candump(make_emcy(cob(kEmcyCobIdBase + 1), kLifeGuard)), "081#3081110000000000");
}

TEST(Emcy, ParsesWhatItEncodes) {
  Emergency e{0x1234, 0x81, {1, 2, 3, 4, 5}};
  auto frame = make_emcy(cob(0x85), e);
  EXPECT_EQ(to_candump(frame), "085#3412810102030405");
  EXPECT_EQ(parse_emcy(frame), e);
  EXPECT_FALSE(parse_emcy(*from_candump("085#3412")).has_value());
}

TEST(EmcyProducer, SendsAtOnceWithoutInhibitTime) {
  EmcyProducer p(cob(0x81));
  auto f = raise(p, kLifeGuard, at_ms(0));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].id, 0x81u);
  EXPECT_EQ(raise(p, kLifeGuard, at_ms(0)).size(), 1u);
}

TEST(EmcyProducer, InhibitTimeDelaysTheNextMessage) {
  EmcyProducer p(cob(0x81), 100);  // 100 × 100 µs = 10 ms
  ASSERT_EQ(raise(p, kLifeGuard, at_ms(0)).size(), 1u);
  EXPECT_TRUE(raise(p, {emcy_code::kGeneric, 1, {}}, at_ms(3)).empty());
  EXPECT_EQ(p.next_deadline(), at_ms(10));
  EXPECT_TRUE(timer(p, at_ms(9)).empty());
  auto out = timer(p, at_ms(10));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(to_candump(out[0]), "081#0010010000000000");
  EXPECT_FALSE(p.next_deadline().has_value());
}

TEST(EmcyProducer, NothingIsSentInStoppedOrWithInvalidCobId) {
  EmcyProducer p(cob(0x81));
  p.set_allowed(false);  // stopped
  EXPECT_EQ(refusal(p, kLifeGuard, at_ms(0)),
            "EMCY 8130h not sent: the NMT state does not allow EMCY");
  p.set_allowed(true);
  p.set_cob_id(cob(0x80000081u));  // CiA 301 §7.5.2.14: bit 31 set, EMCY does not exist
  EXPECT_EQ(refusal(p, kLifeGuard, at_ms(0)),
            "EMCY 8130h not sent: the EMCY COB-ID (1014h) is invalid");
  EXPECT_EQ(p.dropped(), 2u);
}

TEST(EmcyProducer, QueueIsBounded) {
  EmcyProducer p(cob(0x81), 10'000);
  ASSERT_EQ(raise(p, kLifeGuard, at_ms(0)).size(), 1u);  // sent; the inhibit time runs
  for (std::size_t i = 0; i < EmcyProducer::kQueueCapacity; ++i) {
    EXPECT_TRUE(raise(p, kLifeGuard, at_ms(0)).empty());  // queued: started
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(refusal(p, kLifeGuard, at_ms(0)),
              "EMCY 8130h not sent: 16 messages already wait for the inhibit time (1015h)");
  }
  EXPECT_EQ(p.dropped(), 3u);
}

TEST(EmcyProducer, ExtendedCobIdUses29BitIdentifier) {
  EmcyProducer p(cob(0x20000181u));
  auto f = raise(p, kLifeGuard, at_ms(0));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_TRUE(f[0].extended);
  EXPECT_EQ(f[0].id, 0x181u);
}

TEST(EmcyProducer, QueuedMessagesAreDroppedWhenTheStateNoLongerAllowsEmcy) {
  // CiA 301 §7.3.2.2 Table 51: no EMCY in stopped, also none that waited for the inhibit time.
  EmcyProducer p(cob(0x81), 100);
  ASSERT_EQ(raise(p, kLifeGuard, at_ms(0)).size(), 1u);
  EXPECT_TRUE(raise(p, kLifeGuard, at_ms(1)).empty());  // queued
  p.set_allowed(false);
  EXPECT_TRUE(timer(p, at_ms(10)).empty());
  EXPECT_EQ(p.dropped(), 1u);
  EXPECT_FALSE(p.next_deadline().has_value());
}

}  // namespace
}  // namespace nmt
