// A simulated device's non-volatile memory on disk (nmt/device_state.hpp) and the node taking
// it back (SlaveNode::set_stored): what 1010h 'save' stored survives a new process, as a real
// device's survives a power cycle (CiA 301 §7.5.2.13), and a damaged file is refused.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "cfg/device_file.hpp"
#include "nmt/device_state.hpp"
#include "nmt/simulated_device.hpp"

namespace {

namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("device_state_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

cfg::NodeId node(int n) {
  return *cfg::NodeId::from(static_cast<std::uint8_t>(n));
}

TEST(DeviceState, FormatsAndParsesBackTheSameValues) {
  // 1017h = 1000 ms (UNSIGNED16 E8h 03h on the bus), 1020h sub 1 = 0x11223344, an empty entry.
  const nmt::SavedValues values = {
      {0x101700, {0xE8, 0x03}}, {0x102001, {0x44, 0x33, 0x22, 0x11}}, {0x200000, {}}};
  const std::string text = nmt::format_device_state(node(5), values);
  EXPECT_NE(text.find("\n1017sub00=E803\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\n1020sub01=44332211\n"), std::string::npos) << text;
  EXPECT_NE(text.find("\nend=3\n"), std::string::npos) << text;
  const auto parsed = nmt::parse_device_state(text, "f", node(5));
  ASSERT_TRUE(parsed) << parsed.error().message;
  EXPECT_EQ(*parsed, values);
}

TEST(DeviceState, RefusesATextCutShortAnotherNodesOrABadLine) {
  const std::string text = nmt::format_device_state(node(5), {{0x101700, {0xE8, 0x03}}});
  const auto cut = nmt::parse_device_state(text.substr(0, text.find("end=")), "f", node(5));
  ASSERT_FALSE(cut);
  EXPECT_NE(cut.error().message.find("f:3: error: "), std::string::npos) << cut.error().message;
  EXPECT_NE(cut.error().message.find("cut short"), std::string::npos);
  EXPECT_FALSE(nmt::parse_device_state(text, "f", node(6)));
  EXPECT_FALSE(nmt::parse_device_state("node=5\n1017sub00=E80\nend=1\n", "f", node(5)));
  EXPECT_FALSE(nmt::parse_device_state("node=5\n1017sub00=E803\nend=2\n", "f", node(5)));
  EXPECT_FALSE(nmt::parse_device_state("node=5\n1017sub0=E803\nend=1\n", "f", node(5)));
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
  TempDir dir;
  nmt::SimulatedDevice first = device();
  first.power_on(nmt::TimePoint{});
  ASSERT_TRUE(first.node().dictionary().set_unsigned(0x1017, 0, 1000));
  // What a 1010h sub 1 'save' stores, here set directly: the node's stored values.
  first.node().set_stored({{0x101700, {0xE8, 0x03}}, {0x100000, {0x00, 0x00, 0x00, 0x00}}});
  EXPECT_EQ(first.node().stored().size(), 1U) << "1000h is read-only: no stored parameter";
  ASSERT_TRUE(nmt::save_device_state(dir.path(), first.node()));

  nmt::SimulatedDevice second = device();
  auto loaded = nmt::load_device_state(dir.path(), node(5));
  ASSERT_TRUE(loaded) << loaded.error().message;
  ASSERT_TRUE(loaded->has_value());
  second.node().set_stored(std::move(**loaded));
  EXPECT_EQ(second.node().dictionary().get_unsigned(0x1017, 0), 0U) << "not before power-on";
  second.power_on(nmt::TimePoint{});
  EXPECT_EQ(second.node().dictionary().get_unsigned(0x1017, 0), 1000U);

  auto none = nmt::load_device_state(dir.path(), node(6));
  ASSERT_TRUE(none);
  EXPECT_FALSE(none->has_value()) << "no file: the device never saved";
}

}  // namespace
