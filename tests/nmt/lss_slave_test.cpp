// LSS slave (CiA 305), frame by frame. Request and answer bytes are written out by hand from the
// layouts nmt/lss/lss.hpp cites (CANopenNode 305/CO_LSS.h and CO_LSSslave.c, lely-core
// src/co/lss.c): byte 0 the command specifier, 32-bit values little-endian in bytes 1-4, error
// code byte 1, manufacturer-specific error byte 2, unused bytes 0, always 8 data bytes.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "nmt/slave/slave_node.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using Frames = std::vector<std::string>;
using Kind = LssSlaveEvent::Kind;

// vendor 01020304h, product 00000A0Bh, revision 00010002h, serial CAFEBABEh
constexpr LssAddress kAddress{0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABE};

class LssSlaveTest : public ::testing::Test {
 protected:
  LssSlave slave{kAddress, lss::kUnconfigured};
  std::vector<LssSlaveEvent> events;

  Frames feed(std::string_view candump, bool expect_handled = true) {
    auto f = from_candump(candump);
    EXPECT_TRUE(f.has_value()) << candump;
    LssSlave::Output out;
    EXPECT_EQ(slave.on_frame(*f, TimePoint{}, out), expect_handled) << candump;
    for (auto& e : out.events) events.push_back(e);
    Frames frames;
    for (auto& fr : out.frames) frames.push_back(to_candump(fr));
    return frames;
  }
  void configuration() {
    EXPECT_TRUE(feed("7E5#0401000000000000").empty());
    ASSERT_EQ(slave.state(), LssState::Configuration);
  }
};

// --- switch state global (04h, byte 1 mode) / selective (40h-43h, answer 44h) ------------------

TEST_F(LssSlaveTest, SwitchStateGlobal04ModeByteOneEntersConfigurationWithoutAnswer) {
  EXPECT_TRUE(feed("7E5#0401000000000000").empty());
  EXPECT_EQ(slave.state(), LssState::Configuration);
  EXPECT_TRUE(feed("7E5#0400000000000000").empty());
  EXPECT_EQ(slave.state(), LssState::Waiting);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, Kind::StateChanged);
  EXPECT_EQ(events[1].state, LssState::Waiting);
}

TEST_F(LssSlaveTest, SwitchStateSelective40To43WithLittleEndianAddressAnswers44) {
  EXPECT_TRUE(feed("7E5#4004030201000000").empty());  // vendor-ID 01020304h
  EXPECT_TRUE(feed("7E5#410B0A0000000000").empty());  // product code 00000A0Bh
  EXPECT_TRUE(feed("7E5#4202000100000000").empty());  // revision 00010002h
  EXPECT_EQ(feed("7E5#43BEBAFECA000000"), Frames{"7E4#4400000000000000"});
  EXPECT_EQ(slave.state(), LssState::Configuration);
}

TEST_F(LssSlaveTest, SwitchStateSelectiveWithAnotherSerialNumberIsNotAnswered) {
  feed("7E5#4004030201000000");
  feed("7E5#410B0A0000000000");
  feed("7E5#4202000100000000");
  EXPECT_TRUE(feed("7E5#43BFBAFECA000000").empty());
  EXPECT_EQ(slave.state(), LssState::Waiting);
}

TEST_F(LssSlaveTest, SwitchStateSelectiveOutOfOrderIsNotAnswered) {
  feed("7E5#410B0A0000000000");
  feed("7E5#4004030201000000");
  feed("7E5#4202000100000000");  // the product code was never matched after the vendor-ID
  EXPECT_TRUE(feed("7E5#43BEBAFECA000000").empty());
  EXPECT_EQ(slave.state(), LssState::Waiting);
}

