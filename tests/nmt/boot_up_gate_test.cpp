// The NMT master's start-up boot-up gate alone (master/boot_up_gate.hpp): closed by the reset
// communication of all nodes (CiA 302-2 §3.1 d) until the wait for the boot-ups ends; paced, a
// quiet time of 20 ms without a boot-up ends it too. Exact times.
#include "master/boot_up_gate.hpp"

#include <gtest/gtest.h>

namespace nmt {
namespace {

using std::chrono::milliseconds;

TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}

TEST(BootUpGate, IsOpenUntilTheStartupResetClosesIt) {
  BootUpGate gate;
  EXPECT_FALSE(gate.closed());
  // Open: a boot after a reset waits its own boot_up_wait from now.
  EXPECT_EQ(gate.wait_until(at_ms(100), milliseconds(500)), at_ms(600));
  gate.close(at_ms(1000), false);
  EXPECT_TRUE(gate.closed());
  // Closed: every boot after the start-up's reset waits until the same time.
  EXPECT_EQ(gate.wait_until(at_ms(100), milliseconds(500)), at_ms(1000));
  EXPECT_EQ(gate.next_deadline(), std::nullopt) << "the boots keep the wait's deadline";
  gate.open();
  EXPECT_FALSE(gate.closed());
  EXPECT_EQ(gate.wait_until(at_ms(1200), milliseconds(500)), at_ms(1700));
}

// Unpaced, a boot-up at the gate starts no quiet time: the gate waits for all or for the wait.
TEST(BootUpGate, UnpacedBootUpsStartNoQuietTime) {
  BootUpGate gate;
  gate.close(at_ms(1000), false);
  gate.booted_up(at_ms(10));
  EXPECT_EQ(gate.next_deadline(), std::nullopt);
  EXPECT_FALSE(gate.quiet_over(at_ms(999)));
}

// Paced, each boot-up restarts the 20 ms quiet time; it is over at its end, not before.
TEST(BootUpGate, PacedGateIsQuiet20msAfterTheLastBootUp) {
  BootUpGate gate;
  gate.close(at_ms(1000), true);
  gate.booted_up(at_ms(10));
  EXPECT_EQ(gate.next_deadline(), at_ms(30));
  gate.booted_up(at_ms(25));
  EXPECT_EQ(gate.next_deadline(), at_ms(45));
  EXPECT_FALSE(gate.quiet_over(at_ms(44)));
  EXPECT_TRUE(gate.quiet_over(at_ms(45)));
  gate.open();
  EXPECT_FALSE(gate.quiet_over(at_ms(50)));
  EXPECT_EQ(gate.next_deadline(), std::nullopt);
  // An open gate starts no quiet time (a boot-up after it opened is no boot-up at the gate).
  gate.booted_up(at_ms(60));
  EXPECT_EQ(gate.next_deadline(), std::nullopt);
}

// A new start-up closes the gate afresh: the quiet time of the last one is gone.
TEST(BootUpGate, ClosingAgainForgetsTheQuietTime) {
  BootUpGate gate;
  gate.close(at_ms(1000), true);
  gate.booted_up(at_ms(10));
  gate.close(at_ms(3000), true);
  EXPECT_EQ(gate.next_deadline(), std::nullopt);
  EXPECT_EQ(gate.wait_until(at_ms(2000), milliseconds(500)), at_ms(3000));
}

}  // namespace
}  // namespace nmt
