// The configuration manager as the NMT master's ConfigurationSource, and its abort codes as the
// SDO server's.
#include "nmt/manager/configuration_manager_source.hpp"

#include <gtest/gtest.h>

#include <memory>

namespace nmt {
namespace {

TEST(ConfigurationManagerSource, GivesTheManagersConfigurationAsItChanges) {
  auto manager = std::make_shared<cfg::ConfigManager>();
  const ConfigurationManagerSource source(manager);
  const cfg::NodeId node = *cfg::NodeId::from(5);
  EXPECT_EQ(source.configuration(node), std::nullopt);
  // 1017h = 1000 ms, written over SDO into 1F22h sub 5 (DSP 302 §6.2 stream).
  const std::vector<cfg::ObjectWrite> writes{{0x1017, 0, {0xE8, 0x03}}};
  ASSERT_TRUE(manager->write(0x1F22, 5, cfg::encode_concise_dcf(writes)).ok());
  EXPECT_EQ(source.configuration(node), writes);
  EXPECT_EQ(source.program(node), std::nullopt);
}

TEST(ConfigurationManagerSource, DataSetEmptyIsAbort08000024) {
  // DSP 302 §6.1: "Data set empty", 0800 0024h.
  const cfg::ConfigManager manager;
  const auto read = manager.read(0x1F20, 1);
  EXPECT_EQ(read.abort, SdoAbort::NoDataAvailable);
  EXPECT_EQ(static_cast<std::uint32_t>(read.abort), 0x08000024U);
}

}  // namespace
}  // namespace nmt
