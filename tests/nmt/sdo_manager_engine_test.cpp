// The SDO manager engine alone (SdoManagerProcess, DSP 302 §7), driven through a fake of its
// port: no master, no bus. The fake answers each SDO access the engine starts from the
// dictionaries of the devices on its "network" (a node without one is silent: the access times
// out), records every access in order, and says what the engine asked of error control. The
// engine's own frames (its server channels) are checked byte for byte. Values are the bit
// layouts of DSP 302 §7.2.3 (1F10h, 1F00h/1F01h, 1F02h, 1F03h) and the choices the top of
// nmt/master/nmt_master.hpp documents (the pool 680h.. of a dictionary without 1F02h, the scan from
// 127 down), the same as the whole-master cases these came from (sdo_manager_test.cpp).
//
// Devices: SRDs from tests/data/sdo_manager/srd.eds (1F10h, 1F11h, client entries 1280h-1283h
// not valid, 1017h = 100 ms); slave 2 from slave_channels.eds (1201h, 1202h not valid), slave 3
// from tests/data/master/slave.eds (its default SDO only). The manager is node 1.
#include <gtest/gtest.h>

#include "master/master_support.hpp"
#include "sdo_manager_engine_rig.hpp"

namespace nmt::engine_test {
namespace {

class SdoManagerEngine : public ::testing::Test, public ManagerEngineRig {};

// §7.2.1, §7.2.4 guideline 2: the scan reads 1F10h from 127 down, one access each, and stops at
// the first open request (Rq indication); the SRD's client entry named in 1F10h gets the
// manager's node-ID and two pool COB-IDs, its 1017h is read (no 1016h entry here), and 1F10h
// is confirmed last with Cnxn 1.
TEST_F(SdoManagerEngine, RegistrationScansFrom127DownAndEnablesTheClientEntryNamedIn1F10h) {
  add_srd(120);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  std::vector<Access> expected;
  for (std::uint8_t node = 127; node >= 120; --node) expected.push_back(read(node, 0x1F10, 0));
  expected.push_back(write(120, 0x1281, 3, kManager));
  expected.push_back(write(120, 0x1281, 1, 0x680));
  expected.push_back(write(120, 0x1281, 2, 0x681));
  expected.push_back(read(120, 0x1017, 0));
  expected.push_back(write(120, 0x1F10, 0, 0x12810002));
  EXPECT_EQ(port.accesses, expected);
  EXPECT_EQ(at(120, 0x1281, 1), 0x680U);
  EXPECT_EQ(at(120, 0x1281, 2), 0x681U);
  EXPECT_EQ(at(120, 0x1281, 3), kManager);
  EXPECT_EQ(at(120, 0x1F10, 0), 0x12810002U);
  EXPECT_EQ(own(0x1F02, 1), kInUse | 0x680);
  EXPECT_EQ(own(0x1F02, 2), kInUse | 0x681);
  // 1F03h sub 1 = client offset 01h, client 78h (120), server offset 01h (1201h), server 01h.
  EXPECT_EQ(own(0x1F03, 1), 0x01780101U);
  // The own channel 1201h serves the SRD; its heartbeat (1017h = 100 ms) is consumed with
  // 2 x 100 + 100 ms.
  EXPECT_EQ(own(0x1201, 1), 0x680U);
  EXPECT_EQ(own(0x1201, 3), 120U);
  ASSERT_EQ(port.watched.count(120), 1U);
  ASSERT_TRUE(port.watched[120].has_value());
  EXPECT_EQ(port.watched[120]->count(), Duration(300ms).count());
  const auto srds = engine().srds();
  ASSERT_EQ(srds.size(), 1U);
  EXPECT_EQ(srds[0].node, 120);
  EXPECT_EQ(srds[0].client_index, 0x1281);
}

// §7.1: a free default SDO of S needs no write to S; the SRD's entry gets 600h/580h + S.
TEST_F(SdoManagerEngine, RequestGetsTheFreeDefaultSdoOfTheSlaveWithoutWritingToIt) {
  add_srd(120);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  port.accesses.clear();
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  const std::vector<Access> expected{read(2, 0x1000, 0), write(120, 0x1282, 3, 2),
                                     write(120, 0x1282, 1, 0x602), write(120, 0x1282, 2, 0x582),
                                     write(120, 0x1F10, 0, 0x12820006)};
  EXPECT_EQ(port.accesses, expected);
  // 1F03h sub 2: client offset 02h, client 78h, server offset 00h (default), server 02h.
  EXPECT_EQ(own(0x1F03, 2), 0x02780002U);
}

// §7.1: a second SRD for the same slave gets S's free 1201h with the next two pool COB-IDs.
TEST_F(SdoManagerEngine, SecondSrdForTheSameSlaveGetsAnAdditionalServerChannel) {
  add_srd(120);
  add_srd(110);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  ASSERT_TRUE(register_srd(110, 0x12810001));
  EXPECT_EQ(at(110, 0x1281, 1), 0x682U);
  port.accesses.clear();
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));
  const std::vector<Access> expected{
      read(2, 0x1201, 1),           write(2, 0x1201, 3, 110),         write(2, 0x1201, 1, 0x684),
      write(2, 0x1201, 2, 0x685),   write(110, 0x1282, 3, 2),         write(110, 0x1282, 1, 0x684),
      write(110, 0x1282, 2, 0x685), write(110, 0x1F10, 0, 0x12820006)};
  EXPECT_EQ(port.accesses, expected);
  EXPECT_EQ(at(2, 0x1201, 3), 110U);
  // 1F03h: client offset 02h, client 6Eh (110), server offset 01h (1201h), server 02h.
  EXPECT_EQ(own(0x1F03, 4), 0x026E0102U);
}