TEST(LssSlave, SwitchStateSelectiveIsAnsweredOnlyByTheDeviceWithAllFourParts) {
  // Four devices of one product that share three parts and differ in one: only the device
  // whose vendor-ID, product code, revision number and serial number all match answers 44h.
  std::vector<LssSlave> slaves{
      LssSlave(kAddress, lss::kUnconfigured),
      LssSlave({0x01020304, 0x00000A0B, 0x00010002, 0xCAFEBABF}, lss::kUnconfigured),
      LssSlave({0x01020304, 0x00000A0B, 0x00010003, 0xCAFEBABE}, lss::kUnconfigured),
      LssSlave({0x01020304, 0x00000A0C, 0x00010002, 0xCAFEBABE}, lss::kUnconfigured),
      LssSlave({0x01020305, 0x00000A0B, 0x00010002, 0xCAFEBABE}, lss::kUnconfigured)};
  std::vector<Frames> answers(slaves.size());
  for (const char* request : {"7E5#4004030201000000", "7E5#410B0A0000000000",
                              "7E5#4202000100000000", "7E5#43BEBAFECA000000"}) {
    for (std::size_t i = 0; i < slaves.size(); ++i) {
      LssSlave::Output out;
      slaves[i].on_frame(*from_candump(request), TimePoint{}, out);
      for (const auto& f : out.frames) answers[i].push_back(to_candump(f));
    }
  }
  EXPECT_EQ(answers[0], Frames{"7E4#4400000000000000"});
  EXPECT_EQ(slaves[0].state(), LssState::Configuration);
  for (std::size_t i = 1; i < slaves.size(); ++i) {
    EXPECT_TRUE(answers[i].empty()) << i;
    EXPECT_EQ(slaves[i].state(), LssState::Waiting) << i;
  }
}

TEST(LssSlave, SwitchStateSelectiveIsAnsweredByAConfiguredDeviceToo) {
  // The selection is by LSS address, not by node-ID state (unlike Fastscan).
  LssSlave slave(kAddress, 5);
  Frames answers;
  for (const char* request : {"7E5#4004030201000000", "7E5#410B0A0000000000",
                              "7E5#4202000100000000", "7E5#43BEBAFECA000000"}) {
    LssSlave::Output out;
    slave.on_frame(*from_candump(request), TimePoint{}, out);
    for (const auto& f : out.frames) answers.push_back(to_candump(f));
  }
  EXPECT_EQ(answers, Frames{"7E4#4400000000000000"});
  EXPECT_EQ(slave.state(), LssState::Configuration);
}

TEST_F(LssSlaveTest, SwitchStateSelectiveWithAPartMissingIsNotAnswered) {
  feed("7E5#4004030201000000");
  feed("7E5#410B0A0000000000");
  // The revision number (42h) never came: the serial number alone selects nothing.
  EXPECT_TRUE(feed("7E5#43BEBAFECA000000").empty());
  EXPECT_EQ(slave.state(), LssState::Waiting);
}

TEST_F(LssSlaveTest, SwitchStateSelectiveAfterAMismatchStartsOverAtTheVendorId) {
  feed("7E5#4004030201000000");
  feed("7E5#410C0A0000000000");  // another product code
  feed("7E5#4202000100000000");
  EXPECT_TRUE(feed("7E5#43BEBAFECA000000").empty());
  // A complete sequence afterwards selects it.
  feed("7E5#4004030201000000");
  feed("7E5#410B0A0000000000");
  feed("7E5#4202000100000000");
  EXPECT_EQ(feed("7E5#43BEBAFECA000000"), Frames{"7E4#4400000000000000"});
}

TEST_F(LssSlaveTest, SwitchStateSelectiveIsIgnoredInConfiguration) {
  configuration();
  feed("7E5#4004030201000000", false);
  feed("7E5#410B0A0000000000", false);
  feed("7E5#4202000100000000", false);
  EXPECT_TRUE(feed("7E5#43BEBAFECA000000", false).empty());
}

// --- configure node-ID (11h, byte 1 node-ID; answer byte 1 error code) --------------------------

