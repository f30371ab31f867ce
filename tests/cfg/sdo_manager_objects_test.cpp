// The SDO manager's object words (DSP 302 §7.2.3, ../shared/spec/001_846495643a25878e.txt):
// expected words are built by hand from the bit tables of §7.2.3 and the example values its text
// gives for 1F10h (xxxx0001h, xxxx0009h, 00000003h).
#include "cfg/sdo_manager_objects.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace cfg::sdo_manager {
namespace {

// §7.2.1: "The COB-ID is 1760d."
static_assert(kDynamicSdoRequestCanId == 0x6E0);

TEST(SdoManagerObjects, SdoRequestBitsAre_Index31to16_SrdNode15to8_Slave7to0_Section7_2_3) {
  // SRD 7Fh asks for a connection to node 05h on its client entry 1281h.
  const SdoRequest r{0x1281, 0x7F, 0x05};
  EXPECT_EQ(r.encode(), 0x12817F05u);
  EXPECT_EQ(SdoRequest::decode(0x12817F05u), r);
  EXPECT_FALSE(r.all_connections());
  EXPECT_FALSE(r.deregister());
}

TEST(SdoManagerObjects, ReleaseWithIndexZeroMeansAllConnectionsToTheSlave_Section7_2_3) {
  const auto r = SdoRequest::decode(0x00007F05u);
  EXPECT_TRUE(r.all_connections());
  EXPECT_EQ(r.slave_node_id, 5);
  EXPECT_FALSE(r.deregister());
}

TEST(SdoManagerObjects, ReleaseWithSlaveZeroDeregisters_Section7_2_1) {
  const auto r = SdoRequest::decode(0x00007F00u);
  EXPECT_TRUE(r.deregister());
  EXPECT_EQ(r.srd_node_id, 0x7F);
}

TEST(SdoManagerObjects, RegistrationRequestIsIndexThen0001h_Section7_2_3) {
  // "it has to set the value of this object to xxxx0001h, whereas xxxx is the value of OD index"
  EXPECT_EQ(DynamicSdoState::registration(0x1280).encode(), 0x12800001u);
  const auto s = DynamicSdoState::decode(0x12800001u);
  EXPECT_TRUE(s.request_indication);
  EXPECT_FALSE(s.request_error_control);
  EXPECT_EQ(s.state, ConnectionState::kFailed);
  EXPECT_EQ(s.client_index, 0x1280);
}

TEST(SdoManagerObjects, RegistrationWithErrorControlOfSlavesIs0009h_Section7_2_3) {
  // "if the SRD requests active error control services for the devices S ... xxxx0009h"
  EXPECT_EQ(DynamicSdoState::registration(0x1281, true).encode(), 0x12810009u);
  const auto s = DynamicSdoState::decode(0x12810009u);
  EXPECT_TRUE(s.request_error_control);
  EXPECT_TRUE(s.request_indication);
}

TEST(SdoManagerObjects, AllDefaultSdosRequestIs00000003h_Section7_2_3) {
  EXPECT_EQ(DynamicSdoState::all_default_sdos_request().encode(), 0x00000003u);
  EXPECT_TRUE(DynamicSdoState::decode(0x00000003u).is_all_default_sdos_request());
  EXPECT_FALSE(DynamicSdoState::decode(0x12800001u).is_all_default_sdos_request());
}

TEST(SdoManagerObjects, ConfirmationsClearRqIndicationAndSetCnxnStateBits2to1_Section7_2_3) {
  // Cnxn state 1 = SRD <-> manager, 2 = all default SDOs, 3 = connection to S.
  EXPECT_EQ(DynamicSdoState::confirmation(0x1280, ConnectionState::kManagerConnected).encode(),
            0x12800002u);
  EXPECT_EQ(DynamicSdoState::confirmation(0, ConnectionState::kAllDefaultSdosOwned).encode(),
            0x00000004u);
  EXPECT_EQ(DynamicSdoState::confirmation(0x1281, ConnectionState::kSlaveConnected).encode(),
            0x12810006u);
  // Req EC stays set when the manager supports error control of slaves.
  EXPECT_EQ(
      DynamicSdoState::confirmation(0x1280, ConnectionState::kManagerConnected, true).encode(),
      0x1280000Au);
}

TEST(SdoManagerObjects, FailureCarriesErrorCodeInBits15to8_Section7_2_3) {
  const auto f = DynamicSdoState::failure(0x1281, DynamicSdoError::kNoFreeServerOnSlave);
  EXPECT_EQ(f.encode(), 0x12810300u);
  const auto d = DynamicSdoState::decode(0x12810400u);
  EXPECT_EQ(d.state, ConnectionState::kFailed);
  EXPECT_EQ(d.error(), DynamicSdoError::kSlaveNotAvailable);
  EXPECT_EQ(describe(d.error()), "slave S not available");
  EXPECT_EQ(describe(DynamicSdoError::kNoChannelToManager),
            "no SDO channel free for connection from SRD to SDO manager");
  EXPECT_EQ(describe(static_cast<DynamicSdoError>(0x05)), "reserved error code");
}

TEST(SdoManagerObjects, DynamicSdoStateRoundTripsEveryFieldIncludingReservedBits) {
  for (const std::uint32_t word :
       {0x00000000u, 0xFFFFFFFFu, 0x12800001u, 0x12FF0209u, 0x000000F0u, 0xABCD5A5Au}) {
    EXPECT_EQ(DynamicSdoState::decode(word).encode(), word) << std::hex << word;
  }
  EXPECT_EQ(DynamicSdoState::decode(0x000000F0u).reserved, 0xF);
  EXPECT_EQ(DynamicSdoState::decode(0x12800001u).reserved, 0);
}

TEST(SdoManagerObjects, SlaveFailedIsReason15to8Node7to0_Section7_2_3) {
  const SlaveFailed f{static_cast<std::uint8_t>(SlaveFailedReason::kErrorControl), 0x05};
  EXPECT_EQ(f.encode(), 0x0005);
  EXPECT_EQ(SlaveFailed::decode(0x0105), (SlaveFailed{1, 5}));
  EXPECT_EQ(SlaveFailed::decode(0xFF7F).encode(), 0xFF7F);
}

TEST(SdoManagerObjects, ManagerCobIdBit31NotValidBit30InUse_Section7_2_3) {
  const auto unconfigured = ManagerCobId{};
  EXPECT_FALSE(unconfigured.valid());
  EXPECT_FALSE(unconfigured.free());

  const auto entry = ManagerCobId::of({0x6E1, false});
  EXPECT_EQ(entry.encode(), 0x000006E1u);
  EXPECT_TRUE(entry.free());
  const auto used = entry.with_in_use(true);
  EXPECT_EQ(used.encode(), 0x400006E1u);
  EXPECT_TRUE(used.in_use());
  EXPECT_FALSE(used.free());
  // The COB-ID a connection writes into 1200h/1280h: without the pool's own bits.
  EXPECT_EQ(used.cob_id(), CobId::standard(0x6E1));
  EXPECT_EQ(used.with_in_use(false), entry);

  // 29-bit entry: bit 29 set and bits 28-11 part of the identifier.
  const auto extended = ManagerCobId::decode(0x60012345u);
  EXPECT_TRUE(extended.in_use());
  EXPECT_EQ(extended.cob_id().can_id(), (CanId{0x00012345, true}));
}

TEST(SdoManagerObjects, SdoConnectionBitsAreClientOffsetClientNodeServerOffsetServerNode) {
  // Client entry 1281h on node 7Fh to server entry 1201h on node 05h.
  const auto c = SdoConnection::of(0x1281, 0x7F, 0x1201, 0x05);
  EXPECT_EQ(c.encode(), 0x017F0105u);
  EXPECT_EQ(SdoConnection::decode(0x017F0105u), c);
  EXPECT_EQ(c.client_index(), 0x1281);
  EXPECT_EQ(c.server_index(), 0x1201);
  EXPECT_FALSE(c.free());
  // "If one of the fields Server ID or Client ID is 0, the connection is not valid".
  EXPECT_TRUE(SdoConnection::decode(0x017F0100u).free());
  EXPECT_TRUE(SdoConnection::decode(0x01000105u).free());
}

TEST(SdoManagerObjects, ConnectionSlotsFill254SubIndicesPerPart_Section7_2_3) {
  EXPECT_EQ(connection_slot(0), (ConnectionSlot{0x1F03, 1}));
  EXPECT_EQ(connection_slot(253), (ConnectionSlot{0x1F03, 254}));
  EXPECT_EQ(connection_slot(254), (ConnectionSlot{0x1F04, 1}));
  EXPECT_EQ(connection_slot(4 * 254 - 1), (ConnectionSlot{0x1F06, 254}));
  EXPECT_TRUE(object::is_sdo_connections(0x1F06));
  EXPECT_FALSE(object::is_sdo_connections(0x1F07));
}

}  // namespace
}  // namespace cfg::sdo_manager
