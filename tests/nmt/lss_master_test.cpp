// LSS master (CiA 305): each service's request bytes and its reading of the answers, written out
// by hand from the layouts nmt/lss/lss.hpp cites (CANopenNode 305/CO_LSS.h, lely-core
// src/co/lss.c); then the master against LSS slaves on the simulated bus in simulated time:
// Fastscan, Fastscan of a known address, a device that never answers, a refused configure node-ID.
// The procedures built from these services (the scan of many devices) are
// tests/nmt/lss_procedure_test.cpp's.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "lss_engine_fixture.hpp"
#include "nmt/lss/lss_event_text.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/sim/sim_bus.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using lss_test::Frames;
using Kind = LssMasterEvent::Kind;

class LssMasterTest : public lss_test::EngineTest<LssMaster> {
 protected:
  LssMaster& master = engine;
};

TEST_F(LssMasterTest, SwitchStateGlobalSends04WithTheModeAndEndsAtOnce) {
  EXPECT_EQ(call([](auto& m, auto t, auto& o) {
              return m.switch_state_global(LssState::Configuration, t, o);
            }),
            Frames{"7E5#0401000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_FALSE(master.busy());
  EXPECT_EQ(
      call([](auto& m, auto t, auto& o) { return m.switch_state_global(LssState::Waiting, t, o); }),
      Frames{"7E5#0400000000000000"});
}

TEST_F(LssMasterTest, SwitchStateSelectiveSends40To43LittleEndianAndWaitsFor44) {
  const LssAddress a{0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE};
  EXPECT_EQ(call([&](auto& m, auto t, auto& o) { return m.switch_state_selective(a, t, o); }),
            (Frames{"7E5#4004030201000000", "7E5#410B0A0000000000", "7E5#4202000100000000",
                    "7E5#43BEBAFECA000000"}));
  EXPECT_TRUE(events.empty());
  EXPECT_EQ(master.next_deadline(), TimePoint{100ms});  // the default timeout
  answer("7E4#4400000000000000");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].address, a);
}

TEST_F(LssMasterTest, SwitchStateSelectiveWithoutAnswerIsATimeoutAfterOneLssTimeout) {
  const LssAddress a{0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE};
  call([&](auto& m, auto t, auto& o) { return m.switch_state_selective(a, t, o); });
  // Another service's answer (4Fh, a Fastscan answer) is not the selection's.
  answer("7E4#4F00000000000000", false);
  EXPECT_TRUE(tick(TimePoint{99ms}).empty());
  EXPECT_TRUE(events.empty());
  EXPECT_TRUE(tick(TimePoint{100ms}).empty());  // nothing more is sent
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Timeout);
  EXPECT_EQ(events[0].address, a);
  EXPECT_FALSE(master.busy());
}

TEST_F(LssMasterTest, ConfigureNodeIdSends11AndReadsErrorCode1AsOutOfRange) {
  // A node-ID the device does not accept (CiA 305 error code 1); the master sends only 1..127
  // and FFh (cfg::NodeId), so the device's range is what refuses here.
  EXPECT_EQ(call([](auto& m, auto t, auto& o) {
              return m.configure_node_id(cfg::NodeId::from(127), t, o);
            }),
            Frames{"7E5#117F000000000000"});
  answer("7E4#1101000000000000");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Refused);
  EXPECT_EQ(events[0].error_code, 1);
  EXPECT_EQ(describe(events[0]), "configure node-ID: refused: node-ID out of range (error code 1)");
}

TEST_F(LssMasterTest, ConfigureNodeIdAnswer0IsDone) {
  call([](auto& m, auto t, auto& o) { return m.configure_node_id(cfg::NodeId::from(5), t, o); });
  answer("7E4#1100000000000000");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].node_id, cfg::NodeId::from(5));
}

TEST_F(LssMasterTest, ConfigureNodeIdWithoutNodeIdSendsFFhNotConfigured) {
  // CiA 305: node-ID FFh sends the device back to "not configured" at its next reset.
  EXPECT_EQ(call([](auto& m, auto t, auto& o) { return m.configure_node_id(std::nullopt, t, o); }),
            Frames{"7E5#11FF000000000000"});
  answer("7E4#1100000000000000");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].node_id, std::nullopt);
}

TEST_F(LssMasterTest, ConfigureBitTimingSends13SelectorAndIndex) {
  EXPECT_EQ(call([](auto& m, auto t, auto& o) {
              return m.configure_bit_timing(*lss::bit_timing_index(250), t, o);
            }),
            Frames{"7E5#1300030000000000"});
  answer("7E4#1301000000000000");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(describe(events[0]),
            "configure bit timing: refused: bit rate not supported (error code 1)");
}