// §7.2.3: the 1F00h write succeeds (the manager started); 1F10h says why not: Cnxn 0, 03h.
TEST_F(SdoManagerEngine, NoFreeServerChannelOnTheSlaveIsReportedIn1F10hWithError03h) {
  add_srd(120);
  add_srd(110);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 3));
  ASSERT_TRUE(register_srd(110, 0x12810001));
  const auto answer = srd_write(110, 0x1281, 0x1F00, request_word(0x1282, 110, 3));
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(answer->data[0], 0x60);
  run();
  EXPECT_EQ(at(110, 0x1F10, 0), 0x12820300U);
  ASSERT_EQ(events_of(Kind::SdoConnectionRefused, 110).size(), 1U);
  EXPECT_EQ(events_of(Kind::SdoConnectionRefused, 110).back().connection_error,
            cfg::sdo_manager::DynamicSdoError::kNoFreeServerOnSlave);
  EXPECT_EQ(at(110, 0x1282, 1) & kInvalid, kInvalid);
  EXPECT_EQ(own(0x1F02, 5), 0x684U);  // the pool entries it would have taken stay free
}

TEST_F(SdoManagerEngine, SilentSlaveIsReportedWithError04h) {
  add_srd(120);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_TRUE(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 50)).has_value());
  run();
  EXPECT_EQ(at(120, 0x1F10, 0), 0x12820400U);  // §7.2.3 error 04h: slave S not available
}

// §7.2.3: index 0 releases all connections of the SRD to the slave, on both sides.
TEST_F(SdoManagerEngine, ReleaseWithIndex0ReleasesEveryConnectionToTheSlaveOnBothSides) {
  add_srd(120);
  add_srd(110);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  ASSERT_TRUE(register_srd(110, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));
  ASSERT_TRUE(srd_write(110, 0x1281, 0x1F01, request_word(0, 110, 2)).has_value());
  run();
  ASSERT_EQ(events_of(Kind::SdoConnectionReleased, 110).size(), 1U);
  EXPECT_EQ(at(110, 0x1282, 1), kInvalid | 0x684);
  EXPECT_EQ(at(110, 0x1282, 2), kInvalid | 0x685);
  EXPECT_EQ(at(2, 0x1201, 1), kInvalid | 0x684);
  EXPECT_EQ(at(2, 0x1201, 2), kInvalid | 0x685);
  EXPECT_EQ(own(0x1F02, 5), 0x684U);  // bit 30 cleared
  EXPECT_EQ(own(0x1F03, 4), 0U);
  EXPECT_EQ(at(110, 0x1281, 1), 0x682U);
  EXPECT_EQ(engine().connections().size(), 3U);
}

