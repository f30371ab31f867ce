// The CiA 305 procedures (nmt/lss/lss_procedure.hpp), with CiA 305's bytes as nmt/lss/lss.hpp cites
// them (CANopenNode 305/CO_LSS.h, lely-core src/co/lss.c): 04h switch state global (byte 1: 0
// waiting, 1 configuration), 40h-43h switch state selective answered 44h, 5Ah-5Eh inquire (the
// value little-endian in bytes 1-4, the node-ID in byte 1), 11h configure node-ID and 13h configure
// bit timing (table selector, index) answered with the error code in byte 1, 17h store
// configuration, 15h activate bit timing (the switch delay in ms, bytes 1-2), 51h Fastscan
// (IDNumber bytes 1-4, BitCheck byte 5, LSSSub byte 6, LSSNext byte 7; BitCheck 80h: every
// unconfigured device answers 4Fh), 4Ch identify non-configured remote slave answered 50h,
// 46h-4Bh identify remote slave answered 4Fh. First each procedure alone, frame by frame in
// simulated time, then against LSS slaves (nmt::LssSlave) on the simulated bus.
#include "nmt/lss/lss_procedure.hpp"

#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "lss_engine_fixture.hpp"
#include "nmt/lss/lss_event_text.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/sim/sim_bus.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using lss_test::Frames;
using Kind = LssProcedureEvent::Kind;

// tests/data/lss/lss_io.eds: 1018h vendor 7E57C0DEh, product 305h, revision 10002h, serial 1001h.
const LssAddress kDevice{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
const Frames kSelectDevice{"7E5#0400000000000000", "7E5#40DEC0577E000000", "7E5#4105030000000000",
                           "7E5#4202000100000000", "7E5#4301100000000000"};

class LssProcedureTest : public lss_test::EngineTest<LssProcedure> {
 protected:
  LssProcedure& procedure = engine;
};

TEST_F(LssProcedureTest, AssignNodeIdSelectsInquiresConfiguresStoresAndSwitchesBackToWaiting) {
  EXPECT_EQ(call([](auto& p, auto t, auto& o) {
              return p.assign_node_id(kDevice, cfg::NodeId::from(5), true, t, o);
            }),
            kSelectDevice);
  EXPECT_EQ(procedure.next_deadline(), TimePoint{100ms});
  EXPECT_EQ(answer("7E4#4400000000000000", TimePoint{1ms}), Frames{"7E5#5E00000000000000"});
  EXPECT_EQ(answer("7E4#5EFF000000000000", TimePoint{2ms}), Frames{"7E5#1105000000000000"});
  EXPECT_EQ(answer("7E4#1100000000000000", TimePoint{3ms}), Frames{"7E5#1700000000000000"});
  EXPECT_TRUE(events.empty());
  EXPECT_EQ(answer("7E4#1700000000000000", TimePoint{4ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].procedure, LssProcedureKind::AssignNodeId);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].at, TimePoint{4ms});
  EXPECT_EQ(events[0].address, kDevice);
  EXPECT_EQ(events[0].node_id, cfg::NodeId::from(5));
  EXPECT_EQ(events[0].previous_node_id, lss::kUnconfigured);
  EXPECT_FALSE(procedure.busy());
  EXPECT_EQ(procedure.next_deadline(), std::nullopt);
}