TEST_F(LssMasterTest, ActivateBitTimingSends15WithTheDelayAndEndsAfterTwiceIt) {
  EXPECT_EQ(call([](auto& m, auto t, auto& o) { return m.activate_bit_timing(1000, t, o); }),
            Frames{"7E5#15E8030000000000"});
  EXPECT_TRUE(tick(TimePoint{1999ms}).empty());
  EXPECT_TRUE(events.empty());
  tick(TimePoint{2000ms});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
}

TEST_F(LssMasterTest, StoreConfigurationSends17AndNamesErrorCodes2AndFF) {
  EXPECT_EQ(call([](auto& m, auto t, auto& o) { return m.store_configuration(t, o); }),
            Frames{"7E5#1700000000000000"});
  answer("7E4#1702000000000000");
  call([](auto& m, auto t, auto& o) { return m.store_configuration(t, o); });
  answer("7E4#17FF330000000000");
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(describe(events[0]),
            "store configuration: refused: storage media access error (error code 2)");
  EXPECT_EQ(describe(events[1]),
            "store configuration: refused: manufacturer-specific error 33h (error code 255)");
  EXPECT_EQ(events[1].spec_error, 0x33);
}

TEST_F(LssMasterTest, InquireIdentitySends5AAndReadsBytes1To4LittleEndian) {
  EXPECT_EQ(
      call([](auto& m, auto t, auto& o) { return m.inquire(LssService::InquireVendorId, t, o); }),
      Frames{"7E5#5A00000000000000"});
  answer("7E4#5A04030201000000");
  EXPECT_EQ(
      call([](auto& m, auto t, auto& o) { return m.inquire(LssService::InquireSerial, t, o); }),
      Frames{"7E5#5D00000000000000"});
  answer("7E4#5DBEBAFECA000000");
  EXPECT_EQ(
      call([](auto& m, auto t, auto& o) { return m.inquire(LssService::InquireNodeId, t, o); }),
      Frames{"7E5#5E00000000000000"});
  answer("7E4#5E05000000000000");
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0].value, 0x01020304u);
  EXPECT_EQ(events[1].value, 0xCAFEBABEu);
  EXPECT_EQ(events[2].value, 5u);
}

TEST_F(LssMasterTest, AnAnswerOfAnotherServiceIsNotTaken) {
  call([](auto& m, auto t, auto& o) { return m.inquire(LssService::InquireProductCode, t, o); });
  answer("7E4#5A04030201000000", false);
  EXPECT_TRUE(events.empty());
}

TEST_F(LssMasterTest, IdentifyRemoteSlaveSends46To4BAndEndsAfterTheScanStep) {
  LssAddressRange range{0x01020304, 0x00000A0B, 1, 2, 0x100, 0x1FF};
  EXPECT_EQ(call([&](auto& m, auto t, auto& o) { return m.identify_remote_slaves(range, t, o); }),
            (Frames{"7E5#4604030201000000", "7E5#470B0A0000000000", "7E5#4801000000000000",
                    "7E5#4902000000000000", "7E5#4A00010000000000", "7E5#4BFF010000000000"}));
  now = TimePoint{1ms};
  answer("7E4#4F00000000000000");
  EXPECT_TRUE(events.empty());  // more devices may answer
  EXPECT_EQ(master.next_deadline(), TimePoint{11ms});
  tick(TimePoint{11ms});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
}

TEST_F(LssMasterTest, IdentifyNonConfiguredSends4CAndReportsNotFoundWithoutAnswer) {
  EXPECT_EQ(call([](auto& m, auto t, auto& o) { return m.identify_non_configured(t, o); }),
            Frames{"7E5#4C00000000000000"});
  tick(TimePoint{10ms});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::NotFound);
}

TEST_F(LssMasterTest, FastscanStartsWithBitCheck80h) {
  EXPECT_EQ(call([](auto& m, auto t, auto& o) { return m.fastscan(t, o); }),
            Frames{"7E5#5100000000800000"});
  now = TimePoint{1ms};
  answer("7E4#4F00000000000000");
  // Then bit 31 of the vendor-ID, queried as 0: IDNumber 0, BitCheck 31, LSSSub 0, LSSNext 0.
  EXPECT_EQ(tick(TimePoint{11ms}), Frames{"7E5#51000000001F0000"});
}

TEST_F(LssMasterTest, FastscanWithoutAnswerToTheResetFindsNothing) {
  call([](auto& m, auto t, auto& o) { return m.fastscan(t, o); });
  tick(TimePoint{10ms});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::NotFound);
  EXPECT_FALSE(master.busy());
}

