// NmtMaster on the simulated bus with simulated devices (tests/data/sim_device.eds): the
// integrator's tests of the engine's own choices (nmt/master/nmt_master.hpp); the independent spec
// suite is nmt_master_spec_test.cpp. Spec: CiA 302-2 §3 (start-up, boot NMT slave, check
// configuration), §4 (error control, handlers), §6 (objects).
#include "nmt/master/nmt_master.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/master_objects.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using namespace cfg::literals;

constexpr cfg::NodeId kMaster = 0x7F_node;

cfg::DeviceDescription sim_eds() {
  static const cfg::DeviceDescription eds = [] {
    auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sim_device.eds");
    EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
    return result.device.value_or(cfg::DeviceDescription{});
  }();
  return eds;
}

std::vector<std::uint8_t> le(std::uint64_t value, std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(value >> (8 * i));
  return bytes;
}

struct Configurations : ConfigurationSource {
  std::map<std::uint8_t, std::vector<cfg::ObjectWrite>> writes;
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    auto it = writes.find(node);
    if (it == writes.end()) return std::nullopt;
    return it->second;
  }
};

class MasterRig {
 public:
  explicit MasterRig(MasterOptions options = {}) : bus(500'000) {
    configurations = std::make_shared<Configurations>();
    if (!options.configurations) options.configurations = configurations;
    auto master = NmtMaster::create(cfg::DeviceDescription{}, kMaster, std::move(options));
    EXPECT_TRUE(master.ok()) << (master.ok() ? "" : master.error().message);
    master_ = std::make_unique<SimEngineNode<NmtMaster>>(std::move(master).value());
    master_->set_event_handler([this](const MasterEvent& e, TimePoint) { events.push_back(e); });
    bus.attach(*master_);
    bus.add_observer([this](const CanFrame& f, TimePoint t) {
      frames.push_back({t, to_candump(f)});
    });
  }

  NmtMaster& master() { return master_->engine(); }
  void set(std::uint16_t index, std::uint8_t sub, std::uint64_t value) {
    ASSERT_TRUE(master().dictionary().set_unsigned(index, sub, value));
  }