// §7.2.3: "If the Manager refuses the request ... abort code 060A 0023h", frame for frame on the
// SRD's channel (CiA 301 abort transfer: 80h, index, sub, code).
TEST_F(SdoManagerEngine, RequestFromAnUnregisteredNodeIsAbortedWith060A0023) {
  add_srd(120);
  engine();
  EXPECT_EQ(dict.write(0x1F00, 0, le(request_word(0x1282, 100, 2), 4), now),
            SdoAbort::ResourceNotAvailable);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  // Registered, but the SRD field is not the node of the channel it writes on.
  auto answer = srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 100, 2));
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(*answer, *from_candump("681#80001F0023000A06"));
  // "The requested Node-ID must not be 0."
  answer = srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 0));
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(*answer, *from_candump("681#80001F0023000A06"));
}

TEST_F(SdoManagerEngine, ManagerObjectsKeepTheirAccessTypes) {
  engine();
  std::vector<std::uint8_t> data;
  // §7.2.3: 1F00h/1F01h wo, 1F03h ro.
  EXPECT_EQ(dict.read(0x1F00, 0, data, now), SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(dict.read(0x1F01, 0, data, now), SdoAbort::ReadOfWriteOnly);
  EXPECT_EQ(dict.write(0x1F03, 1, le(0x01780101, 4), now), SdoAbort::WriteOfReadOnly);
  EXPECT_EQ(own(0x1F03, 0), 254U);
  EXPECT_EQ(own(0x1F06, 0), 254U);
  // 1F02h: bit 30 belongs to the manager.
  EXPECT_EQ(dict.write(0x1F02, 1, le(kInUse | 0x690, 4), now), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(dict.write(0x1F02, 1, le(0x690, 4), now), SdoAbort::None);
}

TEST_F(SdoManagerEngine, PoolIsNotWritableWhileConnectionsUseIt) {
  add_srd(120);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  EXPECT_EQ(dict.write(0x1F02, 10, le(0x6F0, 4), now), SdoAbort::DeviceState);
}

TEST_F(SdoManagerEngine, AllDefaultSdosAreGrantedWithCnxnState2) {
  add_srd(120);
  // §7.2.3: 00000003h asks for all default SDOs; Cnxn state 2 grants them.
  ASSERT_TRUE(register_srd(120, 0x00000003));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x00000004U);
  EXPECT_TRUE(engine().connections().empty());
  ASSERT_EQ(engine().srds().size(), 1U);
  EXPECT_TRUE(engine().srds()[0].all_default_sdos);
  // §7.1: the master's own transfers keep off every default SDO now.
  EXPECT_TRUE(engine().default_sdo_given_out(3_node));
}

TEST_F(SdoManagerEngine, DeregistrationReleasesEverythingAndTheChannelToTheManagerLast) {
  add_srd(120);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  EXPECT_TRUE(engine().default_sdo_given_out(2_node));
  // §7.2.3: slave node-ID 0 releases all connections and de-registers.
  const auto answer = srd_write(120, 0x1281, 0x1F01, request_word(0, 120, 0));
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(*answer, *from_candump("681#60011F0000000000"));
  run();
  ASSERT_EQ(events_of(Kind::SrdDeregistered, 120).size(), 1U);
  EXPECT_EQ(at(120, 0x1282, 1), kInvalid | 0x602);
  EXPECT_EQ(at(120, 0x1281, 1), kInvalid | 0x680);
  const auto released = events_of(Kind::SdoConnectionReleased, 120);
  ASSERT_EQ(released.size(), 2U);
  EXPECT_FALSE(released[0].connection->to_manager);
  EXPECT_TRUE(released[1].connection->to_manager);
  EXPECT_TRUE(engine().srds().empty());
  EXPECT_EQ(own(0x1F03, 1), 0U);
  EXPECT_EQ(own(0x1F02, 1), 0x680U);
  EXPECT_EQ(own(0x1201, 1), kInvalid | 0x680);  // the own channel is closed
  EXPECT_FALSE(engine().default_sdo_given_out(2_node));
  EXPECT_EQ(std::count(port.unwatched.begin(), port.unwatched.end(), 120), 1);
}

// §7.2.3 Cnxn state 2 needs "all default SDOs in the system are unused": with slave 2's default
// SDO held by a connection, 00000003h gets Cnxn 0 with error 00h, and nothing is given.
TEST_F(SdoManagerEngine, AllDefaultSdosAreNotGrantedWhileOneIsHeld) {
  add_srd(126);
  add_srd(127);
  add_slaves();
  ASSERT_TRUE(register_srd(126, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(126, 2));
  EXPECT_FALSE(register_srd(127, 0x00000003));
  EXPECT_EQ(at(127, 0x1F10, 0), 0x00000000U);
  ASSERT_EQ(events_of(Kind::SrdRegistrationFailed, 127).size(), 1U);
  EXPECT_EQ(events_of(Kind::SrdRegistrationFailed, 127)[0].connection_error,
            cfg::sdo_manager::DynamicSdoError::kNoDetails);
  EXPECT_EQ(engine().srds().size(), 1U);
}

// §7.2.3 1F02h bit 29: a 29-bit identifier. With only such entries free, the SRD's channel to
// the manager runs on extended frames, and the engine's own channel answers on them.
TEST_F(SdoManagerEngine, PoolEntriesWith29BitIdentifiersGiveAnExtendedChannel) {
  constexpr std::uint32_t k29Bit = 0x20000000U;
  dict.insert(make_entry(0x1F02, 0, "pool", cfg::DataType::Unsigned8, cfg::AccessType::Const, 3));
  dict.insert(make_entry(0x1F02, 1, "pool 1", cfg::DataType::Unsigned32, cfg::AccessType::Rw,
                         k29Bit | 0x1234567U));
  dict.insert(make_entry(0x1F02, 2, "pool 2", cfg::DataType::Unsigned32, cfg::AccessType::Rw,
                         k29Bit | 0x1234568U));
  dict.insert(make_entry(0x1F02, 3, "pool 3", cfg::DataType::Unsigned32, cfg::AccessType::Rw,
                         kInvalid | 0x680U));
  add_srd(120);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  EXPECT_EQ(at(120, 0x1281, 1), k29Bit | 0x1234567U);
  EXPECT_EQ(at(120, 0x1281, 2), k29Bit | 0x1234568U);
  EXPECT_EQ(own(0x1F02, 1), kInUse | k29Bit | 0x1234567U);
  // The SRD reads 1F02h sub 0 over it: upload initiate 40h, answered expedited with 1 byte.
  auto request = *from_candump("01234567#40021F0000000000");
  ASSERT_TRUE(request.extended);
  ASSERT_TRUE(engine().on_frame(request, now, out));
  EXPECT_EQ(out.frames.back(), *from_candump("01234568#4F021F0003000000"));
  EXPECT_TRUE(out.frames.back().extended);
}

// §7.2.1: the loss of an SRD's error control releases everything it held (S's server entry
// too; the SRD itself is not written, each write to it tried once) and de-registers it.
TEST_F(SdoManagerEngine, SrdErrorControlLossReleasesItsConnectionsOnBothSides) {
  add_srd(120);
  add_srd(110);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));
  ASSERT_TRUE(register_srd(110, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));
  ASSERT_EQ(at(2, 0x1201, 3), 110U);
  port.devices.erase(110);
  port.accesses.clear();
  engine().node_lost(110_node, now, out);
  ASSERT_EQ(events_of(Kind::SrdLost, 110).size(), 1U);
  run();
  // The connection to S first, the SRD's channel to the manager last.
  const std::vector<Access> expected{
      write(110, 0x1282, 1, kInvalid | 0x684), write(110, 0x1282, 2, kInvalid | 0x685),
      write(2, 0x1201, 1, kInvalid | 0x684),   write(2, 0x1201, 2, kInvalid | 0x685),
      write(110, 0x1281, 1, kInvalid | 0x682), write(110, 0x1281, 2, kInvalid | 0x683)};
  EXPECT_EQ(port.accesses, expected);
  EXPECT_EQ(events_of(Kind::SdoConnectionReleased, 110).size(), 2U);
  EXPECT_TRUE(events_of(Kind::SrdDeregistered, 110).empty());  // lost, not de-registered
  EXPECT_EQ(at(2, 0x1201, 1) & kInvalid, kInvalid);
  EXPECT_EQ(own(0x1F02, 3), 0x682U);
  EXPECT_EQ(own(0x1F02, 5), 0x684U);
  for (const auto& row : engine().connections()) EXPECT_NE(row.srd, 110);
  ASSERT_EQ(engine().srds().size(), 1U);
  EXPECT_EQ(engine().srds()[0].node, 120);
}