// CiA 305 Fastscan with BitCheck 0: all 32 bits of part LSSSub compared, LSSNext the next part
// (0 after the serial number, which puts the matching device in LSS configuration).
TEST_F(LssMasterTest, FastscanConfirmSendsTheResetThenTheFourPartsWithBitCheckZero) {
  const LssAddress a{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
  EXPECT_EQ(call([&](auto& m, auto t, auto& o) { return m.fastscan_confirm(a, t, o); }),
            Frames{"7E5#5100000000800000"});
  answer("7E4#4F00000000000000");
  EXPECT_TRUE(tick(TimePoint{9ms}).empty());
  EXPECT_EQ(tick(TimePoint{10ms}), Frames{"7E5#51DEC0577E000001"});
  answer("7E4#4F00000000000000");
  EXPECT_EQ(tick(TimePoint{20ms}), Frames{"7E5#5105030000000102"});
  answer("7E4#4F00000000000000");
  EXPECT_EQ(tick(TimePoint{30ms}), Frames{"7E5#5102000100000203"});
  answer("7E4#4F00000000000000");
  EXPECT_EQ(tick(TimePoint{40ms}), Frames{"7E5#5101100000000300"});
  answer("7E4#4F00000000000000");
  EXPECT_TRUE(events.empty());
  EXPECT_TRUE(tick(TimePoint{50ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].service, LssService::Fastscan);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].address, a);
}

TEST_F(LssMasterTest, FastscanConfirmOfAnAbsentAddressEndsAbsentAfterOneSilentStep) {
  const LssAddress a{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
  call([&](auto& m, auto t, auto& o) { return m.fastscan_confirm(a, t, o); });
  answer("7E4#4F00000000000000");  // some unconfigured device
  EXPECT_EQ(tick(TimePoint{10ms}), Frames{"7E5#51DEC0577E000001"});
  EXPECT_TRUE(tick(TimePoint{20ms}).empty());  // nobody has vendor-ID 7E57C0DEh
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Absent);
  EXPECT_EQ(events[0].address, a);
  EXPECT_FALSE(master.busy());
}

TEST_F(LssMasterTest, FastscanConfirmWithoutAnswerToTheResetFindsNothing) {
  call([](auto& m, auto t, auto& o) { return m.fastscan_confirm({1, 2, 3, 4}, t, o); });
  EXPECT_TRUE(tick(TimePoint{10ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::NotFound);
}

TEST_F(LssMasterTest, NoAnswerWithinTheTimeoutIsATimeoutEvent) {
  call([](auto& m, auto t, auto& o) { return m.configure_node_id(cfg::NodeId::from(5), t, o); });
  EXPECT_TRUE(tick(TimePoint{99ms}).empty());
  EXPECT_TRUE(events.empty());
  tick(TimePoint{100ms});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Timeout);
  EXPECT_EQ(describe(events[0]), "configure node-ID: no answer within 100 ms");
}

TEST_F(LssMasterTest, AnAnswerReceivedAfterTheTimeoutCountsAsLate) {
  call([](auto& m, auto t, auto& o) { return m.configure_node_id(cfg::NodeId::from(5), t, o); });
  now = TimePoint{150ms};  // the loop got to it late; it arrived after the deadline
  answer("7E4#1100000000000000", false);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Timeout);
}

TEST_F(LssMasterTest, OneServiceAtATimeAndABusyStartSaysWhyAndSendsNothing) {
  call([](auto& m, auto t, auto& o) { return m.store_configuration(t, o); });
  // engine.hpp rule 5: could not start is the call's answer; nothing goes into `out`.
  LssMaster::Output out;
  const cfg::Status started = master.configure_node_id(cfg::NodeId::from(5), now, out);
  ASSERT_FALSE(started.ok());
  EXPECT_EQ(started.error().message,
            "LSS configure node-ID not started: store configuration runs (one LSS service at a "
            "time)");
  EXPECT_TRUE(out.empty());
  // The running service is not disturbed.
  answer("7E4#1700000000000000");
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].service, LssService::StoreConfiguration);
  EXPECT_EQ(events[0].kind, Kind::Done);
}

TEST_F(LssMasterTest, InquireOfAServiceThatIsNoInquirySaysSoAndSendsNothing) {
  LssMaster::Output out;
  const cfg::Status started = master.inquire(LssService::StoreConfiguration, now, out);
  ASSERT_FALSE(started.ok());
  EXPECT_EQ(started.error().message, "LSS store configuration is not an inquire service");
  EXPECT_TRUE(out.empty());
  EXPECT_FALSE(master.busy());
}

// --- master against slaves on the simulated bus ------------------------------------------------

using LssBus = lss_test::LssBusTest<LssMaster>;

