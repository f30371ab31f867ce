// A simulated device's non-volatile memory on disk (nmt/sim/device_state.hpp) and the node taking
// it back (SlaveNode::set_stored): what 1010h 'save' stored survives a new process, as a real
// device's survives a power cycle (CiA 301 §7.5.2.13), and a damaged file is refused.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "cfg/device_file.hpp"
#include "nmt/sim/device_state.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "scratch_dir.hpp"
#include "test_paths.hpp"

namespace {
using namespace cfg::literals;

// Powers `device` on at `now` (nothing it reports at power-on is looked at here).
template <class Device>
void power_on_at(Device& device, nmt::TimePoint now) {
  typename Device::Output out;
  device.start(now, out);
}

namespace fs = std::filesystem;

TEST(DeviceState, FormatsAndParsesBackTheSameValues) {
  // 1017h = 1000 ms (UNSIGNED16 E8h 03h on the bus), 1020h sub 1 = 0x11223344, an empty entry.
  const nmt::SavedValues values = {
      {0x101700, {0xE8, 0x03}}, {0x102001, {0x44, 0x33, 0x22, 0x11}}, {0x200000, {}}};
  const std::string text = nmt::format_device_state(5_node, {values, std::nullopt, {}});
  EXPECT_NE(text.find("\n1017sub00=E803\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\n1020sub01=44332211\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nend=3\n"), std::string::npos) << text;
  const auto parsed = nmt::parse_device_state(text, "f", 5_node);
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_EQ(parsed->values, values);
  EXPECT_FALSE(parsed->lss) << "LSS never stored";
}

TEST(DeviceState, KeepsWhatLssStoredAndNamesAnUnconfiguredDevicesFileByItsLssAddress) {
  // CiA 305 store configuration: node-ID 5 and bit timing index 3 (250 kbit/s) of the device
  // with LSS address 7E57C0DEh/00000305h/00010002h/00001001h (tests/data/lss/lss_io.eds).
  const nmt::LssAddress address{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
  const nmt::DeviceState state{{{0x101700, {0xE8, 0x03}}}, nmt::LssStoredConfig{5, 3}, {}};
  const std::string text = nmt::format_device_state(address, state);
  EXPECT_NE(text.find("\nlss=7E57C0DE:00000305:00010002:00001001\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nlss_node=5\nlss_bit_timing=3\nend=1\n"), std::string::npos) << text;
  const auto parsed = nmt::parse_device_state(text, "f", address);
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_EQ(*parsed, state);
  EXPECT_EQ(nmt::device_state_file("d", address),
            fs::path("d") / "lss-7E57C0DE-00000305-00010002-00001001.saved");
  EXPECT_EQ(nmt::device_state_file("d", 5_node), fs::path("d") / "node-05.saved");

  // Another device's file, a node's file, half the LSS lines, a node-ID out of range: refused.
  nmt::LssAddress other = address;
  other.serial = 0x1003;
  EXPECT_FALSE(nmt::parse_device_state(text, "f", other));
  EXPECT_FALSE(nmt::parse_device_state(text, "f", 5_node));
  EXPECT_FALSE(nmt::parse_device_state(nmt::format_device_state(5_node, state), "f", address));
  EXPECT_FALSE(nmt::parse_device_state("node=5\nlss_node=5\nend=0\n", "f", 5_node));
  const auto bad =
      nmt::parse_device_state("node=5\nlss_node=128\nlss_bit_timing=2\nend=0\n", "f", 5_node);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("f:2: error: lss_node=128"), std::string::npos)
      << bad.error().message;
  EXPECT_FALSE(
      nmt::parse_device_state("node=5\nlss_node=255\nlss_bit_timing=10\nend=0\n", "f", 5_node));
  EXPECT_TRUE(
      nmt::parse_device_state("node=5\nlss_node=255\nlss_bit_timing=9\nend=0\n", "f", 5_node));
}

TEST(DeviceState, RefusesATextCutShortAnotherNodesOrABadLine) {
  const std::string text =
      nmt::format_device_state(5_node, {{{0x101700, {0xE8, 0x03}}}, std::nullopt, {}});
  const auto cut = nmt::parse_device_state(text.substr(0, text.find("end=")), "f", 5_node);
  ASSERT_FALSE(cut);
  EXPECT_NE(cut.error().message.find("f:3: error: "), std::string::npos) << cut.error().message;
  EXPECT_NE(cut.error().message.find("cut short"), std::string::npos);
  EXPECT_FALSE(nmt::parse_device_state(text, "f", 6_node));
  EXPECT_FALSE(nmt::parse_device_state("node=5\n1017sub00=E80\nend=1\n", "f", 5_node));
  EXPECT_FALSE(nmt::parse_device_state("node=5\n1017sub00=E803\nend=2\n", "f", 5_node));
  EXPECT_FALSE(nmt::parse_device_state("node=5\n1017sub0=E803\nend=1\n", "f", 5_node));
}

// A device with 1017h (rw) and 1010h sub 1, built from a small DCF text.
nmt::SimulatedDevice device() {
  const std::string dcf =
      "[DeviceInfo]\nVendorNumber=0xABC\n[DeviceComissioning]\nNodeID=5\n"
      "[MandatoryObjects]\nSupportedObjects=2\n1=0x1000\n2=0x1001\n"
      "[OptionalObjects]\nSupportedObjects=2\n1=0x1010\n2=0x1017\n"
      "[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
      "DefaultValue=0x191\nPDOMapping=0\n"
      "[1001]\nParameterName=Error register\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\n"
      "DefaultValue=0\nPDOMapping=0\n"
      "[1010]\nParameterName=Store parameters\nObjectType=0x8\nSubNumber=2\n"
      "[1010sub0]\nParameterName=Highest\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\n"
      "DefaultValue=1\nPDOMapping=0\n"
      "[1010sub1]\nParameterName=Save all\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
      "DefaultValue=1\nPDOMapping=0\n"
      "[1017]\nParameterName=Producer heartbeat time\nObjectType=0x7\nDataType=0x0006\n"
      "AccessType=rw\nDefaultValue=0\nPDOMapping=0\n";
  auto read = cfg::parse_device_description(dcf);
  EXPECT_TRUE(read.ok()) << "the DCF parses";
  auto created = nmt::SimulatedDevice::create(*read.device, 5);
  EXPECT_TRUE(created);
  return std::move(created).value();
}

TEST(DeviceState, ADeviceGivenItsSavedValuesHasThemAfterPowerOn) {
  // CiA 301 §7.5.2.13: saved parameters are what the device starts with after a power cycle.
  test_support::ScratchDir dir;
  nmt::SimulatedDevice first = device();
  power_on_at(first, nmt::TimePoint{});
  ASSERT_TRUE(first.node().dictionary().set_unsigned(0x1017, 0, 1000));
  // What a 1010h sub 1 'save' stores, here set directly: the node's stored values.
  first.node().set_stored({{0x101700, {0xE8, 0x03}}, {0x100000, {0x00, 0x00, 0x00, 0x00}}});
  EXPECT_EQ(first.node().stored().size(), 1U) << "1000h is read-only: no stored parameter";
  ASSERT_TRUE(nmt::save_device_state(dir.path(), 5_node, first.node()));

  nmt::SimulatedDevice second = device();
  auto loaded = nmt::load_device_state(dir.path(), 5_node);
  ASSERT_TRUE(loaded) << loaded.error().message;
  ASSERT_TRUE(loaded->has_value());
  nmt::restore_device_state(second.node(), std::move(**loaded));
  EXPECT_EQ(second.node().dictionary().get_unsigned(0x1017, 0), 0U) << "not before power-on";
  power_on_at(second, nmt::TimePoint{});
  EXPECT_EQ(second.node().dictionary().get_unsigned(0x1017, 0), 1000U);

  auto none = nmt::load_device_state(dir.path(), 6_node);
  ASSERT_TRUE(none);
  EXPECT_FALSE(none->has_value()) << "no file: the device never saved";
}

TEST(DeviceState, AnUnconfiguredDeviceLssGaveNodeId5BootsAsNode5InTheNextProcess) {
  // CiA 305: a node-ID stored with store configuration (17h) is the one the device powers on
  // with. The device of lss_io.eds starts unconfigured, LSS gives it node-ID 5 and stores it;
  // a new device from the same file with the saved state boots at once as node 5 (705h#00).
  test_support::ScratchDir dir;
  auto read = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/lss/lss_io.eds");
  ASSERT_TRUE(read.device) << read.diagnostics.format();
  auto frames = [](nmt::SlaveNode& n, std::string_view candump) {
    nmt::SlaveNode::Output out;
    n.on_frame(*nmt::from_candump(candump), nmt::TimePoint{}, out);
    std::vector<std::string> sent;
    for (const auto& f : out.frames) sent.push_back(nmt::to_candump(f));
    return sent;
  };
  auto first = nmt::SlaveNode::create_unconfigured(*read.device);
  ASSERT_TRUE(first) << first.error().message;
  nmt::SlaveNode& one = *first.value();
  const nmt::DeviceStateOwner owner(one.lss()->address());
  power_on_at(one, nmt::TimePoint{});
  frames(one, "7E5#0401000000000000");  // switch state global: configuration
  EXPECT_EQ(frames(one, "7E5#1105000000000000"), std::vector<std::string>{"7E4#1100000000000000"});
  EXPECT_EQ(frames(one, "7E5#1700000000000000"), std::vector<std::string>{"7E4#1700000000000000"});
  ASSERT_TRUE(one.lss_stored());
  EXPECT_EQ(*one.lss_stored(), (nmt::LssStoredConfig{5, 2})) << "500 kbit/s: index 2";
  ASSERT_TRUE(nmt::save_device_state(dir.path(), owner, one));
  EXPECT_TRUE(fs::exists(dir.path() / "lss-7E57C0DE-00000305-00010002-00001001.saved"));

  auto second = nmt::SlaveNode::create_unconfigured(*read.device);
  ASSERT_TRUE(second);
  nmt::SlaveNode& two = *second.value();
  auto loaded = nmt::load_device_state(dir.path(), owner);
  ASSERT_TRUE(loaded) << loaded.error().message;
  ASSERT_TRUE(loaded->has_value());
  nmt::restore_device_state(two, std::move(**loaded));
  power_on_at(two, nmt::TimePoint{});
  EXPECT_TRUE(two.has_node_id());
  nmt::SlaveNode::Output out;
  two.on_timer(nmt::TimePoint{}, out);
  ASSERT_EQ(out.frames.size(), 1U);
  EXPECT_EQ(nmt::to_candump(out.frames[0]), "705#00");

  // Without the state the same file powers on unconfigured: no boot-up.
  auto third = nmt::SlaveNode::create_unconfigured(*read.device);
  ASSERT_TRUE(third);
  power_on_at(*third.value(), nmt::TimePoint{});
  EXPECT_FALSE(third.value()->has_node_id());
}

}  // namespace
