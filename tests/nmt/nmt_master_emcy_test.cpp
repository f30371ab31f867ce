// The NMT master's emergency consumer in the master (docs/master.md "Emergencies"), on the
// simulated bus with simulated devices (tests/data/sim_device.eds, 1000h 000F0191h: CiA 401)
// whose EMCYs are raised at set times (DeviceFaults::emergencies, through their EmcyProducer).
// CiA 301 §7.2.7 (the message), §7.5.2.30 (1028h, emergency consumer: sub-index n is node n's
// EMCY COB-ID, bit 31 set: not valid).
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/master_objects.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using namespace cfg::literals;
using Kind = MasterEvent::Kind;

constexpr cfg::NodeId kMaster = 0x7F_node;
constexpr auto kOptional = cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave;

cfg::DeviceDescription read_text(const std::string& text) {
  auto result = cfg::parse_device_description(text);
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  return result.device.value_or(cfg::DeviceDescription{});
}

cfg::DeviceDescription sim_eds() {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sim_device.eds");
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  return result.device.value_or(cfg::DeviceDescription{});
}

// A master DCF with 1028h sub 1..3 as given.
cfg::DeviceDescription master_with_1028(std::uint32_t sub1, std::uint32_t sub2,
                                        std::uint32_t sub3) {
  std::string text =
      "[DeviceInfo]\nVendorName=test\nProductName=master\n"
      "[MandatoryObjects]\nSupportedObjects=1\n1=0x1000\n"
      "[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
      "DefaultValue=0\n"
      "[OptionalObjects]\nSupportedObjects=1\n1=0x1028\n"
      "[1028]\nParameterName=Emergency consumer\nObjectType=0x8\nSubNumber=4\n"
      "[1028sub0]\nParameterName=Highest sub-index supported\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=ro\nDefaultValue=3\n";
  const std::uint32_t subs[] = {sub1, sub2, sub3};
  for (int i = 0; i < 3; ++i) {
    text += "[1028sub" + std::to_string(i + 1) + "]\nParameterName=Consumer " +
            std::to_string(i + 1) +
            "\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=" +
            std::to_string(subs[i]) + "\n";
  }
  return read_text(text);
}