TEST_F(LssSlaveTest, ConfigureNodeId11AnswersErrorCode0AndKeepsItPending) {
  configuration();
  EXPECT_EQ(feed("7E5#1105000000000000"), Frames{"7E4#1100000000000000"});
  EXPECT_EQ(slave.pending_node_id(), 5);
  EXPECT_EQ(slave.active_node_id(), lss::kUnconfigured);
  EXPECT_EQ(events.back().kind, Kind::NodeIdConfigured);
  EXPECT_EQ(events.back().node_id, 5);
}

TEST_F(LssSlaveTest, ConfigureNodeIdOutOfRangeAnswersErrorCode1) {
  configuration();
  EXPECT_EQ(feed("7E5#1180000000000000"), Frames{"7E4#1101000000000000"});  // 128
  EXPECT_EQ(feed("7E5#1100000000000000"), Frames{"7E4#1101000000000000"});  // 0
  EXPECT_EQ(slave.pending_node_id(), lss::kUnconfigured);
  // FFh: back to not configured.
  EXPECT_EQ(feed("7E5#11FF000000000000"), Frames{"7E4#1100000000000000"});
}

TEST_F(LssSlaveTest, ConfigureServicesAreIgnoredInWaiting) {
  EXPECT_TRUE(feed("7E5#1105000000000000", false).empty());
  EXPECT_TRUE(feed("7E5#1700000000000000", false).empty());
  EXPECT_TRUE(feed("7E5#5A00000000000000", false).empty());
  EXPECT_EQ(slave.pending_node_id(), lss::kUnconfigured);
}

TEST_F(LssSlaveTest, UnconfiguredDeviceLeavingConfigurationWithANodeIdStartsWithIt) {
  configuration();
  feed("7E5#1105000000000000");
  feed("7E5#0400000000000000");
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().kind, Kind::NodeIdActivate);
  EXPECT_EQ(events.back().node_id, 5);
}

// --- configure bit timing (13h, byte 1 table selector, byte 2 table index) ----------------------

TEST_F(LssSlaveTest, ConfigureBitTiming13Index3Is250KbitAndAnswersErrorCode0) {
  configuration();
  EXPECT_EQ(feed("7E5#1300030000000000"), Frames{"7E4#1300000000000000"});
  EXPECT_EQ(slave.pending_bit_timing_index(), 3);
  EXPECT_EQ(lss::bit_rate_kbit(3), 250);
}

TEST_F(LssSlaveTest, ConfigureBitTimingReservedIndexOtherTableOrAutoAnswersErrorCode1) {
  configuration();
  EXPECT_EQ(feed("7E5#1300050000000000"), Frames{"7E4#1301000000000000"});  // 5 reserved
  EXPECT_EQ(feed("7E5#1301020000000000"), Frames{"7E4#1301000000000000"});  // table 1
  EXPECT_EQ(feed("7E5#1300090000000000"), Frames{"7E4#1301000000000000"});  // auto: not here
  EXPECT_FALSE(slave.pending_bit_timing_index().has_value());
}

TEST_F(LssSlaveTest, ActivateBitTiming15CarriesTheSwitchDelayLittleEndianWithoutAnswer) {
  configuration();
  feed("7E5#1300040000000000");                       // 125 kbit/s
  EXPECT_TRUE(feed("7E5#15E8030000000000").empty());  // 1000 ms
  ASSERT_EQ(events.back().kind, Kind::BitTimingActivate);
  EXPECT_EQ(events.back().switch_delay_ms, 1000);
  EXPECT_EQ(events.back().bit_timing_index, 4);
}

// --- store configuration (17h; answer byte 1 error code) --------------------------------------

TEST_F(LssSlaveTest, StoreConfiguration17AnswersErrorCode0AndAsksTheOwnerToStore) {
  configuration();
  feed("7E5#1107000000000000");
  EXPECT_EQ(feed("7E5#1700000000000000"), Frames{"7E4#1700000000000000"});
  EXPECT_EQ(events.back().kind, Kind::StoreRequested);
  EXPECT_EQ(events.back().node_id, 7);
}

