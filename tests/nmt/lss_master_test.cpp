// LSS master (CiA 305): each service's request bytes and its reading of the answers, written out
// by hand from the layouts nmt/lss.hpp cites (CANopenNode 305/CO_LSS.h, lely-core src/co/lss.c);
// then the master against LSS slaves on the simulated bus in simulated time: Fastscan and the
// scan of many unconfigured devices, a device that never answers, a refused configure node-ID.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "nmt/lss_master.hpp"
#include "nmt/lss_slave.hpp"
#include "nmt/sim_bus.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Frames = std::vector<std::string>;
using Kind = LssMasterEvent::Kind;

class LssMasterTest : public ::testing::Test {
 protected:
  LssMaster master;
  TimePoint now{};
  std::vector<LssMasterEvent> events;

  Frames take(LssMaster::Output& out) {
    for (auto& e : out.events) events.push_back(e);
    Frames frames;
    for (auto& f : out.frames) frames.push_back(to_candump(f));
    out.clear();
    return frames;
  }
  // Starts a service that must start (engine.hpp rule 5: a start that fails says why).
  template <class Fn>
  Frames call(Fn fn) {
    LssMaster::Output out;
    const cfg::Status started = fn(master, now, out);
    EXPECT_TRUE(started.ok()) << started.error().message;
    return take(out);
  }
  Frames answer(std::string_view candump, bool expect_taken = true) {
    LssMaster::Output out;
    EXPECT_EQ(master.on_frame(*from_candump(candump), now, out), expect_taken) << candump;
    return take(out);
  }
  Frames tick(TimePoint t) {
    now = t;
    LssMaster::Output out;
    master.on_timer(now, out);
    return take(out);
  }
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
  EXPECT_EQ(events[0].text, "configure node-ID: refused: node-ID out of range (error code 1)");
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
  EXPECT_EQ(events[0].text, "configure bit timing: refused: bit rate not supported (error code 1)");
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
  EXPECT_EQ(events[0].text,
            "store configuration: refused: storage media access error (error code 2)");
  EXPECT_EQ(events[1].text,
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

TEST_F(LssMasterTest, NoAnswerWithinTheTimeoutIsATimeoutEvent) {
  call([](auto& m, auto t, auto& o) { return m.configure_node_id(cfg::NodeId::from(5), t, o); });
  EXPECT_TRUE(tick(TimePoint{99ms}).empty());
  EXPECT_TRUE(events.empty());
  tick(TimePoint{100ms});
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Kind::Timeout);
  EXPECT_EQ(events[0].text, "configure node-ID: no answer within 100 ms");
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

class LssBus : public ::testing::Test {
 protected:
  SimBus bus{500'000};
  SimEngineNode<LssMaster> master;
  std::vector<std::unique_ptr<SimEngineNode<LssSlave>>> slaves;
  std::vector<LssMasterEvent> events;

  LssBus() {
    bus.attach(master);
    master.set_event_handler([this](const LssMasterEvent& e, TimePoint) { events.push_back(e); });
  }
  SimEngineNode<LssSlave>& add(LssAddress address, std::uint8_t node_id = lss::kUnconfigured) {
    auto node = std::make_unique<SimEngineNode<LssSlave>>(address, node_id);
    auto* raw = node.get();
    // The owner's part: a device that got its node-ID starts with it.
    raw->set_event_handler([raw](const LssSlaveEvent& e, TimePoint) {
      if (e.kind == LssSlaveEvent::Kind::NodeIdActivate) {
        raw->engine().activate_pending_node_id();
      }
    });
    bus.attach(*raw);
    slaves.push_back(std::move(node));
    return *raw;
  }
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
  // Starts a service that must start (engine.hpp rule 5: a start that fails says why).
  template <class Fn>
  void start(Fn fn) {
    const cfg::Status started = master.apply(fn);
    EXPECT_TRUE(started.ok()) << started.error().message;
  }
  void run_until_done() {
    ASSERT_TRUE(bus.run_until([this] { return !master.engine().busy(); }, TimePoint{3600s}));
  }
  // Scans with node-IDs 1, 2, ... in the order devices are found.
  std::vector<LssMasterEvent> scan_all() {
    std::uint8_t next = 1;
    start([&](auto& m, auto t, auto& o) {
      return m.scan([&next](const LssAddress&) { return cfg::NodeId::from(next++); }, t, o);
    });
    run_until_done();
    return events;
  }
  void expect_all_configured(const std::vector<LssAddress>& addresses) {
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.back().service, LssService::Scan);
    EXPECT_EQ(events.back().kind, Kind::Done);
    EXPECT_EQ(events.back().value, addresses.size());
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

TEST_F(LssBus, ScanConfiguresOneUnconfiguredDevice) {
  auto addresses = add_random(1, 1);
  scan_all();
  expect_all_configured(addresses);
}

TEST_F(LssBus, ScanConfiguresTwoDevices) {
  auto addresses = add_random(2, 2);
  scan_all();
  expect_all_configured(addresses);
}

TEST_F(LssBus, ScanTellsApartTwoDevicesWhoseAddressesDifferInOneBit) {
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

TEST_F(LssBus, ScanConfiguresTenDevicesWithRandomSerialNumbers) {
  auto addresses = add_random(10, 10);
  scan_all();
  expect_all_configured(addresses);
}

TEST_F(LssBus, ScanConfiguresFiftyDevicesWithRandomSerialNumbers) {
  auto addresses = add_random(50, 50);
  int requests = 0;
  bus.add_observer([&](const CanFrame& f, TimePoint) { requests += f.id == lss::kMasterCobId; });
  scan_all();
  expect_all_configured(addresses);
  // Per device: the Fastscan reset, 4 x (32 bit queries + confirmation), configure node-ID,
  // store configuration, switch state global; before them the switch of all devices to
  // waiting, after them the reset nobody answers.
  EXPECT_EQ(requests, 1 + 50 * (1 + 4 * 33 + 3) + 1);
}

TEST_F(LssBus, ScanLooksPastADeviceItGivesNoNodeId) {
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
  EXPECT_EQ(events.back().value, 6u);
  for (const auto& s : slaves) {
    EXPECT_EQ(s->engine().configured(), skip.count(s->engine().address()) == 0);
  }
}

TEST_F(LssBus, ScanLeavesTwoDevicesWithOneLssAddressUnconfiguredAndFindsTheOthers) {
  // CiA 305 takes LSS addresses to be unique; two devices with one answer configure node-ID
  // twice: FFh is configured and stored in both, the address Skipped, the others configured.
  const LssAddress twin{0x0000019A, 0x00020001, 0x00010000, 0x00000005};
  const LssAddress other{0x0000019A, 0x00020001, 0x00010000, 0x00000009};
  for (const LssAddress& address : {twin, twin, other}) add(address);
  scan_all();
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0].kind, Kind::Skipped);
  EXPECT_EQ(events[0].address, twin);
  EXPECT_NE(events[0].text.find("more than one device answered configure node-ID with this LSS "
                                "address"),
            std::string::npos)
      << events[0].text;
  EXPECT_EQ(events[1].kind, Kind::Assigned);
  EXPECT_EQ(events[1].address, other);
  EXPECT_EQ(events[2].kind, Kind::Done);
  EXPECT_EQ(events[2].value, 2u);
  EXPECT_EQ(slaves[0]->engine().active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(slaves[1]->engine().active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(slaves[2]->engine().active_node_id(), 2);  // node-ID 1 went to the twins, undone
}

TEST_F(LssBus, ScanFirstSwitchesADeviceLeftInConfigurationBackToWaiting) {
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
  for (const auto& e : events) EXPECT_EQ(e.kind, Kind::Done) << e.text;
  EXPECT_EQ(events[3].value, 0xCAFEBABEu);
  EXPECT_EQ(events[4].value, 3u);  // the active node-ID; 42 is pending until reset
  EXPECT_EQ(stored, std::vector<std::string>{"LSS: store node-ID 42"});
}

}  // namespace
}  // namespace nmt