  SimulatedDevice& add_slave(std::uint8_t node, DeviceFaults faults = {}) {
    auto device = SimulatedDevice::create(sim_eds(), *cfg::NodeId::from(node), std::move(faults));
    EXPECT_TRUE(device.ok()) << (device.ok() ? "" : device.error().message);
    auto& slot = slaves_[node];
    slot = std::make_unique<SimEngineNode<SimulatedDevice>>(std::move(device).value());
    bus.attach(*slot);
    slot->apply(
        [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
    return slot->engine();
  }
  SimulatedDevice& slave(std::uint8_t node) { return slaves_.at(node)->engine(); }

  void start() {
    master_->apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  }
  void run(Duration d) { bus.run_for(d); }

  std::vector<const MasterEvent*> of_kind(MasterEvent::Kind kind) const {
    std::vector<const MasterEvent*> found;
    for (const auto& e : events) {
      if (e.kind == kind) found.push_back(&e);
    }
    return found;
  }
  bool sent(const std::string& frame) const {
    return std::any_of(frames.begin(), frames.end(),
                       [&](const auto& f) { return f.second == frame; });
  }
  std::optional<TimePoint> first(const std::string& frame) const {
    for (const auto& f : frames) {
      if (f.second == frame) return f.first;
    }
    return std::nullopt;
  }

  SimBus bus;
  std::shared_ptr<Configurations> configurations;
  std::vector<MasterEvent> events;
  std::vector<std::pair<TimePoint, std::string>> frames;

 private:
  std::unique_ptr<SimEngineNode<NmtMaster>> master_;
  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<SimulatedDevice>>> slaves_;
};

constexpr auto kMandatory = cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave |
                            cfg::SlaveAssignment::kMandatory;
constexpr auto kOptional = cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave;

TEST(NmtMaster, BootsConfiguresAndStartsMandatorySlaves) {
  MasterRig rig;
  for (std::uint8_t node : {std::uint8_t{2}, std::uint8_t{3}}) {
    rig.add_slave(node);
    rig.set(0x1F81, node, kMandatory);
    rig.set(0x1F84, node, 0x000F0191);  // sim_device.eds 1000h
    rig.set(0x1F26, node, 15000);
    rig.set(0x1F27, node, 3600000);
    rig.configurations->writes[node] = {{0x2000, 0, le(25, 2)}};
  }
  rig.start();
  rig.run(2s);
  EXPECT_EQ(rig.master().startup_state(), StartupState::Operational);
  EXPECT_EQ(rig.master().state(), NmtState::Operational);
  EXPECT_TRUE(rig.sent("000#8200"));  // §3.1 d: reset communication all
  EXPECT_TRUE(rig.sent("000#0102"));  // §3.4 l: start remote node individually (1F80h bit 1 = 0)
  EXPECT_TRUE(rig.sent("000#0103"));
  for (std::uint8_t node : {std::uint8_t{2}, std::uint8_t{3}}) {
    auto& d = rig.slave(node);
    EXPECT_EQ(d.node().state(), NmtState::Operational);
    EXPECT_EQ(d.node().dictionary().get_unsigned(0x2000, 0), 25U);
    EXPECT_EQ(d.node().dictionary().get_unsigned(0x1020, 1), 15000U);
    EXPECT_EQ(d.node().dictionary().get_unsigned(0x1020, 2), 3600000U);
    // 1010h 'save' after 1020h was written (DSP 302 §6: date and time first, then "save"): the
    // configuration and the verify configuration are what the device keeps.
    const auto& stored = d.node().stored();
    EXPECT_EQ(stored.at(LocalDictionary::key(0x2000, 0)), le(25, 2));
    EXPECT_EQ(stored.at(LocalDictionary::key(0x1020, 1)), le(15000, 4));
    EXPECT_EQ(stored.at(LocalDictionary::key(0x1020, 2)), le(3600000, 4));
    EXPECT_EQ(rig.master().boot_step(*cfg::NodeId::from(node)), BootStep::Booted);
  }
  const auto booted = rig.of_kind(MasterEvent::Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 2U);
  EXPECT_TRUE(booted[0]->configured);
  EXPECT_EQ(rig.of_kind(MasterEvent::Kind::StartupComplete).size(), 1U);
}

TEST(NmtMaster, SecondStartUpSkipsTheDownloadWhen1020Matches) {
  MasterRig rig;
  rig.add_slave(2);
  rig.set(0x1F81, 2, kMandatory);
  rig.set(0x1F26, 2, 15000);
  rig.set(0x1F27, 2, 1234);
  rig.configurations->writes[2] = {{0x2000, 0, le(25, 2)}};
  rig.start();
  rig.run(1s);
  ASSERT_EQ(rig.of_kind(MasterEvent::Kind::SlaveBooted).size(), 1U);
  // The master restarts (1F82h sub own node-ID: reset node); the slave keeps its saved values.
  rig.events.clear();
  rig.run(10ms);
  rig.master().dictionary().set_unsigned(0x1F82, kMaster, 0);
  rig.start();
  rig.run(1s);
  const auto booted = rig.of_kind(MasterEvent::Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  EXPECT_FALSE(booted[0]->configured);
}

TEST(NmtMaster, StartAllNodesWhenEverySlaveBooted) {
  MasterRig rig;
  rig.set(0x1F80, 0, cfg::NmtStartup::kMaster | cfg::NmtStartup::kStartAllNodes);
  for (std::uint8_t node : {std::uint8_t{2}, std::uint8_t{3}}) {
    rig.add_slave(node);
    rig.set(0x1F81, node, kMandatory);
  }
  rig.start();
  rig.run(1s);
  EXPECT_TRUE(rig.sent("000#0100"));
  EXPECT_FALSE(rig.sent("000#0102"));
  EXPECT_EQ(rig.slave(2).node().state(), NmtState::Operational);
}

TEST(NmtMaster, MissingMandatorySlaveHaltsStartUpAfterBootTime) {
  MasterRig rig;
  rig.set(0x1F89, 0, 2500);
  rig.set(0x1F81, 5, kMandatory);
  rig.start();
  rig.run(6s);
  EXPECT_EQ(rig.master().startup_state(), StartupState::Halted);
  EXPECT_EQ(rig.master().last_error(*cfg::NodeId::from(5)), BootError::B);
  const auto errors = rig.of_kind(MasterEvent::Kind::BootError);
  ASSERT_FALSE(errors.empty());
  EXPECT_TRUE(errors.back()->final);
  EXPECT_EQ(rig.of_kind(MasterEvent::Kind::StartupHalted).size(), 1U);
  // CiA 302-2 §3.1: "Before transition from NMT state Pre-operational to NMT state Operational
  // of the CANopen manager all assigned NMT slaves shall be booted".
  EXPECT_EQ(rig.master().state(), NmtState::PreOperational);
}

TEST(NmtMaster, OptionalSlaveAppearingLateIsBooted) {
  MasterRig rig;
  rig.set(0x1F81, 4, kOptional);
  rig.start();
  rig.run(3s);
  EXPECT_EQ(rig.master().startup_state(), StartupState::Operational);
  rig.add_slave(4);
  rig.run(2s);
  EXPECT_EQ(rig.master().boot_step(*cfg::NodeId::from(4)), BootStep::Booted);
  EXPECT_EQ(rig.slave(4).node().state(), NmtState::Operational);
}

TEST(NmtMaster, WrongDeviceTypeIsStatusC) {
  MasterRig rig;
  DeviceFaults faults;
  faults.device_type = 0x12345678;
  rig.add_slave(2, faults);
  rig.set(0x1F81, 2, kMandatory);
  rig.set(0x1F84, 2, 0x000F0191);
  rig.start();
  rig.run(1s);
  EXPECT_EQ(rig.master().last_error(*cfg::NodeId::from(2)), BootError::C);
  EXPECT_EQ(rig.master().startup_state(), StartupState::Halted);
}

TEST(NmtMaster, HeartbeatLossOfOptionalSlaveRestartsItsBoot) {
  MasterRig rig;
  DeviceFaults faults;
  faults.heartbeat_stops_at = TimePoint{3s};
  rig.add_slave(2, faults);
  rig.set(0x1F81, 2, kOptional);
  rig.set(0x1016, 1, HeartbeatConsumerEntry{2, 300}.encode());
  rig.configurations->writes[2] = {{0x1017, 0, le(100, 2)}};
  rig.start();
  rig.run(2s);
  EXPECT_EQ(rig.master().boot_step(*cfg::NodeId::from(2)), BootStep::Booted);
  rig.run(2s);
  EXPECT_EQ(rig.of_kind(MasterEvent::Kind::HeartbeatLost).size(), 1U);
}

TEST(NmtMaster, NmtInhibitTimeSpacesCommands) {
  MasterRig rig;
  rig.set(0x102A, 0, 50);  // 5 ms
  for (std::uint8_t node : {std::uint8_t{2}, std::uint8_t{3}, std::uint8_t{4}}) {
    rig.add_slave(node);
    rig.set(0x1F81, node, kMandatory | cfg::SlaveAssignment::kKeepAlive);
  }
  rig.start();
  rig.run(2s);
  std::vector<TimePoint> nmt;
  for (const auto& [t, f] : rig.frames) {
    if (f.rfind("000#", 0) == 0) nmt.push_back(t);
  }
  ASSERT_GT(nmt.size(), 10U);
  // Frames are seen at their end; the one in progress when an NMT frame is queued can delay it
  // by up to one frame time (at most 160 bits, 320 µs at 500 kbit/s). The first command also
  // waits behind the master's own boot-up, which shortens the first gap: it is not counted.
  for (std::size_t i = 2; i < nmt.size(); ++i) {
    EXPECT_GE(nmt[i] - nmt[i - 1], 5ms - 320us) << i;
  }
}

TEST(NmtMaster, RequestNmtOverTheDictionaryChecksValues) {
  MasterRig rig;
  rig.set(0x1F81, 2, kOptional);
  rig.start();
  auto& dict = rig.master().dictionary();
  const std::vector<std::uint8_t> reserved{0x02};
  EXPECT_EQ(dict.write(0x1F82, 2, reserved, TimePoint{}), SdoAbort::ValueRangeExceeded);
  const std::vector<std::uint8_t> start{0x05};
  EXPECT_EQ(dict.write(0x1F82, 9, start, TimePoint{}), SdoAbort::General);  // not a slave
  const std::vector<std::uint8_t> excluding{0x85};
  EXPECT_EQ(dict.write(0x1F82, 0x80, excluding, TimePoint{}), SdoAbort::General);
  // Bit 5 (flying master, §6.2 Table 13) is supported: it takes effect at the next start-up.
  const std::vector<std::uint8_t> flying = le(0x21, 4);
  EXPECT_EQ(dict.write(0x1F80, 0, flying, TimePoint{}), SdoAbort::None);
}

}  // namespace
}  // namespace nmt
namespace nmt {
namespace {
TEST(NmtMaster, PacedBootCompletes) {
  MasterOptions options;
  options.pacing.bitrate = 500'000;
  MasterRig rig(options);
  for (std::uint8_t node : {std::uint8_t{2}, std::uint8_t{3}}) {
    rig.add_slave(node);
    rig.set(0x1F81, node, kMandatory);
    rig.configurations->writes[node] = {{0x2000, 0, le(25, 2)}, {0x1017, 0, le(100, 2)}};
  }
  rig.start();
  rig.run(2s);
  EXPECT_EQ(rig.master().startup_state(), StartupState::Operational);
}
}  // namespace
}  // namespace nmt

namespace nmt {
namespace {

// A response timeout of 0 (or less) could never be met: the master is not built with it, and
// the error names the option, so no transfer later meets a timeout it cannot use.
TEST(NmtMaster, IsNotBuiltWithAResponseTimeoutThatIsNotPositive) {
  for (const auto timeout : {Duration::zero(), Duration{-1}}) {
    MasterOptions options;
    options.sdo.timeout = timeout;
    const auto created = NmtMaster::create(cfg::DeviceDescription{}, kMaster, options);
    ASSERT_FALSE(created.ok());
    EXPECT_NE(created.error().message.find("sdo.timeout"), std::string::npos)
        << created.error().message;
  }
  MasterOptions zero;
  zero.sdo.timeout = Duration::zero();
  const auto refused = zero.validate();
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().message, "MasterOptions::sdo.timeout must be positive (it is 0 us)");
}

// The other waits of the boot and the SDO manager are refused alike; 0 is taken where it
// means "none" (boot.boot_up_wait: no wait; lss.period: no looks).
TEST(NmtMaster, IsNotBuiltWithOtherTimeoutsThatAreNotPositive) {
  using Field = Duration& (*)(MasterOptions&);
  const std::vector<std::pair<Field, const char*>> fields{
      {[](MasterOptions& o) -> Duration& { return o.boot.retry_interval; }, "boot.retry_interval"},
      {[](MasterOptions& o) -> Duration& { return o.boot.reboot_timeout; }, "boot.reboot_timeout"},
      {[](MasterOptions& o) -> Duration& { return o.program.control_timeout; },
       "program.control_timeout"},
      {[](MasterOptions& o) -> Duration& { return o.program.clear_timeout; },
       "program.clear_timeout"},
      {[](MasterOptions& o) -> Duration& { return o.program.data_timeout; },
       "program.data_timeout"},
      {[](MasterOptions& o) -> Duration& { return o.boot.guarding_reply_timeout; },
       "boot.guarding_reply_timeout"},
      {[](MasterOptions& o) -> Duration& { return o.sdo_manager.scan_timeout; },
       "sdo_manager.scan_timeout"},
      {[](MasterOptions& o) -> Duration& { return o.sdo_manager.srd_guard_time; },
       "sdo_manager.srd_guard_time"},
  };
  for (const auto& [field, name] : fields) {
    for (const Duration value : {Duration::zero(), Duration{-5000}}) {
      MasterOptions options;
      field(options) = value;
      const auto created = NmtMaster::create(cfg::DeviceDescription{}, kMaster, options);
      ASSERT_FALSE(created.ok()) << name;
      EXPECT_NE(created.error().message.find(name), std::string::npos) << created.error().message;
    }
  }
  MasterOptions lss;
  lss.lss.timing.timeout = Duration::zero();
  EXPECT_FALSE(lss.validate().ok());
  MasterOptions none;
  none.boot.boot_up_wait = Duration::zero();
  none.lss.period = Duration::zero();
  EXPECT_TRUE(none.validate().ok());
  none.boot.boot_up_wait = -std::chrono::milliseconds(1);
  const auto negative = none.validate();
  ASSERT_FALSE(negative.ok());
  EXPECT_NE(negative.error().message.find("boot.boot_up_wait"), std::string::npos);
}

// CiA 302-2 §3.5 d: "The DCF may be read from ... object 1F22h on the configuration manager":
// without a ConfigurationSource the master downloads its own 1F22h sub node-ID.
TEST(NmtMaster, DownloadsTheConciseDcfOfItsOwn1F22) {
  cfg::DeviceDescription description;
  MasterOptions options;
  auto created = NmtMaster::create(description, kMaster, options);
  ASSERT_TRUE(created.ok());
  SimBus bus(500'000);
  SimEngineNode<NmtMaster> master(std::move(created).value());
  auto& dict = master.engine().dictionary();
  DictionaryEntry stream;
  stream.index = 0x1F22;
  stream.sub_index = 2;
  stream.data_type = static_cast<std::uint16_t>(cfg::DataType::Domain);
  stream.basic_type = cfg::DataType::Domain;
  stream.bytes = cfg::encode_concise_dcf(std::vector<cfg::ObjectWrite>{{0x2000, 0, le(42, 2)}});
  dict.insert(stream);
  ASSERT_TRUE(dict.set_unsigned(0x1F81, 2, kMandatory));
  auto device = SimulatedDevice::create(sim_eds(), *cfg::NodeId::from(2), {});
  ASSERT_TRUE(device.ok());
  SimEngineNode<SimulatedDevice> slave(std::move(device).value());
  bus.attach(master);
  bus.attach(slave);
  slave.apply(
      [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
  master.apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  bus.run_for(1s);
  EXPECT_EQ(slave.engine().node().dictionary().get_unsigned(0x2000, 0), 42U);
  EXPECT_EQ(master.engine().startup_state(), StartupState::Operational);
}

// §6.3 / DSP 302 §5.2: bit 1 of 1F81h is reserved: a master DCF setting it is refused, naming
// the entry.
TEST(NmtMaster, CreateRefusesReservedBit1Of1F81) {
  auto eds = cfg::parse_device_description(
      "[FileInfo]\nFileName=m.dcf\n[DeviceInfo]\nVendorName=x\n[OptionalObjects]\nSupportedObjects="
      "1\n"
      "1=0x1F81\n[1F81]\nParameterName=NMT slave assignment\nObjectType=0x8\nSubNumber=3\n"
      "[1F81sub0]\nParameterName=n\nObjectType=0x7\nDataType=0x0005\nAccessType=const\n"
      "DefaultValue=2\nPDOMapping=0\n[1F81sub1]\nParameterName=a\nObjectType=0x7\n"
      "DataType=0x0007\nAccessType=rw\nDefaultValue=0x03\nPDOMapping=0\n[1F81sub2]\n"
      "ParameterName=b\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\n"
      "PDOMapping=0\n");
  ASSERT_TRUE(eds.device.has_value()) << eds.diagnostics.format();
  auto created = NmtMaster::create(*eds.device, kMaster, {});
  ASSERT_FALSE(created.ok());
  EXPECT_NE(created.error().message.find("1F81h sub 01h"), std::string::npos)
      << created.error().message;
}

}  // namespace
}  // namespace nmt