struct Rig {
  explicit Rig(cfg::DeviceDescription dcf = {}, MasterOptions options = {}) : bus(500'000) {
    auto master = NmtMaster::create(dcf, kMaster, std::move(options));
    EXPECT_TRUE(master.ok()) << (master.ok() ? "" : master.error().message);
    master_ = std::make_unique<SimEngineNode<NmtMaster>>(std::move(master).value());
    master_->set_event_handler([this](const MasterEvent& e, TimePoint) { events.push_back(e); });
    bus.attach(*master_);
  }
  void set(std::uint16_t index, std::uint8_t sub, std::uint64_t value) {
    ASSERT_TRUE(master_->engine().dictionary().set_unsigned(index, sub, value));
  }
  void add_slave(std::uint8_t node, DeviceFaults faults) {
    auto device = SimulatedDevice::create(sim_eds(), node, std::move(faults));
    ASSERT_TRUE(device.ok()) << (device.ok() ? "" : device.error().message);
    slaves.push_back(std::make_unique<SimEngineNode<SimulatedDevice>>(std::move(device).value()));
    bus.attach(*slaves.back());
    slaves.back()->apply(
        [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
    set(0x1F81, node, kOptional);
  }
  void start() {
    master_->apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  }
  std::vector<const MasterEvent*> of_kind(Kind kind) const {
    std::vector<const MasterEvent*> found;
    for (const auto& e : events) {
      if (e.kind == kind) found.push_back(&e);
    }
    return found;
  }

  SimBus bus;
  std::vector<MasterEvent> events;
  std::vector<std::unique_ptr<SimEngineNode<SimulatedDevice>>> slaves;

 private:
  std::unique_ptr<SimEngineNode<NmtMaster>> master_;
};

DeviceFaults emcy_at(std::chrono::milliseconds at, std::uint16_t code, std::uint8_t bits) {
  DeviceFaults faults;
  faults.emergencies.push_back({TimePoint{} + at, code, bits});
  return faults;
}

TEST(NmtMasterEmcy, ReportsASlavesEmergencyOnItsDefaultCobId) {
  Rig rig;
  auto faults = emcy_at(500ms, 0x8130, error_register::kCommunication);
  faults.emergencies.push_back({TimePoint{} + 700ms, emcy_code::kErrorReset, 0});
  rig.add_slave(3, faults);
  rig.start();
  rig.bus.run_for(1s);
  const auto emcys = rig.of_kind(Kind::Emergency);
  ASSERT_EQ(emcys.size(), 2U);
  EXPECT_EQ(emcys[0]->node_id, 3_node);
  // Raised at 500 ms, received once its 8 bytes crossed the bus (about 0.25 ms at 500 kbit/s).
  EXPECT_GE(emcys[0]->at, TimePoint{} + 500ms);
  EXPECT_LT(emcys[0]->at, TimePoint{} + 501ms);
  ASSERT_TRUE(emcys[0]->emergency.has_value());
  // 1001h: the communication bit asked for and the generic bit every error sets (§7.5.2.2).
  EXPECT_EQ(emcys[0]->emergency->emcy, (Emergency{0x8130, 0x11, {}}));
  EXPECT_EQ(emcys[0]->emergency->device_type, std::nullopt);  // no source, 1F84h sub 3 is 0
  EXPECT_EQ(emcys[1]->emergency->emcy.error_code, 0x0000);
  EXPECT_TRUE(emcys[1]->emergency->ends_error);
  EXPECT_EQ(describe(*emcys[1]),
            "node 3: emergency ended: 0000h error reset or no error; error register 11h "
            "(generic, communication); manufacturer bytes 00 00 00 00 00");
}

TEST(NmtMasterEmcy, ReadsTheCodeInTheProfileOfTheDeviceType) {
  MasterOptions options;
  options.emcy.sources[3_node] = {.cob_id = std::nullopt, .device_type = 0x000F0191};
  Rig rig({}, options);
  rig.add_slave(3, emcy_at(500ms, 0x2310, error_register::kCurrent));
  rig.start();
  rig.bus.run_for(1s);
  const auto emcys = rig.of_kind(Kind::Emergency);
  ASSERT_EQ(emcys.size(), 1U);
  EXPECT_EQ(emcys[0]->emergency->device_type, 0x000F0191U);
  EXPECT_EQ(describe(*emcys[0]),
            "node 3: emergency 2310h current at outputs too high (overload) (CiA 401); current, "
            "device output side; error register 03h (generic, current); manufacturer bytes 00 "
            "00 00 00 00");
}

TEST(NmtMasterEmcy, A1014hOfAnotherIdIsNotHeardOnTheDefault) {
  // The DCF says the node's EMCY is on 0A3h: the default 83h of the device is not its EMCY.
  MasterOptions options;
  options.emcy.sources[3_node] = {.cob_id = cfg::CobId::standard(0x0A3), .device_type = {}};
  Rig rig({}, options);
  rig.add_slave(3, emcy_at(500ms, 0x8130, 0));
  rig.start();
  rig.bus.run_for(1s);
  EXPECT_TRUE(rig.of_kind(Kind::Emergency).empty());
}

TEST(NmtMasterEmcy, The1028hOfTheMasterDcfWins) {
  // 1028h sub 3 not valid (bit 31): node 3's EMCY is not consumed, though 1F81h lists it and
  // the source names 83h; sub 2 moves node 2's to 0A2h, where its device does not send.
  MasterOptions options;
  options.emcy.sources[3_node] = {.cob_id = cfg::CobId::standard(0x083), .device_type = {}};
  Rig rig(master_with_1028(0x81, 0x0A2, 0x80000083), options);
  rig.add_slave(3, emcy_at(500ms, 0x8130, 0));
  rig.add_slave(2, emcy_at(500ms, 0x8130, 0));
  rig.add_slave(1, emcy_at(500ms, 0x1000, 0));
  rig.start();
  rig.bus.run_for(1s);
  const auto emcys = rig.of_kind(Kind::Emergency);
  ASSERT_EQ(emcys.size(), 1U);
  EXPECT_EQ(emcys[0]->node_id, 1_node);
}

TEST(NmtMasterEmcy, AFloodIsSummarised) {
  MasterOptions options;
  options.emcy.max_per_window = 2;
  Rig rig({}, options);
  DeviceFaults faults;
  for (int i = 0; i < 10; ++i) faults.emergencies.push_back({TimePoint{} + 500ms, 0x8130, 0});
  rig.add_slave(3, faults);
  rig.start();
  rig.bus.run_for(2s);
  const auto emcys = rig.of_kind(Kind::Emergency);
  ASSERT_EQ(emcys.size(), 2U);
  const auto floods = rig.of_kind(Kind::EmergencyFlood);
  ASSERT_EQ(floods.size(), 1U);
  EXPECT_EQ(floods[0]->at, emcys[0]->at + 1s);  // the window of 1 s from the first
  EXPECT_EQ(floods[0]->emergency->suppressed, 8U);
  EXPECT_EQ(describe(*floods[0]),
            "node 3: 8 more emergencies 8130h life guard error or heartbeat error not reported "
            "(at most 2 per 1000 ms per node and code)");
}

TEST(NmtMasterEmcy, ABootErrorSaysTheEmergencySentDuringTheBoot) {
  Rig rig;
  // The device answers SDO 50 ms late: its EMCY at 20 ms comes while the master identifies it,
  // and 1F84h expects another device type (status C, CiA 302-2 Table 1).
  auto faults = emcy_at(20ms, 0x5000, 0);
  faults.sdo_latency = 50ms;
  rig.add_slave(3, faults);
  rig.set(0x1F84, 3, 0x00020192);
  rig.start();
  rig.bus.run_for(500ms);
  const auto errors = rig.of_kind(Kind::BootError);
  ASSERT_FALSE(errors.empty());
  ASSERT_TRUE(errors[0]->boot_emergency.has_value());
  EXPECT_EQ(errors[0]->boot_emergency->emcy.error_code, 0x5000);
  EXPECT_NE(describe_boot_error(*errors[0])
                .find("; the node sent emergency 5000h device hardware during its boot"),
            std::string::npos)
      << describe_boot_error(*errors[0]);
}

}  // namespace
}  // namespace nmt