TEST_F(LssBus, FastscanFindsTheOnlyUnconfiguredDeviceAndLeavesItInConfiguration) {
  const LssAddress a{0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE};
  auto& slave = add(a);
  add({0x01020304, 0x00000A0B, 0x00010002, 0x00000001}, 9);  // configured: does not take part
  start([](auto& m, auto t, auto& o) { return m.fastscan(t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].address, a);
  EXPECT_EQ(slave.engine().state(), LssState::Configuration);
}

TEST_F(LssBus, FastscanSends133RequestsForOneDevice) {
  add({0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE});
  int requests = 0;
  bus.add_observer([&](const CanFrame& f, TimePoint) { requests += f.id == lss::kMasterCobId; });
  start([](auto& m, auto t, auto& o) { return m.fastscan(t, o); });
  run_until_done();
  // The reset, then per part 32 bit queries and a confirmation (lely-core's walk).
  EXPECT_EQ(requests, 1 + 4 * 33);
}

TEST_F(LssBus, FastscanAfterAnAddressFindsTheNextHigherOne) {
  const LssAddress low{0x00000001, 0x00000002, 0x00000003, 0x00000004};
  const LssAddress mid{0x00000001, 0x00000003, 0x00000000, 0x00000000};
  const LssAddress high{0x00000002, 0x00000000, 0x00000000, 0x00000001};
  add(high);
  add(low);
  add(mid);
  start([&](auto& m, auto t, auto& o) { return m.fastscan(low, t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].address, mid);
  start([](auto& m, auto t, auto& o) { return m.switch_state_global(LssState::Waiting, t, o); });
  start([&](auto& m, auto t, auto& o) { return m.fastscan(mid, t, o); });
  run_until_done();
  EXPECT_EQ(events.back().address, high);
  start([](auto& m, auto t, auto& o) { return m.switch_state_global(LssState::Waiting, t, o); });
  start([&](auto& m, auto t, auto& o) { return m.fastscan(high, t, o); });
  run_until_done();
  EXPECT_EQ(events.back().kind, Kind::NotFound);
}

TEST_F(LssBus, ADeviceThatNeverAnswersEndsInATimeout) {
  FunctionNode mute;  // on the bus, hears everything, says nothing
  bus.attach(mute);
  start([](auto& m, auto t, auto& o) { return m.switch_state_selective({1, 2, 3, 4}, t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Timeout);
  EXPECT_GE(bus.now(), TimePoint{100ms});
}

// The device's refusal of 0 and 128..254 (error code 1) is LssSlave's (lss_slave_test); the
// master cannot ask for them (cfg::NodeId), and reads the refusal (ConfigureNodeIdSends11...).
TEST_F(LssBus, ConfigureNodeIdWithoutNodeIdMakesTheDeviceUnconfiguredAtItsNextReset) {
  const LssAddress a{0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE};
  auto& slave = add(a, 3);
  start([&](auto& m, auto t, auto& o) { return m.switch_state_selective(a, t, o); });
  run_until_done();
  start([](auto& m, auto t, auto& o) { return m.configure_node_id(std::nullopt, t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[1].kind, Kind::Done);
  EXPECT_EQ(slave.engine().pending_node_id(), lss::kUnconfigured);
  EXPECT_EQ(slave.engine().active_node_id(), 3);
}

TEST_F(LssBus, SelectiveConfigureStoreAndInquireAgainstADevice) {
  const LssAddress a{0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE};
  auto& slave = add(a, 3);
  add({0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABF}, 4);  // stays in waiting
  std::vector<std::string> stored;
  slave.set_event_handler([&](const LssSlaveEvent& e, TimePoint) {
    if (e.kind == LssSlaveEvent::Kind::StoreRequested) stored.push_back(e.text);
  });
  auto run = [&](auto fn) {
    start(fn);
    run_until_done();
  };
  run([&](auto& m, auto t, auto& o) { return m.switch_state_selective(a, t, o); });
  run([](auto& m, auto t, auto& o) { return m.configure_node_id(cfg::NodeId::from(42), t, o); });
  run([](auto& m, auto t, auto& o) { return m.store_configuration(t, o); });
  run([](auto& m, auto t, auto& o) { return m.inquire(LssService::InquireSerial, t, o); });
  run([](auto& m, auto t, auto& o) { return m.inquire(LssService::InquireNodeId, t, o); });
  ASSERT_EQ(events.size(), 5u);
  for (const auto& e : events) EXPECT_EQ(e.kind, Kind::Done) << describe(e);
  EXPECT_EQ(events[3].value, 0xCAFEBABEu);
  EXPECT_EQ(events[4].value, 3u);  // the active node-ID; 42 is pending until reset
  EXPECT_EQ(stored, std::vector<std::string>{"LSS: store node-ID 42"});
}

}  // namespace
}  // namespace nmt
