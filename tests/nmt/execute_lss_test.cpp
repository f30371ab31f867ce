// Execute LSS (master/execute_lss.hpp): DSP 302 §4 figure 1 step 3 and CiA 302-2 §3.1 c, with
// CiA 305's bytes as nmt/lss/lss.hpp cites them (CANopenNode 305/CO_LSS.h, lely-core src/co/lss.c):
// 04h switch state global (byte 1: 0 waiting), 51h Fastscan (IDNumber bytes 1-4, BitCheck byte
// 5, LSSSub byte 6, LSSNext byte 7; BitCheck 80h: every unconfigured device answers 4Fh), 11h
// configure node-ID (byte 1) answered 11h with the error code in byte 1, 17h store configuration
// answered 17h, 4Ch identify non-configured remote slave answered 50h.
// First the engine alone with a fake port (frame by frame, simulated time), then against LSS
// slaves on the simulated bus, then composed into the NMT master with SlaveNode devices that
// power on unconfigured.
#include "master/execute_lss.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using namespace cfg::literals;
using Frames = std::vector<std::string>;
using Kind = MasterEvent::Kind;
using Phase = ExecuteLssProcess::Phase;

// sim_device.eds: vendor 7E57C0DEh, product 00000508h, revision 00020001h.
LssAddress sim_address(std::uint32_t serial) {
  return {0x7E57C0DE, 0x00000508, 0x00020001, serial};
}

struct FakePort final : ExecuteLssPort {
  std::optional<cfg::NodeId> slave_with(const LssAddress& address) const override {
    for (const auto& [node, a] : slaves) {
      if (a == address) return cfg::NodeId::from(node);
    }
    return std::nullopt;
  }
  std::vector<LssAddress> known_addresses() const override {
    std::vector<LssAddress> known;
    for (const auto& [node, a] : slaves) known.push_back(a);
    return known;
  }
  void pass_ended(TimePoint now, Output& /*out*/) override { ended_at.push_back(now); }
  bool may_look() const override { return looking; }

  std::map<std::uint8_t, LssAddress> slaves;
  std::vector<TimePoint> ended_at;
  bool looking = true;
};

std::vector<std::string> texts(const std::vector<MasterEvent>& events, Kind kind) {
  std::vector<std::string> found;
  for (const auto& e : events) {
    if (e.kind == kind) found.push_back(describe(e));
  }
  return found;
}

// --- the engine alone, frame by frame ------------------------------------------------------------

class ExecuteLssEngine : public ::testing::Test {
 protected:
  FakePort port;
  ExecuteLssProcess process{port, LssMasterOptions{}, 1s};  // 100 ms timeout, 10 ms step
  std::vector<MasterEvent> events;

  Frames take(ExecuteLssProcess::Output& out) {
    for (auto& e : out.events) events.push_back(e);
    Frames frames;
    for (auto& f : out.frames) frames.push_back(to_candump(f));
    out.clear();
    return frames;
  }
  Frames start(TimePoint now) {
    ExecuteLssProcess::Output out;
    process.start(now, out);
    return take(out);
  }
  Frames tick(TimePoint now) {
    ExecuteLssProcess::Output out;
    process.on_timer(now, out);
    return take(out);
  }
  Frames answer(std::string_view candump, TimePoint now) {
    ExecuteLssProcess::Output out;
    EXPECT_TRUE(process.on_frame(*from_candump(candump), now, out)) << candump;
    return take(out);
  }
};

TEST_F(ExecuteLssEngine, StartupPassSwitchesAllToWaitingAndEndsAfterOneSilentFastscanStep) {
  EXPECT_EQ(start(TimePoint{}), (Frames{"7E5#0400000000000000", "7E5#5100000000800000"}));
  EXPECT_EQ(process.phase(), Phase::Startup);
  EXPECT_EQ(process.next_deadline(), TimePoint{10ms});
  EXPECT_TRUE(tick(TimePoint{9ms}).empty());
  EXPECT_TRUE(port.ended_at.empty());
  EXPECT_TRUE(tick(TimePoint{10ms}).empty());
  EXPECT_EQ(port.ended_at, std::vector<TimePoint>{TimePoint{10ms}});
  EXPECT_EQ(texts(events, Kind::LssScanEnded),
            Frames{"LSS: 0 unconfigured devices found, 0 given a node-ID"});
  // The period (1 s) runs from the end of the pass.
  EXPECT_EQ(process.phase(), Phase::Idle);
  EXPECT_EQ(process.next_deadline(), TimePoint{1010ms});
}