TEST(LssSlave, StoreConfigurationNotSupportedAnswersErrorCode1) {
  LssSlaveOptions options;
  options.store_supported = false;
  LssSlave slave(kAddress, 3, options);
  LssSlave::Output out;
  slave.on_frame(*from_candump("7E5#0401000000000000"), TimePoint{}, out);
  slave.on_frame(*from_candump("7E5#1700000000000000"), TimePoint{}, out);
  ASSERT_EQ(out.frames.size(), 1u);
  EXPECT_EQ(to_candump(out.frames[0]), "7E4#1701000000000000");
}

// --- inquire identity (5Ah-5Dh, value bytes 1-4) and node-ID (5Eh, byte 1) ---------------------

TEST_F(LssSlaveTest, InquireIdentity5ATo5DAnswersThe1018hValuesLittleEndian) {
  configuration();
  EXPECT_EQ(feed("7E5#5A00000000000000"), Frames{"7E4#5A04030201000000"});
  EXPECT_EQ(feed("7E5#5B00000000000000"), Frames{"7E4#5B0B0A0000000000"});
  EXPECT_EQ(feed("7E5#5C00000000000000"), Frames{"7E4#5C02000100000000"});
  EXPECT_EQ(feed("7E5#5D00000000000000"), Frames{"7E4#5DBEBAFECA000000"});
}

TEST_F(LssSlaveTest, InquireNodeId5EAnswersTheActiveNodeIdFFhWhenUnconfigured) {
  configuration();
  feed("7E5#1105000000000000");  // pending only
  EXPECT_EQ(feed("7E5#5E00000000000000"), Frames{"7E4#5EFF000000000000"});
}

// --- identify remote slave (46h-4Bh, answer 4Fh) and non-configured (4Ch, answer 50h) ---------

TEST_F(LssSlaveTest, IdentifyRemoteSlave46To4BInsideTheRangeAnswers4F) {
  feed("7E5#4604030201000000");  // vendor-ID
  feed("7E5#470B0A0000000000");  // product code
  feed("7E5#4800000000000000");  // revision low 0
  feed("7E5#49FFFFFFFF000000");  // revision high FFFFFFFFh
  feed("7E5#4ABEBAFECA000000");  // serial low = the serial (bounds included)
  EXPECT_EQ(feed("7E5#4BBEBAFECA000000"), Frames{"7E4#4F00000000000000"});
}

TEST_F(LssSlaveTest, IdentifyRemoteSlaveOutsideTheSerialRangeIsNotAnswered) {
  feed("7E5#4604030201000000");
  feed("7E5#470B0A0000000000");
  feed("7E5#4800000000000000");
  feed("7E5#49FFFFFFFF000000");
  feed("7E5#4A00000000000000");
  EXPECT_TRUE(feed("7E5#4BBDBAFECA000000").empty());  // high CAFEBABDh < serial
}

TEST_F(LssSlaveTest, IdentifyNonConfiguredRemoteSlave4CIsAnswered50WhileUnconfigured) {
  EXPECT_EQ(feed("7E5#4C00000000000000"), Frames{"7E4#5000000000000000"});
  LssSlave configured(kAddress, 5);
  LssSlave::Output out;
  configured.on_frame(*from_candump("7E5#4C00000000000000"), TimePoint{}, out);
  EXPECT_TRUE(out.frames.empty());
}

// --- Fastscan (51h: IDNumber bytes 1-4, BitCheck 5, LSSSub 6, LSSNext 7; answer 4Fh) ----------

TEST_F(LssSlaveTest, FastscanBitCheck80hIsAnsweredByAnUnconfiguredDevice) {
  EXPECT_EQ(feed("7E5#5100000000800000"), Frames{"7E4#4F00000000000000"});
}