// §7.2.3 xxxx0009h (Req EC): the manager watches the slave for the SRD; its loss is written to
// the SRD's 1F11h (reason 00h, node-ID), then the client entry is cleared.
TEST_F(SdoManagerEngine, SlaveFailureIsReportedIn1F11hToAnSrdThatAskedForErrorControl) {
  add_srd(120);
  add_device(5, "master/slave.eds");
  ASSERT_TRUE(register_srd(120, 0x12810009));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x1281000AU);  // Req EC kept: supported
  ASSERT_NO_FATAL_FAILURE(connect(120, 5));
  EXPECT_EQ(at(120, 0x1F10, 0), 0x1282000EU);
  ASSERT_EQ(port.watched.count(5), 1U);  // §7.2.5 step 4.4
  port.devices.erase(5);
  engine().node_lost(5_node, now, out);
  run();
  ASSERT_EQ(events_of(Kind::SlaveFailedReported, 120).size(), 1U);
  EXPECT_EQ(at(120, 0x1F11, 0), 0x0005U);
  ASSERT_EQ(events_of(Kind::SdoConnectionReleased, 120).size(), 1U);
  EXPECT_EQ(at(120, 0x1282, 1) & kInvalid, kInvalid);
}

// A scan (126 silent node-IDs x the scan timeout) lets a request that came meanwhile go before
// its next read (choice, nmt/master/nmt_master.hpp).
TEST_F(SdoManagerEngine, RequestIsServedBetweenTheReadsOfAScanNotAfterIt) {
  add_srd(120);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  port.accesses.clear();
  ASSERT_TRUE(engine().on_frame(*from_candump("6E0#"), now, out));
  engine().on_timer(now, out);
  ASSERT_EQ(port.accesses.size(), 1U);  // 127's 1F10h
  ASSERT_TRUE(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 2)).has_value());
  run();
  // 127, then the request's accesses, then the scan goes on from 126 down to node 3 (2's
  // default SDO is now held: skipped).
  ASSERT_GE(port.accesses.size(), 7U);
  EXPECT_EQ(port.accesses[0], read(127, 0x1F10, 0));
  EXPECT_EQ(port.accesses[1], read(2, 0x1000, 0));
  EXPECT_EQ(port.accesses[5], write(120, 0x1F10, 0, 0x12820006));
  EXPECT_EQ(port.accesses[6], read(126, 0x1F10, 0));
  EXPECT_EQ(port.accesses.back(), read(3, 0x1F10, 0));
  EXPECT_EQ(std::count(port.accesses.begin(), port.accesses.end(), read(2, 0x1F10, 0)), 0);
}