TEST_F(ExecuteLssEngine, WatchSendsIdentifyNonConfiguredEachPeriodAndScansOnlyWhenAnswered) {
  start(TimePoint{});
  tick(TimePoint{10ms});
  EXPECT_TRUE(tick(TimePoint{1009ms}).empty());
  EXPECT_EQ(tick(TimePoint{1010ms}), Frames{"7E5#4C00000000000000"});
  EXPECT_EQ(process.phase(), Phase::Probe);
  // Nobody answers within the Fastscan step: the next look one period later.
  EXPECT_TRUE(tick(TimePoint{1020ms}).empty());
  EXPECT_EQ(process.phase(), Phase::Idle);
  EXPECT_EQ(process.next_deadline(), TimePoint{2010ms});
  // A device answers 50h: a scan (switch to waiting, Fastscan reset) after the step.
  EXPECT_EQ(tick(TimePoint{2010ms}), Frames{"7E5#4C00000000000000"});
  EXPECT_TRUE(answer("7E4#5000000000000000", TimePoint{2011ms}).empty());
  EXPECT_EQ(tick(TimePoint{2021ms}), (Frames{"7E5#0400000000000000", "7E5#5100000000800000"}));
  EXPECT_EQ(process.phase(), Phase::Scan);
  // Not the start-up pass: its end does not continue the start-up again.
  tick(TimePoint{2031ms});
  EXPECT_EQ(port.ended_at.size(), 1u);
  EXPECT_EQ(process.phase(), Phase::Idle);
}

TEST_F(ExecuteLssEngine, NoLookWhileThisDeviceIsNotTheActiveMaster) {
  start(TimePoint{});
  tick(TimePoint{10ms});
  port.looking = false;
  EXPECT_TRUE(tick(TimePoint{1010ms}).empty());
  EXPECT_EQ(process.next_deadline(), TimePoint{2010ms});
}

TEST_F(ExecuteLssEngine, StopAbandonsTheScanAndItsAnswersAreNotTaken) {
  start(TimePoint{});
  process.stop();
  EXPECT_EQ(process.phase(), Phase::Off);
  EXPECT_EQ(process.next_deadline(), std::nullopt);
  ExecuteLssProcess::Output out;
  EXPECT_FALSE(process.on_frame(*from_candump("7E4#4F00000000000000"), TimePoint{1ms}, out));
  EXPECT_TRUE(out.empty());
}

// --- the engine against LSS slaves on the simulated bus -------------------------------------

// An unconfigured LSS device that refuses every configure node-ID with error code 1 (CiA 305:
// node-ID out of range; a device may accept less than 1..127), a test fault wrapper of the
// engine shape (engine.hpp rule 7) around an LssSlave.
struct RefusesNodeId {
  using Event = LssSlaveEvent;
  using Output = LssSlave::Output;
  explicit RefusesNodeId(LssAddress address) : slave(address, lss::kUnconfigured) {}
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out) {
    if (lss::is_lss_frame(frame, lss::kMasterCobId) &&
        frame.data[0] == static_cast<std::uint8_t>(lss::Cs::ConfigureNodeId) &&
        slave.state() == LssState::Configuration) {
      out.send(*from_candump("7E4#1101000000000000"));
      return true;
    }
    return slave.on_frame(frame, now, out);
  }
  void on_timer(TimePoint now, Output& out) { slave.on_timer(now, out); }
  std::optional<TimePoint> next_deadline() const { return slave.next_deadline(); }
  LssSlave slave;
};
static_assert(Engine<RefusesNodeId>);