TEST_F(LssSlaveTest, FastscanComparesBitsFromBitCheckUp) {
  feed("7E5#5100000000800000");
  // Vendor-ID 01020304h: bits 31..25 are 0, bit 24 is 1.
  EXPECT_EQ(feed("7E5#5100000000190000"), Frames{"7E4#4F00000000000000"});  // bits 31..25 = 0
  EXPECT_TRUE(feed("7E5#5100000000180000").empty());                        // bit 24 = 0: no
  EXPECT_EQ(feed("7E5#5100000001180000"), Frames{"7E4#4F00000000000000"});  // bit 24 = 1
}

TEST_F(LssSlaveTest, FastscanConfirmingAllFourPartsEntersConfiguration) {
  feed("7E5#5100000000800000");
  EXPECT_EQ(feed("7E5#5104030201000001").size(), 1u);  // vendor-ID, LSSNext 1
  EXPECT_EQ(feed("7E5#510B0A0000000102").size(), 1u);  // product code, LSSNext 2
  EXPECT_EQ(feed("7E5#5102000100000203").size(), 1u);  // revision, LSSNext 3
  EXPECT_EQ(slave.state(), LssState::Waiting);
  EXPECT_EQ(feed("7E5#51BEBAFECA000300"), Frames{"7E4#4F00000000000000"});  // serial, LSSNext 0
  EXPECT_EQ(slave.state(), LssState::Configuration);
}

TEST_F(LssSlaveTest, FastscanForAnotherPartThanTheDevicesPositionIsNotAnswered) {
  feed("7E5#5100000000800000");
  EXPECT_TRUE(feed("7E5#510B0A0000000102").empty());  // LSSSub 1 before the vendor-ID matched
}

TEST(LssSlave, FastscanIsNotAnsweredByAConfiguredDevice) {
  LssSlave slave(kAddress, 5);
  LssSlave::Output out;
  slave.on_frame(*from_candump("7E5#5100000000800000"), TimePoint{}, out);
  EXPECT_TRUE(out.frames.empty());
}

TEST_F(LssSlaveTest, FramesWithoutEightDataBytesAreIgnored) {
  EXPECT_TRUE(feed("7E5#04010000000000", false).empty());
  EXPECT_TRUE(feed("7E5#4C", false).empty());
  EXPECT_EQ(slave.state(), LssState::Waiting);
}

}  // namespace
}  // namespace nmt

// --- the LSS slave inside SlaveNode (tests/data/sim_device.eds with LSS_Supported=1) -----------