// CiA 301: a slave's additional server entries (1201h..) are not kept over a reset; the manager
// releases the connections on them when the slave boots up, writing only the SRD.
TEST_F(SdoManagerEngine, SlaveBootUpReleasesTheConnectionsOnItsAdditionalServerEntries) {
  add_srd(120);
  add_srd(110);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));  // 2's default SDO
  ASSERT_TRUE(register_srd(110, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(110, 2));  // 2's 1201h, pool subs 5/6
  ASSERT_EQ(own(0x1F03, 4), 0x026E0102U);
  port.accesses.clear();
  engine().node_booted(2_node, now, out);
  run();
  const std::vector<Access> expected{write(110, 0x1282, 1, kInvalid | 0x684),
                                     write(110, 0x1282, 2, kInvalid | 0x685)};
  EXPECT_EQ(port.accesses, expected);
  const auto released = events_of(Kind::SdoConnectionReleased, 110);
  ASSERT_EQ(released.size(), 1U);
  EXPECT_EQ(released[0].connection->server, 2);
  EXPECT_EQ(released[0].connection->server_index, 0x1201);
  EXPECT_EQ(own(0x1F03, 4), 0U);
  EXPECT_EQ(own(0x1F02, 5), 0x684U);
  EXPECT_EQ(own(0x1F02, 6), 0x685U);
  EXPECT_EQ(own(0x1F03, 2), 0x02780002U);  // the connection on 2's default SDO stays
}