class ExecuteLssBus : public ::testing::Test {
 protected:
  SimBus bus{500'000};
  FakePort port;
  SimEngineNode<ExecuteLssProcess> process{port, LssMasterOptions{}, Duration{0}};
  std::vector<std::unique_ptr<SimEngineNode<LssSlave>>> devices;
  std::vector<std::unique_ptr<SimEngineNode<RefusesNodeId>>> refusing;
  std::vector<MasterEvent> events;
  Frames frames;

  ExecuteLssBus() {
    bus.attach(process);
    process.set_event_handler([this](const MasterEvent& e, TimePoint) { events.push_back(e); });
    bus.add_observer([this](const CanFrame& f, TimePoint) { frames.push_back(to_candump(f)); });
  }
  LssSlave& add(LssAddress address) {
    auto node = std::make_unique<SimEngineNode<LssSlave>>(address, lss::kUnconfigured);
    auto* raw = node.get();
    raw->set_event_handler([raw](const LssSlaveEvent& e, TimePoint) {
      if (e.kind == LssSlaveEvent::Kind::NodeIdActivate) raw->engine().activate_pending_node_id();
    });
    bus.attach(*raw);
    devices.push_back(std::move(node));
    return raw->engine();
  }
  LssSlave& add_refusing(LssAddress address) {
    refusing.push_back(std::make_unique<SimEngineNode<RefusesNodeId>>(address));
    bus.attach(*refusing.back());
    return refusing.back()->engine().slave;
  }
  // The first event of `kind`, or nullptr.
  const MasterEvent* event_of(Kind kind) const {
    const auto e = std::find_if(events.begin(), events.end(),
                                [kind](const MasterEvent& m) { return m.kind == kind; });
    return e == events.end() ? nullptr : &*e;
  }
  void run_pass() {
    process.apply([](auto& p, TimePoint now, auto& out) {
      p.start(now, out);
      return true;
    });
    ASSERT_TRUE(bus.run_until([this] { return !port.ended_at.empty(); }, TimePoint{60s}));
  }
};

TEST_F(ExecuteLssBus, FoundDeviceGetsItsSlavesNodeIdStoredThenBackToWaiting) {
  port.slaves[5] = sim_address(0xCAFEBABE);
  auto& device = add(sim_address(0xCAFEBABE));
  run_pass();
  EXPECT_EQ(device.active_node_id(), 5);
  EXPECT_EQ(device.state(), LssState::Waiting);
  // After its selection (the serial number in 43h, answered 44h) and inquire node-ID (FFh):
  // configure node-ID 5, its answer (error code 0), store, its answer, back to waiting, and
  // the Fastscan reset that looks for devices left over.
  const auto selected = std::find(frames.begin(), frames.end(), "7E5#43BEBAFECA000000");
  ASSERT_NE(selected, frames.end());
  EXPECT_EQ(Frames(selected, frames.end()),
            (Frames{"7E5#43BEBAFECA000000", "7E4#4400000000000000", "7E5#5E00000000000000",
                    "7E4#5EFF000000000000", "7E5#1105000000000000", "7E4#1100000000000000",
                    "7E5#1700000000000000", "7E4#1700000000000000", "7E5#0400000000000000",
                    "7E5#5100000000800000"}));
  ASSERT_EQ(texts(events, Kind::LssAssigned).size(), 1u);
  const MasterEvent* assigned = event_of(Kind::LssAssigned);
  ASSERT_NE(assigned, nullptr);
  EXPECT_EQ(assigned->node_id, 5);
  EXPECT_EQ(assigned->lss_address, sim_address(0xCAFEBABE));
  // Store configuration answered 0 (CiA 305 §8.3.4): stored.
  ASSERT_TRUE(assigned->lss.has_value());
  EXPECT_EQ(assigned->lss->outcome, LssScanOutcome::Stored);
  EXPECT_EQ(texts(events, Kind::LssScanEnded),
            Frames{"LSS: 1 unconfigured device found, 1 given a node-ID"});
  const MasterEvent* ended = event_of(Kind::LssScanEnded);
  ASSERT_NE(ended, nullptr);
  ASSERT_TRUE(ended->lss_scan.has_value());
  EXPECT_EQ(ended->lss_scan->found, 1U);
  EXPECT_EQ(ended->lss_scan->assigned, 1U);
  EXPECT_EQ(ended->lss_scan->stopped, MasterEvent::LssScan::Stop::None);
}

TEST_F(ExecuteLssBus, DeviceMatchingNoSlaveIsReportedWithItsAddressAndLeftUnconfigured) {
  port.slaves[5] = sim_address(1);
  auto& stranger = add(sim_address(0x00000063));
  run_pass();
  EXPECT_EQ(stranger.active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(stranger.state(), LssState::Waiting);
  EXPECT_EQ(texts(events, Kind::LssUnmatched),
            Frames{"LSS: unconfigured device 7E57C0DE:00000508:00020001:00000063 matches no "
                   "slave: left unconfigured"});
  EXPECT_TRUE(texts(events, Kind::LssAssigned).empty());
  // No configure node-ID was sent at all.
  EXPECT_EQ(std::count_if(frames.begin(), frames.end(),
                          [](auto& f) { return f.rfind("7E5#11", 0) == 0; }),
            0);
}

TEST_F(ExecuteLssBus, TwoDevicesWithOneLssAddressAreReportedWithTheAddressAndLeftUnconfigured) {
  port.slaves[7] = sim_address(42);
  auto& first = add(sim_address(42));
  auto& second = add(sim_address(42));
  run_pass();
  // CiA 305 takes LSS addresses to be unique. Both devices answer each Fastscan step alike and
  // are in configuration together; the second answer to configure node-ID tells: FFh (not
  // configured) is configured and stored in both, and the slave's LssFailed names the address.
  EXPECT_TRUE(texts(events, Kind::LssAssigned).empty());
  EXPECT_EQ(texts(events, Kind::LssFailed),
            Frames{"node 7: LSS: vendor 7E57C0DEh product 00000508h revision 00020001h serial "
                   "0000002Ah left unconfigured: more than one device answered configure node-ID "
                   "with this LSS address (CiA 305 takes LSS addresses to be unique)"});
  const MasterEvent* failed = event_of(Kind::LssFailed);
  ASSERT_NE(failed, nullptr);
  EXPECT_EQ(failed->lss_address, sim_address(42));
  ASSERT_TRUE(failed->lss.has_value());
  EXPECT_EQ(failed->lss->outcome, LssScanOutcome::Duplicate);
  for (const LssSlave* d : {&first, &second}) {
    EXPECT_EQ(d->active_node_id(), lss::kUnconfigured);
    EXPECT_EQ(d->pending_node_id(), lss::kUnconfigured);
    EXPECT_EQ(d->state(), LssState::Waiting);
  }
  // After configure node-ID 7 and store: configure FFh, store, back to waiting.
  const auto undo = std::find(frames.begin(), frames.end(), "7E5#11FF000000000000");
  ASSERT_NE(undo, frames.end());
  EXPECT_EQ(std::count(undo, frames.end(), "7E5#1700000000000000"), 1);
  EXPECT_EQ(texts(events, Kind::LssScanEnded),
            Frames{"LSS: 1 unconfigured device found, 0 given a node-ID"});
}

TEST_F(ExecuteLssBus, RefusedConfigureNodeIdIsTheSlavesLssFailure) {
  port.slaves[9] = sim_address(3);
  auto& device = add_refusing(sim_address(3));
  run_pass();
  EXPECT_EQ(device.active_node_id(), lss::kUnconfigured);
  ASSERT_EQ(texts(events, Kind::LssFailed).size(), 1u);
  EXPECT_NE(texts(events, Kind::LssFailed)[0].find("node-ID out of range (error code 1)"),
            std::string::npos)
      << texts(events, Kind::LssFailed)[0];
  // CiA 305 §8.3.1: configure node-ID error code 1, node-ID out of range.
  const MasterEvent* failed = event_of(Kind::LssFailed);
  ASSERT_NE(failed, nullptr);
  ASSERT_TRUE(failed->lss.has_value());
  EXPECT_EQ(failed->lss->outcome, LssScanOutcome::ConfigureRefused);
  EXPECT_EQ(failed->lss->error_code, 1U);
  EXPECT_EQ(failed->node_id, 9);
}

TEST_F(ExecuteLssBus, TenDevicesOfTenSlavesAllGetTheirNodeIds) {
  for (std::uint8_t n = 1; n <= 10; ++n) {
    port.slaves[n] = sim_address(0x1000u * n + 7);
    add(sim_address(0x1000u * n + 7));
  }
  run_pass();
  for (const auto& d : devices) {
    EXPECT_EQ(d->engine().active_node_id(), (d->engine().address().serial - 7) / 0x1000u);
  }
  EXPECT_EQ(texts(events, Kind::LssAssigned).size(), 10u);
}

// The known addresses selected (CiA 305 switch state selective: 40h vendor-ID, 41h product code,
// 42h revision number, 43h serial number, each little-endian in bytes 1-4; only the device whose
// four parts all match answers 44h and enters LSS configuration), after identify non-configured
// remote slave (4Ch, answered 50h by every device without node-ID). sim_address's parts
// little-endian: vendor DE C0 57 7E, product 08 05 00 00, revision 01 00 02 00.
const std::string kWaiting = "7E5#0400000000000000";
const std::string kIdentify = "7E5#4C00000000000000";
const std::string kUnconfigured = "7E4#5000000000000000";
const std::string kReset = "7E5#5100000000800000";
const std::string kAnswer = "7E4#4F00000000000000";
const std::string kSelectVendor = "7E5#40DEC0577E000000";
const std::string kSelectProduct = "7E5#4108050000000000";
const std::string kSelectRevision = "7E5#4201000200000000";
const std::string kSelected = "7E4#4400000000000000";
const std::string kInquireNodeId = "7E5#5E00000000000000";
const std::string kNoNodeId = "7E4#5EFF000000000000";
const std::string kVendor = "7E5#51DEC0577E000001";    // Fastscan part 0, BitCheck 0, LSSNext 1
const std::string kProduct = "7E5#5108050000000102";   // part 1, LSSNext 2
const std::string kRevision = "7E5#5101000200000203";  // part 2, LSSNext 3
const std::string kStore = "7E5#1700000000000000";
const std::string kStored = "7E4#1700000000000000";
const std::string kConfigured = "7E4#1100000000000000";  // configure node-ID, error code 0

// The selection of sim_address(serial): 40h-43h.
Frames select(std::uint32_t serial) {
  char last[32];
  std::snprintf(last, sizeof last, "7E5#43%02X%02X%02X%02X000000", serial & 0xFF,
                serial >> 8 & 0xFF, serial >> 16 & 0xFF, serial >> 24 & 0xFF);
  return {kSelectVendor, kSelectProduct, kSelectRevision, last};
}
// Frames `parts` one after another.
Frames cat(std::initializer_list<Frames> parts) {
  Frames all;
  for (const auto& p : parts) all.insert(all.end(), p.begin(), p.end());
  return all;
}

TEST_F(ExecuteLssBus, KnownAddressIsSelectedByItsFourPartsAndOnlyItsDeviceAnswers) {
  port.slaves[5] = sim_address(0xCAFEBABE);
  auto& device = add(sim_address(0xCAFEBABE));
  run_pass();
  EXPECT_EQ(device.active_node_id(), 5);
  EXPECT_EQ(frames, cat({{kWaiting, kIdentify, kUnconfigured},
                         select(0xCAFEBABE),
                         {kSelected, kInquireNodeId, kNoNodeId, "7E5#1105000000000000", kConfigured,
                          kStore, kStored, kWaiting, kReset}}));
  EXPECT_EQ(texts(events, Kind::LssScanEnded),
            Frames{"LSS: 1 unconfigured device found, 1 given a node-ID"});
}

TEST_F(ExecuteLssBus, TwoDevicesWhoseSerialNumbersDifferInOneBitAreSelectedOneAfterTheOther) {
  port.slaves[5] = sim_address(0x10);
  port.slaves[6] = sim_address(0x11);
  auto& first = add(sim_address(0x10));
  auto& second = add(sim_address(0x11));
  run_pass();
  EXPECT_EQ(first.active_node_id(), 5);
  EXPECT_EQ(second.active_node_id(), 6);
  // Both answer 4Ch; each selection is answered by its own device only, and while one is
  // configured the other says nothing.
  EXPECT_EQ(frames, cat({{kWaiting, kIdentify, kUnconfigured, kUnconfigured},
                         select(0x10),
                         {kSelected, kInquireNodeId, kNoNodeId, "7E5#1105000000000000", kConfigured,
                          kStore, kStored, kWaiting},
                         select(0x11),
                         {kSelected, kInquireNodeId, kNoNodeId, "7E5#1106000000000000", kConfigured,
                          kStore, kStored, kWaiting, kReset}}));
  EXPECT_EQ(texts(events, Kind::LssAssigned).size(), 2u);
}

TEST_F(ExecuteLssBus, AbsentTargetCostsOneLssTimeoutThenItsFastscanConfirmation) {
  port.slaves[5] = sim_address(1);  // no device
  port.slaves[6] = sim_address(2);
  std::map<std::string, std::vector<TimePoint>> sent;
  bus.add_observer([&sent](const CanFrame& f, TimePoint at) { sent[to_candump(f)].push_back(at); });
  auto& present = add(sim_address(2));
  run_pass();
  EXPECT_EQ(present.active_node_id(), 6);
  // Slave 5's selection goes unanswered: after the LSS timeout every device to waiting and the
  // Fastscan confirmation of its address, whose serial number nobody answers; then slave 6's
  // selection.
  EXPECT_EQ(frames, cat({{kWaiting, kIdentify, kUnconfigured},
                         select(1),
                         {kWaiting, kReset, kAnswer, kVendor, kAnswer, kProduct, kAnswer, kRevision,
                          kAnswer, "7E5#5101000000000300"},
                         select(2),
                         {kSelected, kInquireNodeId, kNoNodeId, "7E5#1106000000000000", kConfigured,
                          kStore, kStored, kWaiting, kReset}}));
  EXPECT_TRUE(texts(events, Kind::LssFailed).empty());
  EXPECT_TRUE(texts(events, Kind::LssUnmatched).empty());
  // One timeout (100 ms, from the selection's start) to the switch to waiting, no more: the
  // selection's first frame and the switch are each seen at the end of their air time.
  ASSERT_EQ(sent[kWaiting].size(), 3u);
  const auto silence = sent[kWaiting][1] - sent[kSelectVendor][0];
  EXPECT_GE(silence, 99ms);
  EXPECT_LT(silence, 101ms);
}

TEST_F(ExecuteLssBus, AbsentTargetAfterTheLastDeviceEndsTheScanOnTheSilentReset) {
  port.slaves[5] = sim_address(1);
  port.slaves[6] = sim_address(2);  // no device
  add(sim_address(1));
  run_pass();
  // Slave 6's selection is not answered; the confirmation's reset is not either: nobody is left.
  EXPECT_EQ(frames, cat({{kWaiting, kIdentify, kUnconfigured},
                         select(1),
                         {kSelected, kInquireNodeId, kNoNodeId, "7E5#1105000000000000", kConfigured,
                          kStore, kStored, kWaiting},
                         select(2),
                         {kWaiting, kReset}}));
}

TEST_F(ExecuteLssBus, ConfiguredDeviceOfATargetIsLeftAsItIsAndIdentifyNonConfiguredEndsTheScan) {
  port.slaves[5] = sim_address(1);
  port.slaves[6] = sim_address(2);
  port.slaves[7] = sim_address(3);
  add(sim_address(1));
  auto& configured = add(sim_address(2));
  configured.start(6);  // powers on with its stored node-ID 6
  run_pass();
  EXPECT_EQ(configured.active_node_id(), 6);
  // Slave 6's device answers its selection (CiA 305 selects by address) and inquire node-ID
  // with 6: switched back untouched. A device got its node-ID since 4Ch was answered, so 4Ch
  // again: silence, the scan ends before slave 7's address.
  EXPECT_EQ(frames,
            cat({{kWaiting, kIdentify, kUnconfigured},
                 select(1),
                 {kSelected, kInquireNodeId, kNoNodeId, "7E5#1105000000000000", kConfigured, kStore,
                  kStored, kWaiting},
                 select(2),
                 {kSelected, kInquireNodeId, "7E4#5E06000000000000", kWaiting, kIdentify}}));
  EXPECT_EQ(texts(events, Kind::LssAssigned).size(), 1u);
  EXPECT_TRUE(texts(events, Kind::LssFailed).empty());
}

// An unconfigured LSS device that misses every switch state selective (a lost frame, or a
// device without it), a test fault wrapper of the engine shape around an LssSlave.
struct IgnoresSelection {
  using Event = LssSlaveEvent;
  using Output = LssSlave::Output;
  explicit IgnoresSelection(LssAddress address) : slave(address, lss::kUnconfigured) {}
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out) {
    if (lss::is_lss_frame(frame, lss::kMasterCobId) && frame.data[0] >= 0x40 &&
        frame.data[0] <= 0x43) {
      return false;
    }
    return slave.on_frame(frame, now, out);
  }
  void on_timer(TimePoint now, Output& out) { slave.on_timer(now, out); }
  std::optional<TimePoint> next_deadline() const { return slave.next_deadline(); }
  LssSlave slave;
};
static_assert(Engine<IgnoresSelection>);

TEST_F(ExecuteLssBus, DeviceThatMissesItsSelectionIsFoundByTheFastscanConfirmation) {
  port.slaves[5] = sim_address(0x42);
  SimEngineNode<IgnoresSelection> device(sim_address(0x42));
  device.set_event_handler([&device](const LssSlaveEvent& e, TimePoint) {
    if (e.kind == LssSlaveEvent::Kind::NodeIdActivate) {
      device.engine().slave.activate_pending_node_id();
    }
  });
  bus.attach(device);
  run_pass();
  EXPECT_EQ(device.engine().slave.active_node_id(), 5);
  EXPECT_EQ(frames, cat({{kWaiting, kIdentify, kUnconfigured},
                         select(0x42),
                         {kWaiting, kReset, kAnswer, kVendor, kAnswer, kProduct, kAnswer, kRevision,
                          kAnswer, "7E5#5142000000000300", kAnswer, "7E5#1105000000000000",
                          kConfigured, kStore, kStored, kWaiting, kReset}}));
  EXPECT_EQ(texts(events, Kind::LssAssigned).size(), 1u);
}

TEST_F(ExecuteLssBus, WhenMostTargetsAreAbsentTheRestAreConfirmedByFastscanWithoutATimeout) {
  for (std::uint8_t n = 1; n <= 5; ++n) port.slaves[n] = sim_address(n);
  auto& present = add(sim_address(5));  // slaves 1-4 have no device
  run_pass();
  EXPECT_EQ(present.active_node_id(), 5);
  // Slaves 1 and 2 are selected (one timeout each) and confirmed; with two absent and none found
  // (2 x 2 > 0 + 2) slaves 3-5 are confirmed by Fastscan at once, no selection sent.
  const auto selections = std::count(frames.begin(), frames.end(), kSelectVendor);
  EXPECT_EQ(selections, 2);
  EXPECT_EQ(std::count(frames.begin(), frames.end(), "7E5#4302000000000000"), 1);
  EXPECT_EQ(std::count(frames.begin(), frames.end(), "7E5#4303000000000000"), 0);
  EXPECT_EQ(std::count(frames.begin(), frames.end(), "7E5#5105000000000300"), 1);
  EXPECT_EQ(texts(events, Kind::LssAssigned).size(), 1u);
}

TEST_F(ExecuteLssBus, DevicesLeftAfterTheTargetsAreSearchedBitByBitAndReported) {
  port.slaves[5] = sim_address(1);
  add(sim_address(1));
  auto& stranger = add(sim_address(0x63));
  run_pass();
  // The target, then the reset still answered (the stranger): the bit-by-bit search starts at
  // once with bit 31 of the vendor-ID queried as 0 (BitCheck 1Fh, LSSSub = LSSNext = 0).
  const Frames head =
      cat({{kWaiting, kIdentify, kUnconfigured, kUnconfigured},
           select(1),
           {kSelected, kInquireNodeId, kNoNodeId, "7E5#1105000000000000", kConfigured, kStore,
            kStored, kWaiting, kReset, kAnswer, "7E5#51000000001F0000"}});
  ASSERT_GE(frames.size(), head.size());
  EXPECT_EQ(Frames(frames.begin(), frames.begin() + static_cast<std::ptrdiff_t>(head.size())),
            head);
  EXPECT_EQ(stranger.active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(texts(events, Kind::LssUnmatched),
            Frames{"LSS: unconfigured device 7E57C0DE:00000508:00020001:00000063 matches no "
                   "slave: left unconfigured"});
  EXPECT_EQ(texts(events, Kind::LssScanEnded),
            Frames{"LSS: 2 unconfigured devices found, 1 given a node-ID"});
}

TEST_F(ExecuteLssBus, TargetWhoseConfigureFailedIsReportedOnceAndDevicesBelowItAreStillFound) {
  port.slaves[9] = sim_address(0x50);
  auto& refused = add_refusing(sim_address(0x50));
  auto& stranger = add(sim_address(0x20));  // a lower address, matching no slave
  run_pass();
  EXPECT_EQ(refused.active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(stranger.active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(texts(events, Kind::LssFailed).size(), 1u);
  EXPECT_EQ(texts(events, Kind::LssUnmatched),
            Frames{"LSS: unconfigured device 7E57C0DE:00000508:00020001:00000020 matches no "
                   "slave: left unconfigured"});
}

// --- composed into the NMT master ----------------------------------------------------------

constexpr cfg::NodeId kMasterId = 0x7F_node;
constexpr std::uint32_t kSlaveBootStart = 0x05;  // 1F81h bits 0 and 2: slave, boot it

// The device's serial number in [DeviceComissioning] LSS_SerialNumber, or (`in_1018h`) as 1018h
// sub 4's ParameterValue, which the device then also answers to the master's 1018h upload.
cfg::DeviceDescription lss_device(std::uint32_t serial, bool in_1018h = false) {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sim_device.eds");
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  auto device = result.device.value_or(cfg::DeviceDescription{});
  device.device_info.set("LSS_Supported", "1");
  if (in_1018h) {
    device.sub(0x1018, 4)->parameter_value = std::to_string(serial);
    return device;
  }
  device.commissioning.emplace();
  device.commissioning->lss_serial_number = serial;
  return device;
}

class MasterLss : public ::testing::Test {
 protected:
  SimBus bus{500'000};
  std::unique_ptr<SimEngineNode<NmtMaster>> master;
  std::map<std::uint32_t, std::unique_ptr<SimEngineNode<SimulatedDevice>>> devices;  // by serial
  std::vector<MasterEvent> events;
  std::vector<std::pair<TimePoint, std::string>> frames;

  MasterLss() {
    bus.add_observer([this](const CanFrame& f, TimePoint t) {
      frames.push_back({t, to_candump(f)});
    });
  }
  void make_master(MasterOptions options, const std::vector<std::uint8_t>& slaves) {
    auto created = NmtMaster::create(cfg::DeviceDescription{}, kMasterId, std::move(options));
    ASSERT_TRUE(created.ok()) << created.error().message;
    master = std::make_unique<SimEngineNode<NmtMaster>>(std::move(created).value());
    master->set_event_handler([this](const MasterEvent& e, TimePoint) { events.push_back(e); });
    for (const auto node : slaves) {
      ASSERT_TRUE(master->engine().dictionary().set_unsigned(0x1F81, node, kSlaveBootStart));
    }
    bus.attach(*master);
  }
  SimulatedDevice& power_on_unconfigured(std::uint32_t serial, bool in_1018h = false) {
    auto device = SimulatedDevice::create_unconfigured(lss_device(serial, in_1018h));
    EXPECT_TRUE(device.ok()) << (device.ok() ? "" : device.error().message);
    auto& slot = devices[serial];
    slot = std::make_unique<SimEngineNode<SimulatedDevice>>(std::move(device).value());
    bus.attach(*slot);
    slot->apply(
        [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
    return slot->engine();
  }
  void start() {
    master->apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  }
  std::vector<const MasterEvent*> of_kind(Kind kind) const {
    std::vector<const MasterEvent*> found;
    for (const auto& e : events) {
      if (e.kind == kind) found.push_back(&e);
    }
    return found;
  }
  std::optional<TimePoint> last_lss_request() const {
    std::optional<TimePoint> last;
    for (const auto& [t, f] : frames) {
      if (f.rfind("7E5#", 0) == 0) last = t;
    }
    return last;
  }
  std::optional<TimePoint> first(const std::string& frame) const {
    for (const auto& [t, f] : frames) {
      if (f == frame) return t;
    }
    return std::nullopt;
  }
  static MasterOptions lss_options(std::map<cfg::NodeId, LssAddress> addresses) {
    MasterOptions options;
    options.lss.enabled = true;
    options.lss.addresses = std::move(addresses);
    return options;
  }
  // Slaves 2 and 3 with their addresses and the look every 500 ms: node 2's device is out of the
  // box at start-up, node 3's absent (its boot ends with B); then node 3's device arrives out of
  // the box and the master runs 8 s more. `frames` and `events` are those of the last 8 s.
  void node3s_device_arrives_later() {
    auto options = lss_options({{2_node, sim_address(0x102)}, {3_node, sim_address(0x103)}});
    options.lss.period = 500ms;
    make_master(std::move(options), {2, 3});
    power_on_unconfigured(0x102);
    start();
    bus.run_for(8s);
    ASSERT_EQ(master->engine().last_error(*cfg::NodeId::from(3)), BootError::B);
    frames.clear();
    events.clear();
    power_on_unconfigured(0x103);
    bus.run_for(8s);
  }
};

TEST_F(MasterLss, ExecuteLssGivesEachDeviceItsSlavesNodeIdBeforeTheResetOfAllNodes) {
  make_master(lss_options({{2_node, sim_address(0x102)},
                           {3_node, sim_address(0x103)},
                           {4_node, sim_address(0x104)}}),
              {2, 3, 4});
  for (const std::uint32_t serial : {0x104u, 0x102u, 0x103u}) power_on_unconfigured(serial);
  start();
  bus.run_for(8s);
  std::vector<std::uint8_t> assigned;
  for (const auto* e : of_kind(Kind::LssAssigned)) assigned.push_back(e->node_id->value());
  std::sort(assigned.begin(), assigned.end());
  EXPECT_EQ(assigned, (std::vector<std::uint8_t>{2, 3, 4}));
  // DSP 302 §4 figure 1: step 3 (Execute LSS) before step 4 (reset of all nodes).
  const auto reset_all = first("000#8200");
  ASSERT_TRUE(reset_all.has_value());
  EXPECT_LT(*last_lss_request(), *reset_all);
  const auto began = of_kind(Kind::StartupBegan);
  ASSERT_EQ(began.size(), 1u);
  // Then the usual boot: every slave configured and started.
  EXPECT_EQ(of_kind(Kind::SlaveBooted).size(), 3u);
  EXPECT_EQ(master->engine().startup_state(), StartupState::Operational);
  for (const auto& [serial, d] : devices) {
    EXPECT_EQ(d->engine().node().node_id().value(), serial - 0x100) << serial;
  }
}

TEST_F(MasterLss, AddressesComeFrom1F85hTo1F88hWhenAllFourAreGivenSerialFrom1018hSub4) {
  make_master(lss_options({}), {6});
  auto& dict = master->engine().dictionary();
  ASSERT_TRUE(dict.set_unsigned(0x1F85, 6, 0x7E57C0DE));
  ASSERT_TRUE(dict.set_unsigned(0x1F86, 6, 0x00000508));
  ASSERT_TRUE(dict.set_unsigned(0x1F87, 6, 0x00020001));
  ASSERT_TRUE(dict.set_unsigned(0x1F88, 6, 0x00000606));
  power_on_unconfigured(0x606, /*in_1018h=*/true);
  start();
  bus.run_for(8s);
  ASSERT_EQ(of_kind(Kind::LssAssigned).size(), 1u);
  EXPECT_EQ(of_kind(Kind::LssAssigned)[0]->node_id, 6);
  EXPECT_EQ(of_kind(Kind::SlaveBooted).size(), 1u);
}

TEST_F(MasterLss, UnmatchedDeviceIsReportedAndTheSlaveWithoutDeviceIsMissing) {
  make_master(lss_options({{2_node, sim_address(0x102)}, {3_node, sim_address(0x103)}}), {2, 3});
  power_on_unconfigured(0x102);
  power_on_unconfigured(0x999);
  start();
  bus.run_for(8s);
  ASSERT_EQ(of_kind(Kind::LssUnmatched).size(), 1u);
  EXPECT_NE(describe(*of_kind(Kind::LssUnmatched)[0]).find("7E57C0DE:00000508:00020001:00000999"),
            std::string::npos);
  EXPECT_FALSE(devices[0x999]->engine().node().has_node_id());
  EXPECT_EQ(master->engine().last_error(*cfg::NodeId::from(3)), BootError::B);
  EXPECT_EQ(master->engine().last_error(*cfg::NodeId::from(2)), std::nullopt);
  ASSERT_EQ(of_kind(Kind::SlaveBooted).size(), 1u);
  EXPECT_EQ(of_kind(Kind::SlaveBooted)[0]->node_id, 2);
}

TEST_F(MasterLss, OffByDefaultNoLssFrame) {
  make_master(MasterOptions{}, {2});
  power_on_unconfigured(0x102);
  start();
  bus.run_for(8s);
  EXPECT_EQ(last_lss_request(), std::nullopt);
  EXPECT_EQ(master->engine().last_error(*cfg::NodeId::from(2)), BootError::B);
}

TEST_F(MasterLss, ConfiguredNetworkCostsTwoLssFramesAndOneStep) {
  make_master(lss_options({{2_node, sim_address(0x102)}}), {2});
  power_on_unconfigured(0x102);
  start();
  bus.run_for(8s);
  ASSERT_EQ(of_kind(Kind::LssAssigned).size(), 1u);
  // The master starts again (a reset of itself): the device kept its node-ID (stored).
  frames.clear();
  events.clear();
  master->apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
    return m.request_nmt(kMasterId, NmtRequest::ResetNode, now, out) == SdoAbort::None;
  });
  bus.run_for(8s);
  EXPECT_TRUE(of_kind(Kind::LssAssigned).empty());
  std::size_t lss_frames = 0;
  for (const auto& [t, f] : frames) {
    lss_frames += f.rfind("7E5#", 0) == 0 || f.rfind("7E4#", 0) == 0 ? 1 : 0;
  }
  EXPECT_EQ(lss_frames, 2u);  // 04h to waiting, 4Ch; nobody answers
  EXPECT_EQ(of_kind(Kind::SlaveBooted).size(), 1u);
}

TEST_F(MasterLss, ReplacedDeviceIsFoundByTheLookAndBootedByTheBootUpHandler) {
  // The device of node 3 arrives new out of the box while the master runs.
  ASSERT_NO_FATAL_FAILURE(node3s_device_arrives_later());
  ASSERT_EQ(of_kind(Kind::LssAssigned).size(), 1u);
  EXPECT_EQ(of_kind(Kind::LssAssigned)[0]->node_id, 3);
  ASSERT_EQ(of_kind(Kind::SlaveBooted).size(), 1u);
  EXPECT_EQ(of_kind(Kind::SlaveBooted)[0]->node_id, 3);
  EXPECT_EQ(devices[0x103]->engine().node().node_id().value(), 3);
}

TEST_F(MasterLss, LookSelectsTheMissingSlavesAddressAndNotTheRunningOnes) {
  ASSERT_NO_FATAL_FAILURE(node3s_device_arrives_later());
  // Node 3 is missing (1F82h 1), node 2 runs (so its device has its node-ID): node 3's address
  // is selected (its serial number 103h in 43h), its device configured, and node 2's address is
  // never sent.
  EXPECT_TRUE(first("7E5#4303010000000000").has_value());
  EXPECT_FALSE(first("7E5#4302010000000000").has_value());
  EXPECT_FALSE(first("7E5#5102010000000300").has_value());
  ASSERT_EQ(of_kind(Kind::LssAssigned).size(), 1u);
  EXPECT_EQ(of_kind(Kind::LssAssigned)[0]->node_id, 3);
}

}  // namespace
}  // namespace nmt