namespace nmt {
namespace {

// Powers `device` on at `now` (nothing it reports at power-on is looked at here).
template <class Device>
void power_on_at(Device& device, TimePoint now) {
  typename Device::Output out;
  device.start(now, out);
}

cfg::DeviceDescription lss_device() {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sim_device.eds");
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  auto device = result.device.value_or(cfg::DeviceDescription{});
  device.device_info.set("LSS_Supported", "1");
  return device;
}

struct LssNode {
  std::unique_ptr<SlaveNode> node;
  Frames sent;
  explicit LssNode(std::unique_ptr<SlaveNode> n) : node(std::move(n)) {}
  bool frame(std::string_view candump, TimePoint now = TimePoint{}) {
    SlaveNode::Output out;
    const bool taken = node->on_frame(*from_candump(candump), now, out);
    sent.clear();
    for (const auto& f : out.frames) sent.push_back(to_candump(f));
    return taken;
  }
  Frames timer(TimePoint now = TimePoint{}) {
    SlaveNode::Output out;
    node->on_timer(now, out);
    sent.clear();
    for (const auto& f : out.frames) sent.push_back(to_candump(f));
    return sent;
  }
};

LssNode unconfigured() {
  auto created = SlaveNode::create_unconfigured(lss_device());
  EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
  return LssNode(std::move(created).value());
}

TEST(SlaveNodeLss, UnconfiguredDevicePowersOnWithoutBootUpAndServesNoNmtOrSdo) {
  auto d = unconfigured();
  power_on_at(*d.node, TimePoint{});
  EXPECT_FALSE(d.node->has_node_id());
  EXPECT_FALSE(d.node->next_deadline().has_value());
  EXPECT_TRUE(d.timer().empty());
  EXPECT_FALSE(d.frame("000#0100"));
  EXPECT_FALSE(d.frame("601#4000100000000000"));
  EXPECT_TRUE(d.sent.empty());
  // It answers LSS: identify non-configured remote slave.
  EXPECT_TRUE(d.frame("7E5#4C00000000000000"));
  EXPECT_EQ(d.sent, Frames{"7E4#5000000000000000"});
}

TEST(SlaveNodeLss, LssAddressIs1018hSub1To4) {
  auto d = unconfigured();
  ASSERT_NE(d.node->lss(), nullptr);
  // sim_device.eds: vendor 7E57C0DEh, product 00000508h, revision 00020001h, serial 0.
  EXPECT_EQ(d.node->lss()->address(), (LssAddress{0x7E57C0DE, 0x00000508, 0x00020001, 0}));
  auto dcf = lss_device();
  dcf.commissioning.emplace();
  dcf.commissioning->lss_serial_number = 0x00C0FFEE;
  auto node = SlaveNode::create(dcf, *cfg::NodeId::from(3));
  ASSERT_TRUE(node.ok());
  EXPECT_EQ(node.value()->lss()->address().serial, 0x00C0FFEEu);
}

TEST(SlaveNodeLss, Sdo1018hSub4AnswersTheLssSerialNumberTheDeviceAnswersLssWith) {
  // lss_io_1003.dcf: 1018h sub 4 DefaultValue 00001001h (the EDS's), [DeviceComissioning]
  // LSS_SerialNumber 00001003h: CiA 305's LSS address is 1018h sub 1-4, so the device has one
  // serial number, 00001003h, in LSS inquire serial number (5Dh) and in SDO 1018h sub 4.
  auto read = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/lss/lss_io_1003.dcf");
  ASSERT_TRUE(read.device.has_value()) << read.diagnostics.format();
  auto created = SlaveNode::create(*read.device, *cfg::NodeId::from(3));
  ASSERT_TRUE(created.ok()) << created.error().message;
  LssNode d(std::move(created).value());
  power_on_at(*d.node, TimePoint{});
  d.timer();
  EXPECT_TRUE(d.frame("603#4018100400000000"));
  EXPECT_EQ(d.sent, Frames{"583#4318100403100000"});
  d.frame("7E5#0401000000000000");
  EXPECT_TRUE(d.frame("7E5#5D00000000000000"));
  EXPECT_EQ(d.sent, Frames{"7E4#5D03100000000000"});
  // A node-ID by LSS rebuilds the dictionary for node 5 (its $NODEID values): still 00001003h.
  d.frame("7E5#1105000000000000");
  d.frame("7E5#0400000000000000");
  d.frame("000#8203", TimePoint{Duration{1000}});
  d.timer(TimePoint{Duration{1000}});
  EXPECT_TRUE(d.frame("605#4018100400000000", TimePoint{Duration{2000}}));
  EXPECT_EQ(d.sent, Frames{"585#4318100403100000"});
}

TEST(SlaveNodeLss, LssSerialNumberIs1018hSub4AlsoWhereTheFileHasNoSub4) {
  // drive_node3.dcf has 1018h sub 1 only: the device gets a sub 4 (UNSIGNED32 ro) with the
  // LSS serial number, and 1018h sub 0 counts it.
  auto read =
      cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/network/nodes/drive_node3.dcf");
  ASSERT_TRUE(read.device.has_value());
  read.device->commissioning.emplace();
  read.device->commissioning->lss_serial_number = 0x00C0FFEE;
  auto created = SlaveNode::create(*read.device, *cfg::NodeId::from(3));
  ASSERT_TRUE(created.ok()) << created.error().message;
  LssNode d(std::move(created).value());
  power_on_at(*d.node, TimePoint{});
  d.timer();
  EXPECT_TRUE(d.frame("603#4018100400000000"));
  EXPECT_EQ(d.sent, Frames{"583#43181004EEFFC000"});
  EXPECT_TRUE(d.frame("603#4018100000000000"));
  EXPECT_EQ(d.sent, Frames{"583#4F18100004000000"});
}

TEST(SlaveNodeLss, LssAddressTakesDeviceInfoWhere1018hHasNoValue) {
  // drive_node3.dcf has 1018h sub 1 (00000ABCh) only; [DeviceInfo] says ProductNumber 402h and
  // RevisionNumber 00020004h, which the device answers in 1018h sub 2/3 as well.
  auto read =
      cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/network/nodes/drive_node3.dcf");
  ASSERT_TRUE(read.device.has_value());
  read.device->device_info.set("LSS_Supported", "1");
  auto node = SlaveNode::create_unconfigured(*read.device);
  ASSERT_TRUE(node.ok()) << node.error().message;
  EXPECT_EQ(node.value()->lss()->address(), (LssAddress{0x00000ABC, 0x00000402, 0x00020004, 0}));
}

TEST(SlaveNodeLss, DeviceFileWithoutLssSupportedCannotStartUnconfigured) {
  auto device = lss_device();
  device.device_info.set("LSS_Supported", "0");
  EXPECT_FALSE(SlaveNode::create_unconfigured(device).ok());
  auto node = SlaveNode::create(device, *cfg::NodeId::from(3));
  ASSERT_TRUE(node.ok());
  EXPECT_EQ(node.value()->lss(), nullptr);
}

TEST(SlaveNodeLss, NodeIdByLssThenBootUpAndTheDictionaryOfThatNodeId) {
  auto d = unconfigured();
  power_on_at(*d.node, TimePoint{});
  d.frame("7E5#0401000000000000");
  d.frame("7E5#1105000000000000");
  EXPECT_EQ(d.sent, Frames{"7E4#1100000000000000"});
  d.frame("7E5#1700000000000000");
  EXPECT_EQ(d.sent, Frames{"7E4#1700000000000000"});
  d.frame("7E5#0400000000000000", TimePoint{Duration{1000}});
  EXPECT_TRUE(d.node->has_node_id());
  EXPECT_EQ(d.node->next_deadline(), TimePoint{Duration{1000}});
  EXPECT_EQ(d.timer(TimePoint{Duration{1000}}), Frames{"705#00"});  // boot-up of node 5
  // 1014h = $NODEID+80h of node 5; SDO on 605h/585h.
  EXPECT_TRUE(d.frame("605#4014100000000000"));
  EXPECT_EQ(d.sent, Frames{"585#4314100085000000"});
  // Stored: the next power-on boots as node 5 at once.
  power_on_at(*d.node, TimePoint{Duration{2000}});
  EXPECT_EQ(d.timer(TimePoint{Duration{2000}}), Frames{"705#00"});
}

TEST(SlaveNodeLss, StoreConfigurationKeepsNodeIdAndBitRateForTheNextPowerOn) {
  // CiA 305 store configuration (17h) saves the pending node-ID and bit timing (13h 00h 03h:
  // table 0 index 3, 250 kbit/s) in non-volatile memory: lss_stored(), which another node of
  // the same file given it (set_lss_stored, what a saved state file does) powers on with.
  auto d = unconfigured();
  power_on_at(*d.node, TimePoint{});
  EXPECT_FALSE(d.node->lss_stored());
  d.frame("7E5#0401000000000000");
  d.frame("7E5#1105000000000000");
  d.frame("7E5#1300030000000000");
  EXPECT_EQ(d.sent, Frames{"7E4#1300000000000000"});
  d.frame("7E5#1700000000000000");
  EXPECT_EQ(d.sent, Frames{"7E4#1700000000000000"});
  ASSERT_TRUE(d.node->lss_stored());
  EXPECT_EQ(*d.node->lss_stored(), (LssStoredConfig{5, 3}));

  auto e = unconfigured();
  e.node->set_lss_stored(d.node->lss_stored());
  power_on_at(*e.node, TimePoint{});
  EXPECT_TRUE(e.node->has_node_id());
  EXPECT_EQ(e.node->lss()->bit_timing_index(), 3);
  EXPECT_EQ(e.timer(), Frames{"705#00"});
}

TEST(SlaveNodeLss, UnstoredNodeIdIsLostAtPowerOn) {
  auto d = unconfigured();
  power_on_at(*d.node, TimePoint{});
  d.frame("7E5#0401000000000000");
  d.frame("7E5#1105000000000000");
  d.frame("7E5#0400000000000000");
  EXPECT_EQ(d.timer(), Frames{"705#00"});
  power_on_at(*d.node, TimePoint{Duration{1000}});
  EXPECT_FALSE(d.node->has_node_id());
  EXPECT_TRUE(d.timer(TimePoint{Duration{1000}}).empty());
}

TEST(SlaveNodeLss, ConfiguredNodeTakesANewNodeIdAtResetCommunication) {
  auto created = SlaveNode::create(lss_device(), *cfg::NodeId::from(3));
  ASSERT_TRUE(created.ok());
  LssNode d(std::move(created).value());
  power_on_at(*d.node, TimePoint{});
  EXPECT_EQ(d.timer(), Frames{"703#00"});
  d.frame("7E5#0401000000000000");
  d.frame("7E5#1109000000000000");
  d.frame("7E5#0400000000000000");
  EXPECT_TRUE(d.timer().empty());  // still node 3 until the reset
  EXPECT_TRUE(d.frame("000#8203"));
  EXPECT_EQ(d.timer(), Frames{"709#00"});
  EXPECT_EQ(d.node->node_id(), *cfg::NodeId::from(9));
}

// tests/data/lss/lss_io.eds has no 1200h: the default SDO channel is 600h/580h + the node-ID
// (CiA 301 §7.3.3), the one LSS gave, not the one the dictionary was first built for.
cfg::DeviceDescription lss_io_without_1200h() {
  auto read = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/lss/lss_io.eds");
  EXPECT_TRUE(read.device.has_value());
  return *read.device;
}

TEST(SlaveNodeLss, DefaultSdoOfAFileWithout1200hFollowsTheNodeIdLssGave) {
  auto created = SlaveNode::create_unconfigured(lss_io_without_1200h());
  ASSERT_TRUE(created.ok()) << created.error().message;
  LssNode d(std::move(created).value());
  power_on_at(*d.node, TimePoint{});
  d.frame("7E5#0401000000000000");
  d.frame("7E5#1105000000000000");
  d.frame("7E5#0400000000000000");
  EXPECT_EQ(d.timer(), Frames{"705#00"});
  // 1000h of lss_io.eds: 00030191h.
  EXPECT_TRUE(d.frame("605#4000100000000000"));
  EXPECT_EQ(d.sent, Frames{"585#4300100091010300"});
  EXPECT_FALSE(d.frame("601#4000100000000000"));
}

TEST(SimulatedDeviceLss, UnconfiguredDeviceAnswersLssThroughItsFaults) {
  // The fault wrapper keeps frames from a node that has not booted; a node without node-ID
  // never boots until LSS gives it one, so LSS frames must reach it.
  auto created = SimulatedDevice::create_unconfigured(lss_io_without_1200h());
  ASSERT_TRUE(created.ok()) << created.error().message;
  auto device = std::move(created).value();
  power_on_at(device, TimePoint{});
  SimulatedDevice::Output out;
  EXPECT_TRUE(device.on_frame(*from_candump("7E5#4C00000000000000"), TimePoint{}, out));
  ASSERT_EQ(out.frames.size(), 1u);
  EXPECT_EQ(to_candump(out.frames[0]), "7E4#5000000000000000");
  auto without_lss = lss_io_without_1200h();
  without_lss.device_info.set("LSS_Supported", "0");
  EXPECT_FALSE(SimulatedDevice::create_unconfigured(without_lss).ok());
}

}  // namespace
}  // namespace nmt