// The own server channels 1201h.. are the manager's: a tool's write is refused with 0800 0021.
TEST_F(SdoManagerEngine, ToolWritesToTheManagersServerChannelsAreRefusedWith08000021) {
  add_srd(120);
  EXPECT_EQ(engine().on_frame(*from_candump("6E1#"), now, out), false);
  EXPECT_EQ(dict.write(0x1202, 1, le(0x6F0, 4), now), SdoAbort::LocalControl);
  EXPECT_EQ(dict.write(0x1202, 3, le(100, 1), now), SdoAbort::LocalControl);
  EXPECT_EQ(own(0x1202, 1), kInvalid);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  EXPECT_EQ(dict.write(0x1201, 1, le(kInvalid | 0x680, 4), now), SdoAbort::LocalControl);
  EXPECT_EQ(own(0x1201, 1), 0x680U);
}

// §7: an inactive manager (the master is not active) ignores 6E0h and refuses 1F00h with
// 0800 0022.
TEST_F(SdoManagerEngine, InactiveManagerIgnoresTheDynamicSdoRequestAndRefuses1F00h) {
  add_srd(120);
  port.devices.at(120).set_unsigned(0x1F10, 0, 0x12810001);
  port.active = false;
  EXPECT_FALSE(engine().on_frame(*from_candump("6E0#"), now, out));
  run();
  EXPECT_TRUE(port.accesses.empty());
  EXPECT_EQ(dict.write(0x1F00, 0, le(request_word(0x1282, 120, 2), 4), now), SdoAbort::DeviceState);
}

// 1F00h requests beyond SdoManagerSettings::max_queued_requests are refused with 0504 0005.
TEST_F(SdoManagerEngine, RequestsBeyondTheQueueBoundAreRefusedOutOfMemory) {
  settings.max_queued_requests = 1;
  add_srd(120);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_EQ(dict.write(0x1F00, 0, le(request_word(0x1282, 120, 2), 4), now), SdoAbort::None);
  EXPECT_EQ(dict.write(0x1F00, 0, le(request_word(0x1280, 120, 3), 4), now), SdoAbort::OutOfMemory);
  run();
  ASSERT_EQ(events_of(Kind::SdoConnectionEstablished, 120).size(), 1U);
  ASSERT_EQ(dict.write(0x1F00, 0, le(request_word(0x1280, 120, 3), 4), now), SdoAbort::None);
  run();
  EXPECT_EQ(engine().connections().size(), 3U);
}

// §7.2.3 error 01h "No SDO channel free": registrations are bounded by the own channels; a
// refused SRD registers once another gave its channel back.
TEST_F(SdoManagerEngine, SrdRefusedForLackOfAChannelRegistersOnceAnotherDeregisters) {
  settings.channels = 1;
  add_srd(110);
  add_srd(120);
  ASSERT_TRUE(register_srd(120, 0x12810001));
  EXPECT_FALSE(register_srd(110, 0x12810001));
  EXPECT_EQ(at(110, 0x1F10, 0) >> 8U & 0xFFU, 0x01U);  // Cnxn 0, error 01h
  ASSERT_TRUE(srd_write(120, 0x1281, 0x1F01, request_word(0, 120, 0)).has_value());
  run();
  ASSERT_EQ(events_of(Kind::SrdDeregistered, 120).size(), 1U);
  EXPECT_TRUE(register_srd(110, 0x12810001));
  EXPECT_EQ(at(110, 0x1F10, 0), 0x12810002U);  // Cnxn 1, no error
}

