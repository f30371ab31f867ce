// Emergency producer (CiA 301 §7.2.7). The life-guarding frame is the example of
// spec/002_*.txt: "81 8 30 81 11 00 00 00 00 00: node 1 sends an EMCY indicating the lifeguard
// error".
#include "nmt/emcy.hpp"

#include <gtest/gtest.h>

namespace nmt {
namespace {

using std::chrono::milliseconds;
TimePoint at_ms(std::int64_t ms) {
  return milliseconds(ms);
}

const Emergency kLifeGuard{emcy_code::kLifeGuardOrHeartbeat,
                           error_register::kGeneric | error_register::kCommunication,
                           {}};

TEST(Emcy, LifeGuardErrorFrameMatchesSpecExample) {
  EXPECT_EQ(to_candump(make_emcy(kEmcyCobIdBase + 1, kLifeGuard)), "081#3081110000000000");
}

TEST(Emcy, ParsesWhatItEncodes) {
  Emergency e{0x1234, 0x81, {1, 2, 3, 4, 5}};
  auto frame = make_emcy(0x85, e);
  EXPECT_EQ(to_candump(frame), "085#3412810102030405");
  EXPECT_EQ(parse_emcy(frame), e);
  EXPECT_FALSE(parse_emcy(*from_candump("085#3412")).has_value());
}

TEST(EmcyProducer, SendsAtOnceWithoutInhibitTime) {
  EmcyProducer p(0x81);
  auto f = p.raise(kLifeGuard, at_ms(0), true);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->id, 0x81u);
  EXPECT_TRUE(p.raise(kLifeGuard, at_ms(0), true).has_value());
}

TEST(EmcyProducer, InhibitTimeDelaysTheNextMessage) {
  EmcyProducer p(0x81, 100);  // 100 × 100 µs = 10 ms
  ASSERT_TRUE(p.raise(kLifeGuard, at_ms(0), true).has_value());
  EXPECT_FALSE(p.raise({emcy_code::kGeneric, 1, {}}, at_ms(3), true).has_value());
  EXPECT_EQ(p.deadline(), at_ms(10));
  EXPECT_TRUE(p.on_timer(at_ms(9), true).empty());
  auto out = p.on_timer(at_ms(10), true);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(to_candump(out[0]), "081#0010010000000000");
  EXPECT_FALSE(p.deadline().has_value());
}

TEST(EmcyProducer, NothingIsSentInStoppedOrWithInvalidCobId) {
  EmcyProducer p(0x81);
  EXPECT_FALSE(p.raise(kLifeGuard, at_ms(0), /*allowed=*/false).has_value());
  p.set_cob_id(0x80000081u);  // CiA 301 §7.5.2.14: bit 31 set, EMCY does not exist
  EXPECT_FALSE(p.raise(kLifeGuard, at_ms(0), true).has_value());
  EXPECT_EQ(p.dropped(), 2u);
}

TEST(EmcyProducer, QueueIsBounded) {
  EmcyProducer p(0x81, 10'000);
  (void)p.raise(kLifeGuard, at_ms(0), true);
  for (std::size_t i = 0; i < EmcyProducer::kQueueCapacity + 3; ++i) {
    (void)p.raise(kLifeGuard, at_ms(0), true);
  }
  EXPECT_EQ(p.dropped(), 3u);
}

TEST(EmcyProducer, ExtendedCobIdUses29BitIdentifier) {
  EmcyProducer p(0x20000181u);
  auto f = p.raise(kLifeGuard, at_ms(0), true);
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->extended);
  EXPECT_EQ(f->id, 0x181u);
}

}  // namespace
}  // namespace nmt
