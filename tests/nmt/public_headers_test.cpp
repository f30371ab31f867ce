// The umbrella headers of libnmt's three rooms (nmt/core.hpp, nmt/io.hpp, nmt/sim.hpp) compile
// together in one file, and each room's engines are where its folder says.
#include <gtest/gtest.h>

#include "nmt/core.hpp"
#include "nmt/io.hpp"
#include "nmt/sim.hpp"

namespace {

// engine.hpp's contract, checked here on engines the umbrellas bring from each folder.
static_assert(nmt::Engine<nmt::NmtMaster>);          // master/
static_assert(nmt::Engine<nmt::SlaveNode>);          // slave/
static_assert(nmt::Engine<nmt::SdoClientMux>);       // sdo/
static_assert(nmt::Engine<nmt::LssProcedure>);       // lss/
static_assert(nmt::Engine<nmt::HeartbeatConsumer>);  // protocol/

TEST(PublicHeaders, UmbrellasOfTheThreeRoomsCompileTogether) {
  // A frame through the candump text form of protocol/frame.hpp, as an embedder's first line.
  const auto frame = nmt::from_candump("705#00");
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->id, 0x705U);
}

}  // namespace