// §7.2.1: a 6E0h that comes while a scan runs may be from an SRD the scan has passed: another
// scan follows the registration the first one ends in, and finds it.
TEST_F(SdoManagerEngine, DynamicSdoRequestDuringAScanMakesAnotherScanFollowIt) {
  add_srd(120);
  add_srd(100);
  port.devices.at(120).set_unsigned(0x1F10, 0, 0x12810001);
  ASSERT_TRUE(engine().on_frame(*from_candump("6E0#"), now, out));
  engine().on_timer(now, out);
  ASSERT_EQ(port.accesses.size(), 1U);  // 127's 1F10h
  port.devices.at(100).set_unsigned(0x1F10, 0, 0x12810001);
  ASSERT_TRUE(engine().on_frame(*from_candump("6E0#"), now, out));
  run();
  EXPECT_EQ(events_of(Kind::SrdRegistered, 120).size(), 1U);
  ASSERT_EQ(events_of(Kind::SrdRegistered, 100).size(), 1U);
  // The second scan starts at 127 again and skips the registered 120.
  const auto second =
      std::find(port.accesses.begin(), port.accesses.end(), write(120, 0x1F10, 0, 0x12810002));
  ASSERT_NE(second, port.accesses.end());
  ASSERT_NE(std::next(second), port.accesses.end());
  EXPECT_EQ(*std::next(second), read(127, 0x1F10, 0));
  EXPECT_EQ(std::count(second, port.accesses.end(), read(120, 0x1F10, 0)), 0);
  EXPECT_EQ(at(100, 0x1F10, 0), 0x12810002U);
}

// §7.2.2: the SRD refuses the write of its client entry (here: 1284h, which it does not have)
// after S's server entry was written: S's entry is invalidated again, the pool entries are
// free, and the refusal is reported with error 00h; 1F10h is not written (the SRD did not take
// its entry, so it cannot take a confirmation either).
TEST_F(SdoManagerEngine, ConnectionTheSrdRefusesIsUndoneOnTheSlaveAndReported) {
  add_srd(120);
  add_srd(110);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_NO_FATAL_FAILURE(connect(120, 2));  // 2's default SDO is now held
  ASSERT_TRUE(register_srd(110, 0x12810001));
  port.accesses.clear();
  const auto answer = srd_write(110, 0x1281, 0x1F00, request_word(0x1284, 110, 2));
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(answer->data[0], 0x60);
  run();
  const std::vector<Access> expected{
      read(2, 0x1201, 1),
      write(2, 0x1201, 3, 110),
      write(2, 0x1201, 1, 0x684),
      write(2, 0x1201, 2, 0x685),
      write(110, 0x1284, 3, 2),  // refused: no such object
      write(2, 0x1201, 1, kInvalid | 0x684),
      write(2, 0x1201, 2, kInvalid | 0x685),
  };
  EXPECT_EQ(port.accesses, expected);
  ASSERT_EQ(events_of(Kind::SdoConnectionRefused, 110).size(), 1U);
  EXPECT_EQ(events_of(Kind::SdoConnectionRefused, 110)[0].connection_error,
            cfg::sdo_manager::DynamicSdoError::kNoDetails);
  EXPECT_EQ(at(110, 0x1F10, 0), 0x12810002U);
  EXPECT_EQ(at(2, 0x1201, 1), kInvalid | 0x684);
  EXPECT_EQ(own(0x1F02, 5), 0x684U);
  EXPECT_EQ(own(0x1F02, 6), 0x685U);
  EXPECT_EQ(engine().connections().size(), 3U);  // two registrations and 120's connection
}

// Reset communication of all nodes: the tables go, and a result of a transfer that still ran
// is stale.
TEST_F(SdoManagerEngine, ClearEmptiesTheTablesAndDropsStaleResults) {
  add_srd(120);
  add_slaves();
  ASSERT_TRUE(register_srd(120, 0x12810001));
  ASSERT_TRUE(srd_write(120, 0x1281, 0x1F00, request_word(0x1282, 120, 2)).has_value());
  engine().on_timer(now, out);
  ASSERT_EQ(port.pending.size(), 1U);
  engine().clear();
  run();
  EXPECT_TRUE(events_of(Kind::SdoConnectionEstablished, 120).empty());
  EXPECT_TRUE(engine().srds().empty());
  EXPECT_TRUE(engine().connections().empty());
  EXPECT_EQ(own(0x1F03, 1), 0U);
  EXPECT_EQ(own(0x1F02, 1), 0x680U);
  EXPECT_EQ(own(0x1201, 1), kInvalid | 0x680);
  EXPECT_FALSE(engine().next_deadline().has_value());
}

}  // namespace
}  // namespace nmt::engine_test