TEST_F(LssProcedureTest, AssignNodeIdWithoutStoreSkips17hAndWithoutInquiryAnswerHasNoPrevious) {
  call([](auto& p, auto t, auto& o) {
    return p.assign_node_id(kDevice, cfg::NodeId::from(5), false, t, o);
  });
  answer("7E4#4400000000000000", TimePoint{1ms});
  EXPECT_EQ(tick(TimePoint{101ms}), Frames{"7E5#1105000000000000"});  // 5Eh unanswered
  EXPECT_EQ(answer("7E4#1100000000000000", TimePoint{102ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].previous_node_id, std::nullopt);
}

TEST_F(LssProcedureTest, AssignNodeIdRefusedWithErrorCode1SwitchesBackAndFailsInWords) {
  call([](auto& p, auto t, auto& o) {
    return p.assign_node_id(kDevice, cfg::NodeId::from(127), true, t, o);
  });
  answer("7E4#4400000000000000", TimePoint{1ms});
  EXPECT_EQ(answer("7E4#5E03000000000000", TimePoint{2ms}), Frames{"7E5#117F000000000000"});
  EXPECT_EQ(answer("7E4#1101000000000000", TimePoint{3ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Failed);
  ASSERT_TRUE(events[0].step.has_value());
  EXPECT_EQ(events[0].step->service, LssService::ConfigureNodeId);
  EXPECT_EQ(events[0].step->kind, LssMasterEvent::Kind::Refused);
  EXPECT_EQ(events[0].step->error_code, 1);
  EXPECT_EQ(describe(events[0]), "configure node-ID: refused: node-ID out of range (error code 1)");
}

TEST_F(LssProcedureTest, AssignNodeIdToAnAbsentDeviceFailsAfterTheTimeoutWithoutMoreFrames) {
  call([](auto& p, auto t, auto& o) {
    return p.assign_node_id(kDevice, cfg::NodeId::from(5), true, t, o);
  });
  EXPECT_TRUE(tick(TimePoint{99ms}).empty());
  EXPECT_TRUE(tick(TimePoint{100ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Failed);
  EXPECT_EQ(events[0].step->service, LssService::SwitchStateSelective);
  EXPECT_EQ(events[0].step->kind, LssMasterEvent::Kind::Timeout);
  EXPECT_EQ(describe(events[0]), "switch state selective: no answer within 100 ms");
}

TEST_F(LssProcedureTest, InquireIdentityOfTheOnlyDeviceReadsFiveValuesAndSwitchesBack) {
  EXPECT_EQ(call([](auto& p, auto t, auto& o) { return p.inquire_identity(std::nullopt, t, o); }),
            (Frames{"7E5#0401000000000000", "7E5#5A00000000000000"}));
  EXPECT_EQ(answer("7E4#5ADEC0577E000000", TimePoint{1ms}), Frames{"7E5#5B00000000000000"});
  EXPECT_EQ(answer("7E4#5B05030000000000", TimePoint{2ms}), Frames{"7E5#5C00000000000000"});
  EXPECT_EQ(answer("7E4#5C02000100000000", TimePoint{3ms}), Frames{"7E5#5D00000000000000"});
  EXPECT_EQ(answer("7E4#5D01100000000000", TimePoint{4ms}), Frames{"7E5#5E00000000000000"});
  EXPECT_EQ(answer("7E4#5E07000000000000", TimePoint{5ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].address, kDevice);
  EXPECT_EQ(events[0].node_id, cfg::NodeId::from(7));
}

TEST_F(LssProcedureTest, InquireNodeIdAnswered0IsNoNodeIdAndFails) {
  EXPECT_EQ(call([](auto& p, auto t, auto& o) { return p.inquire_node_id(kDevice, t, o); }),
            kSelectDevice);
  EXPECT_EQ(answer("7E4#4400000000000000", TimePoint{1ms}), Frames{"7E5#5E00000000000000"});
  EXPECT_EQ(answer("7E4#5E00000000000000", TimePoint{2ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Failed);
  EXPECT_EQ(describe(events[0]),
            "inquire node-ID answered 0: no node-ID (CiA 305: 1..127, or 255 for not configured)");
}

TEST_F(LssProcedureTest, InquireNodeIdFFhIsUnconfigured) {
  call([](auto& p, auto t, auto& o) { return p.inquire_node_id(kDevice, t, o); });
  answer("7E4#4400000000000000", TimePoint{1ms});
  EXPECT_EQ(answer("7E4#5EFF000000000000", TimePoint{2ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].node_id, std::nullopt);
}

TEST_F(LssProcedureTest, SetBitRateConfiguresStoresAndActivatesThenWaitsTwiceTheDelay) {
  // 250 kbit/s: index 3 of table selector 0; switch delay 100 ms = 0064h.
  EXPECT_EQ(call([](auto& p, auto t, auto& o) {
              return p.set_bit_rate(*lss::bit_timing_index(250), true, 100, t, o);
            }),
            (Frames{"7E5#0401000000000000", "7E5#1300030000000000"}));
  EXPECT_EQ(answer("7E4#1300000000000000", TimePoint{1ms}), Frames{"7E5#1700000000000000"});
  EXPECT_EQ(answer("7E4#1700000000000000", TimePoint{2ms}), Frames{"7E5#1564000000000000"});
  EXPECT_EQ(procedure.next_deadline(), TimePoint{202ms});
  EXPECT_TRUE(tick(TimePoint{201ms}).empty());
  EXPECT_TRUE(events.empty());
  EXPECT_TRUE(tick(TimePoint{202ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].procedure, LssProcedureKind::SetBitRate);
  EXPECT_EQ(events[0].kind, Kind::Done);
}

TEST_F(LssProcedureTest, SetBitRateNotSupportedSwitchesBackToWaiting) {
  call([](auto& p, auto t, auto& o) { return p.set_bit_rate(0, false, 100, t, o); });
  EXPECT_EQ(answer("7E4#1301000000000000", TimePoint{1ms}), Frames{"7E5#0400000000000000"});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Failed);
  EXPECT_EQ(describe(events[0]),
            "configure bit timing: refused: bit rate not supported (error code 1)");
}

TEST_F(LssProcedureTest, AnyUnconfiguredSends4ChAndCountsAnAnswerWithinTheStep) {
  EXPECT_EQ(call([](auto& p, auto t, auto& o) { return p.any_unconfigured(t, o); }),
            Frames{"7E5#4C00000000000000"});
  EXPECT_TRUE(tick(TimePoint{10ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].found, 0u);
  call([](auto& p, auto t, auto& o) { return p.any_unconfigured(t, o); });
  answer("7E4#5000000000000000", TimePoint{12ms});
  tick(TimePoint{22ms});
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].kind, Kind::Done);
  EXPECT_EQ(events[1].found, 1u);
}

TEST_F(LssProcedureTest, ScanSwitchesAllToWaitingThenTheFastscanResetAndEndsOnItsSilence) {
  EXPECT_EQ(call([](auto& p, auto t, auto& o) { return p.scan({}, t, o); }),
            (Frames{"7E5#0400000000000000", "7E5#5100000000800000"}));
  EXPECT_EQ(procedure.next_deadline(), TimePoint{10ms});
  EXPECT_TRUE(tick(TimePoint{10ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].found, 0u);
  EXPECT_EQ(describe(events[0]), "scan: 0 unconfigured devices found");
}

// Scan with a known address (Execute LSS): kDevice's selection, 40h-43h without the 04h.
const Frames kSelect(kSelectDevice.begin() + 1, kSelectDevice.end());
const std::string kWaiting = "7E5#0400000000000000";
const std::string kIdentifyNonConfigured = "7E5#4C00000000000000";
const std::string kFastscanReset = "7E5#5100000000800000";

std::optional<cfg::NodeId> node_5(const LssAddress&) {
  return cfg::NodeId::from(5);
}

TEST_F(LssProcedureTest, ScanOfAKnownAddressSelectsItInquiresConfiguresStoresAndSwitchesBack) {
  EXPECT_EQ(call([](auto& p, auto t, auto& o) { return p.scan(node_5, t, o, {kDevice}); }),
            (Frames{kWaiting, kIdentifyNonConfigured}));
  // 50h: a device without node-ID is there; the scan step ends the identify service.
  EXPECT_TRUE(answer("7E4#5000000000000000", TimePoint{1ms}).empty());
  EXPECT_EQ(tick(TimePoint{11ms}), kSelect);
  EXPECT_EQ(procedure.next_deadline(), TimePoint{111ms});  // the LSS timeout, one answer
  EXPECT_EQ(answer("7E4#4400000000000000", TimePoint{12ms}), Frames{"7E5#5E00000000000000"});
  EXPECT_EQ(answer("7E4#5EFF000000000000", TimePoint{13ms}), Frames{"7E5#1105000000000000"});
  EXPECT_EQ(answer("7E4#1100000000000000", TimePoint{14ms}), Frames{"7E5#1700000000000000"});
  // Stored: back to waiting (it starts with node-ID 5), then the Fastscan reset asks whether
  // any unconfigured device is left.
  EXPECT_EQ(answer("7E4#1700000000000000", TimePoint{15ms}), (Frames{kWaiting, kFastscanReset}));
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Assigned);
  EXPECT_EQ(events[0].address, kDevice);
  EXPECT_EQ(events[0].node_id, cfg::NodeId::from(5));
  EXPECT_EQ(events[0].outcome, LssScanOutcome::Stored);
  EXPECT_TRUE(tick(TimePoint{25ms}).empty());
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].kind, Kind::Done);
  EXPECT_EQ(events[1].found, 1u);
}

TEST_F(LssProcedureTest, ScanOfKnownAddressesEndsOnTheSilenceOfIdentifyNonConfigured) {
  // Every device has a node-ID (a second push): no selection at all.
  EXPECT_EQ(call([](auto& p, auto t, auto& o) { return p.scan(node_5, t, o, {kDevice}); }),
            (Frames{kWaiting, kIdentifyNonConfigured}));
  EXPECT_TRUE(tick(TimePoint{10ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].found, 0u);
}

TEST_F(LssProcedureTest, KnownAddressOfAConfiguredDeviceIsSwitchedBackWithoutAConfigure) {
  call([](auto& p, auto t, auto& o) { return p.scan(node_5, t, o, {kDevice}); });
  answer("7E4#5000000000000000", TimePoint{1ms});  // another device has no node-ID
  EXPECT_EQ(tick(TimePoint{11ms}), kSelect);
  EXPECT_EQ(answer("7E4#4400000000000000", TimePoint{12ms}), Frames{"7E5#5E00000000000000"});
  // Node-ID 9: it is left as it is; the targets done, the Fastscan search for the rest.
  EXPECT_EQ(answer("7E4#5E09000000000000", TimePoint{13ms}), (Frames{kWaiting, kFastscanReset}));
  EXPECT_TRUE(events.empty());
}

TEST_F(LssProcedureTest, UnansweredSelectionFallsBackToTheFastscanConfirmationAfterTheTimeout) {
  call([](auto& p, auto t, auto& o) { return p.scan(node_5, t, o, {kDevice}); });
  answer("7E4#5000000000000000", TimePoint{1ms});
  EXPECT_EQ(tick(TimePoint{11ms}), kSelect);
  EXPECT_TRUE(tick(TimePoint{110ms}).empty());
  // One LSS timeout; then every device to waiting and the confirmation, the reset first.
  EXPECT_EQ(tick(TimePoint{111ms}), (Frames{kWaiting, kFastscanReset}));
  EXPECT_EQ(answer("7E4#4F00000000000000", TimePoint{112ms}), Frames{});
  // The reset was answered: the vendor-ID with BitCheck 0, LSSSub 0, LSSNext 1.
  EXPECT_EQ(tick(TimePoint{122ms}), Frames{"7E5#51DEC0577E000001"});
  // Unanswered: the target is absent; no target left, so the search for the rest.
  EXPECT_EQ(tick(TimePoint{132ms}), Frames{kFastscanReset});
  EXPECT_TRUE(tick(TimePoint{142ms}).empty());
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].found, 0u);
}

TEST_F(LssProcedureTest, OneProcedureAtATimeAndABusyStartSaysWhyAndSendsNothing) {
  call([](auto& p, auto t, auto& o) { return p.find_unconfigured(t, o); });
  LssProcedure::Output out;
  const cfg::Status started = procedure.set_bit_rate(0, true, 100, now, out);
  ASSERT_FALSE(started.ok());
  EXPECT_EQ(started.error().message,
            "LSS set bit rate not started: find unconfigured devices runs (one LSS procedure at a "
            "time)");
  EXPECT_TRUE(out.empty());
}

// --- procedures against slaves on the simulated bus --------------------------------------------

class LssProcedureBus : public lss_test::LssBusTest<LssProcedure> {
 protected:
  // Devices of one product (the usual case: a batch of new drives) with random serial numbers.
  std::vector<LssAddress> add_random(int n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    auto draw = [&rng] { return static_cast<std::uint32_t>(rng()); };
    std::set<LssAddress> made;
    while (static_cast<int>(made.size()) < n) {
      made.insert(LssAddress{0x0000019A, 0x00020001, 0x00010000 + draw() % 3, draw()});
    }
    for (const auto& a : made) add(a);
    return {made.begin(), made.end()};
  }
  // Scans with node-IDs 1, 2, ... in the order devices are found.
  std::vector<LssProcedureEvent> scan_all() {
    std::uint8_t next = 1;
    start([&](auto& m, auto t, auto& o) {
      return m.scan([&next](const LssAddress&) { return cfg::NodeId::from(next++); }, t, o);
    });
    run_until_done();
    return events;
  }
  void expect_all_configured(const std::vector<LssAddress>& addresses) {
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.back().procedure, LssProcedureKind::Scan);
    EXPECT_EQ(events.back().kind, Kind::Done);
    EXPECT_EQ(events.back().found, addresses.size());
    std::vector<LssAddress> found;
    std::map<LssAddress, std::uint8_t> node_ids;  // the slaves' raw node-IDs (lss_slave.hpp)
    for (const auto& e : events) {
      if (e.kind != Kind::Assigned) continue;
      found.push_back(e.address);
      node_ids[e.address] = e.node_id.value();
    }
    // Every device once, lowest LSS address first (Fastscan finds the lowest).
    EXPECT_EQ(found, addresses);
    for (const auto& s : slaves) {
      const auto& slave = s->engine();
      EXPECT_EQ(slave.active_node_id(), node_ids[slave.address()]) << to_string(slave.address());
      EXPECT_EQ(slave.state(), LssState::Waiting);
    }
  }
};

// N devices of one product with random serial numbers (the seed is N).
class LssProcedureScanOfRandomDevices : public LssProcedureBus,
                                        public ::testing::WithParamInterface<int> {};

TEST_P(LssProcedureScanOfRandomDevices, ConfiguresEachOnceLowestAddressFirstIn136RequestsEach) {
  const int n = GetParam();
  auto addresses = add_random(n, static_cast<std::uint32_t>(n));
  int requests = 0;
  bus.add_observer([&](const CanFrame& f, TimePoint) { requests += f.id == lss::kMasterCobId; });
  scan_all();
  expect_all_configured(addresses);
  // Per device: the Fastscan reset, 4 x (32 bit queries + confirmation), configure node-ID,
  // store configuration, switch state global; before them the switch of all devices to
  // waiting, after them the reset nobody answers.
  EXPECT_EQ(requests, 1 + n * (1 + 4 * 33 + 3) + 1);
}

INSTANTIATE_TEST_SUITE_P(OneTwoTenFifty, LssProcedureScanOfRandomDevices,
                         ::testing::Values(1, 2, 10, 50),
                         [](const ::testing::TestParamInfo<int>& param) {
                           return std::to_string(param.param) + "Devices";
                         });

TEST_F(LssProcedureBus, ScanTellsApartTwoDevicesWhoseAddressesDifferInOneBit) {
  // Serial numbers 0x5A5A0F0F and 0x5A5A0F0E: only bit 0 differs; likewise bit 31 of two
  // revisions.
  const LssAddress a{0x0000019A, 0x00020001, 0x00010000, 0x5A5A0F0E};
  const LssAddress b{0x0000019A, 0x00020001, 0x00010000, 0x5A5A0F0F};
  const LssAddress c{0x0000019A, 0x00020001, 0x80010000, 0x5A5A0F0E};
  add(c);
  add(b);
  add(a);
  scan_all();
  expect_all_configured({a, b, c});
}

TEST_F(LssProcedureBus, ScanLooksPastADeviceItGivesNoNodeId) {
  auto addresses = add_random(6, 6);
  std::set<LssAddress> skip{addresses[0], addresses[3]};
  std::uint8_t next = 1;
  start([&](auto& m, auto t, auto& o) {
    return m.scan(
        [&](const LssAddress& a) -> std::optional<cfg::NodeId> {
          if (skip.count(a) != 0) return std::nullopt;
          return cfg::NodeId::from(next++);
        },
        t, o);
  });
  run_until_done();
  std::vector<LssAddress> skipped;
  std::vector<LssAddress> assigned;
  for (const auto& e : events) {
    if (e.kind == Kind::Skipped) skipped.push_back(e.address);
    if (e.kind == Kind::Assigned) assigned.push_back(e.address);
  }
  EXPECT_EQ(skipped, (std::vector<LssAddress>{addresses[0], addresses[3]}));
  EXPECT_EQ(assigned,
            (std::vector<LssAddress>{addresses[1], addresses[2], addresses[4], addresses[5]}));
  EXPECT_EQ(events.back().found, 6u);
  for (const auto& s : slaves) {
    EXPECT_EQ(s->engine().configured(), skip.count(s->engine().address()) == 0);
  }
}

TEST_F(LssProcedureBus, ScanLeavesTwoDevicesWithOneLssAddressUnconfiguredAndFindsTheOthers) {
  // CiA 305 takes LSS addresses to be unique; two devices with one answer configure node-ID
  // twice: FFh is configured and stored in both, the address Skipped, the others configured.
  const LssAddress twin{0x0000019A, 0x00020001, 0x00010000, 0x00000005};
  const LssAddress other{0x0000019A, 0x00020001, 0x00010000, 0x00000009};
  for (const LssAddress& address : {twin, twin, other}) add(address);
  scan_all();
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0].kind, Kind::Skipped);
  EXPECT_EQ(events[0].address, twin);
  EXPECT_EQ(events[0].outcome, LssScanOutcome::Duplicate);
  EXPECT_NE(
      describe(events[0]).find("more than one device answered configure node-ID with this LSS "
                               "address"),
      std::string::npos)
      << describe(events[0]);
  EXPECT_EQ(events[1].kind, Kind::Assigned);
  EXPECT_EQ(events[1].address, other);
  EXPECT_EQ(events[2].kind, Kind::Done);
  EXPECT_EQ(events[2].found, 2u);
  EXPECT_EQ(slaves[0]->engine().active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(slaves[1]->engine().active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(slaves[2]->engine().active_node_id(), 2);  // node-ID 1 went to the twins, undone
}

TEST_F(LssProcedureBus, ScanFirstSwitchesADeviceLeftInConfigurationBackToWaiting) {
  auto& bystander = add({0x0000019A, 0x00020001, 0x00010000, 0x00000001}, 9);
  LssSlave::Output ignored;
  bystander.engine().on_frame(*from_candump("7E5#0401000000000000"), TimePoint{}, ignored);
  ASSERT_EQ(bystander.engine().state(), LssState::Configuration);
  auto addresses = std::vector<LssAddress>{{0x0000019A, 0x00020001, 0x00010000, 0x00000002}};
  add(addresses[0]);
  scan_all();
  EXPECT_EQ(bystander.engine().pending_node_id(), 9);  // the node-ID 1 went to the new device
  EXPECT_EQ(slaves[1]->engine().active_node_id(), 1);
}

TEST_F(LssProcedureBus, FindUnconfiguredListsEveryDeviceWithoutNodeIdAndAssignsNothing) {
  auto addresses = add_random(5, 5);
  add({0x0000019A, 0x00020001, 0x00010000, 0x00000001}, 9);  // configured: does not answer
  Frames requests;
  bus.add_observer([&](const CanFrame& f, TimePoint) {
    if (f.id == lss::kMasterCobId) requests.push_back(to_candump(f));
  });
  start([](auto& m, auto t, auto& o) { return m.find_unconfigured(t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].procedure, LssProcedureKind::FindUnconfigured);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].addresses, addresses);  // ascending: Fastscan finds the lowest first
  EXPECT_EQ(events[0].found, 5u);
  for (std::size_t i = 0; i < addresses.size(); ++i) {
    EXPECT_EQ(slaves[i]->engine().active_node_id(), lss::kUnconfigured);
    EXPECT_EQ(slaves[i]->engine().state(), LssState::Waiting);
  }

  // The same requests as the services one by one: switch state global to waiting, then
  // Fastscan above the last device found and back to waiting, until Fastscan finds none.
  SimBus twin_bus{500'000};
  SimEngineNode<LssMaster> twin;
  twin_bus.attach(twin);
  std::vector<std::unique_ptr<SimEngineNode<LssSlave>>> twin_slaves;
  for (const auto& s : slaves) {
    twin_slaves.push_back(std::make_unique<SimEngineNode<LssSlave>>(s->engine().address(),
                                                                    s->engine().active_node_id()));
    twin_bus.attach(*twin_slaves.back());
  }
  Frames twin_requests;
  twin_bus.add_observer([&](const CanFrame& f, TimePoint) {
    if (f.id == lss::kMasterCobId) twin_requests.push_back(to_candump(f));
  });
  std::optional<LssMasterEvent> last;
  twin.set_event_handler([&](const LssMasterEvent& e, TimePoint) { last = e; });
  const auto run = [&](auto fn) {
    ASSERT_TRUE(twin.apply(fn).ok());
    ASSERT_TRUE(twin_bus.run_until([&] { return !twin.engine().busy(); }, TimePoint{3600s}));
  };
  const auto to_waiting = [](auto& m, auto t, auto& o) {
    return m.switch_state_global(LssState::Waiting, t, o);
  };
  run(to_waiting);
  std::optional<LssAddress> after;
  for (;;) {
    run([&](auto& m, auto t, auto& o) { return m.fastscan(after, t, o); });
    if (last->kind != LssMasterEvent::Kind::Done) break;
    after = last->address;
    run(to_waiting);
  }
  EXPECT_EQ(requests, twin_requests);
}

TEST_F(LssProcedureBus, FindProductListsConfiguredAndUnconfiguredDevicesOfThatProductOnly) {
  const LssAddress a{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
  const LssAddress b{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001003};
  add(b);
  add(a, 7);
  add({0x7E57C0DE, 0x00000306, 0x00010002, 0x00001002});  // another product
  start([](auto& m, auto t, auto& o) { return m.find_product(0x7E57C0DE, 0x305, t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done);
  EXPECT_EQ(events[0].addresses, (std::vector<LssAddress>{a, b}));
}

TEST_F(LssProcedureBus, AssignNodeIdGivesTheSelectedDeviceItsNodeIdAndLeavesTheOthers) {
  const LssAddress a{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
  auto& device = add(a);
  auto& other = add({0x7E57C0DE, 0x00000305, 0x00010002, 0x00001003});
  start([&](auto& m, auto t, auto& o) {
    return m.assign_node_id(a, cfg::NodeId::from(5), true, t, o);
  });
  run_until_done();
  bus.run_for(10ms);  // the switch back to waiting, sent as the procedure ended, has no answer
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Done) << describe(events[0]);
  EXPECT_EQ(events[0].previous_node_id, lss::kUnconfigured);
  // Unconfigured before, so back in waiting it starts with the new node-ID.
  EXPECT_EQ(device.engine().active_node_id(), 5);
  EXPECT_EQ(device.engine().state(), LssState::Waiting);
  EXPECT_EQ(other.engine().active_node_id(), lss::kUnconfigured);
  events.clear();
  start([&](auto& m, auto t, auto& o) { return m.inquire_node_id(a, t, o); });
  run_until_done();
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].node_id, cfg::NodeId::from(5));
}

}  // namespace
}  // namespace nmt
