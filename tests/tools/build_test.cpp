// cfgmgr build end to end on the sample network (samples/network): the outputs are read back,
// the master DCF through the DCF reader and the concise DCFs through the decoder, and compared
// with the network's own values (load_network of the same project file) and the spec's rules.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/dynamic_channels.hpp"
#include "cfg/network.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "tool_test_support.hpp"

namespace {

using ::testing::HasSubstr;
using tool_test::cfgmgr;
using tool_test::RunResult;
using tool_test::sample_network;
using tool_test::ScratchDir;

std::vector<std::uint8_t> bytes_of(const std::string& path) {
  const std::string text = tool_test::slurp(path);
  return {text.begin(), text.end()};
}

// The master DCF's configured UNSIGNED32 (ParameterValue, else DefaultValue).
std::uint32_t u32(const cfg::DeviceDescription& dcf, std::uint16_t index, std::uint8_t sub) {
  const cfg::SubObject* s = dcf.sub(index, sub);
  if (s == nullptr || !s->configured_value()) return 0xFFFFFFFF;
  return static_cast<std::uint32_t>(
      cfg::parse_value(cfg::DataType::Unsigned32, *s->configured_value())->as_unsigned());
}

class Build : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto r = cfgmgr(dir_, {"build", sample_network("nodelist.cpj"), "-o", dir_ / "out"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    output_ = r.out;
    auto read = cfg::read_device_file(dir_ / "out/master.dcf");
    ASSERT_TRUE(read.ok()) << read.diagnostics.format();
    master_ = std::move(*read.device);
    auto load = cfg::load_network(sample_network("nodelist.cpj"));
    ASSERT_TRUE(load.ok()) << load.diagnostics.format();
    network_ = std::move(*load.network);
  }
  ScratchDir dir_;
  std::string output_;
  cfg::DeviceDescription master_;
  cfg::Network network_;
};

// DSP 302 v3.2.1 §6.2: 1F22h sub N holds node N's concise DCF; the files decode to exactly the
// writes the network configures node N with.
TEST_F(Build, EveryNodesConciseDcfDecodesToItsWrites) {
  ASSERT_EQ(network_.nodes.size(), 3U);
  for (const auto& node : network_.nodes) {
    const std::string name = "node" + std::to_string(node.node_id.value()) + ".bin";
    const cfg::SubObject* entry = master_.sub(cfg::object::kConciseDcf, node.node_id.value());
    ASSERT_NE(entry, nullptr);
    EXPECT_EQ(entry->download_file.value_or(""), name);
    EXPECT_EQ(entry->upload_file.value_or(""), name);
    const auto decoded = cfg::decode_concise_dcf(bytes_of(dir_ / ("out/" + name)));
    ASSERT_TRUE(decoded) << decoded.error().message;
    EXPECT_EQ(*decoded, node.writes) << name;
  }
  EXPECT_EQ(master_.sub(cfg::object::kConciseDcf, 5)->download_file.value_or(""), "");
  EXPECT_THAT(output_, HasSubstr("node 3 (axis_x), 23 entries"));
}

// CiA 302-2 §6: 1F81h sub 3 = 0Dh (bit 0 slave, bit 2 boot, bit 3 mandatory); 1F84h sub 3 =
// node 3's 1000h (drive_node3.dcf: 0x00020192); 1016h: node 3 produces heartbeat every 500 ms
// (its 1017h), consumed at 2 x 500 + 100 ms = 1100 ms (0x044C) (cfg/network.hpp).
TEST_F(Build, TheMasterDcfHasTheDerivedMasterObjects) {
  ASSERT_TRUE(master_.commissioning.has_value());
  EXPECT_TRUE(master_.commissioning->canopen_manager.value_or(false));
  EXPECT_EQ(master_.node_id(), 0x7F);
  EXPECT_EQ(master_.commissioning->network_name, "sample cell");
  EXPECT_EQ(u32(master_, cfg::object::kNmtStartup, 0), 1U);
  EXPECT_EQ(u32(master_, cfg::object::kSlaveAssignment, 3), 0x0DU);
  EXPECT_EQ(u32(master_, cfg::object::kSlaveAssignment, 5), 0U);
  EXPECT_EQ(u32(master_, cfg::object::kDeviceTypeIdentification, 3), 0x00020192U);
  EXPECT_EQ(u32(master_, cfg::object::kDeviceTypeIdentification, 2), 0x000F0191U);
  bool consumer = false;
  for (std::uint8_t sub = 1; sub <= 127; ++sub) {
    consumer = consumer || u32(master_, cfg::object::kConsumerHeartbeatTime, sub) == 0x0003044CU;
  }
  EXPECT_TRUE(consumer);
  // 1F26h/1F27h: the stamp of each node's configuration, so that 1020h matches after a push.
  for (const auto& node : network_.nodes) {
    const auto stamp = cfg::configuration_stamp(cfg::encode_concise_dcf(node.writes));
    EXPECT_EQ(u32(master_, cfg::object::kExpectedConfigurationDate, node.node_id.value()),
              stamp.days);
    EXPECT_EQ(u32(master_, cfg::object::kExpectedConfigurationTime, node.node_id.value()),
              stamp.ms);
  }
}

// The master DCF alone describes the network: loading it gives the same nodes, writes and
// master values as the project file.
TEST_F(Build, TheMasterDcfAloneLoadsAsTheSameNetwork) {
  auto again = cfg::load_network(dir_ / "out/master.dcf");
  ASSERT_TRUE(again.ok()) << again.diagnostics.format();
  ASSERT_EQ(again.network->nodes.size(), network_.nodes.size());
  for (std::size_t i = 0; i < network_.nodes.size(); ++i) {
    EXPECT_EQ(again.network->nodes[i].node_id, network_.nodes[i].node_id);
    EXPECT_EQ(again.network->nodes[i].writes, network_.nodes[i].writes);
  }
  EXPECT_EQ(again.network->master_node_id, cfg::NodeId::from(0x7F));
  const auto check = cfgmgr(dir_, {"check", "--network", dir_ / "out/master.dcf"});
  EXPECT_EQ(check.exit_code, 0) << check.err;
}

TEST(BuildErrors, ExitCodes) {
  ScratchDir dir;
  EXPECT_EQ(cfgmgr(dir, {"build", sample_network("nodelist.cpj")}).exit_code, 2);  // -o is required
  EXPECT_EQ(
      cfgmgr(dir, {"build", sample_network("nodelist.cpj"), "-o", dir / "o", "--node-id", "3"})
          .exit_code,
      2);  // node 3 is a slave
  EXPECT_EQ(cfgmgr(dir, {"build", tool_test::data_path("network_check/clash.cpj"), "-o", dir / "o"})
                .exit_code,
            1);
  EXPECT_FALSE(std::filesystem::exists(dir / "o"));
  EXPECT_EQ(cfgmgr(dir, {"build", dir / "absent.cpj", "-o", dir / "o"}).exit_code, 3);
}

// --variables NODE=FILE (CiA DSP 302 §8.2, §8.5): node 5 (tests/data/dynamic/network, the
// segments of ds405_like.eds) gets the variables of plc5.csv as ARRAY objects in DIR/node5.dcf.
TEST(BuildVariables, WritesTheProgrammedDcfOfTheNode) {
  ScratchDir dir;
  const std::string net = tool_test::data_path("dynamic/network/nodelist.cpj");
  const auto r = cfgmgr(dir, {"build", net, "-o", dir / "out", "--variables",
                              "5=" + tool_test::data_path("dynamic/network/plc5.csv")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("node 5 programmed, 5 network variables"));
  auto read = cfg::read_device_file(dir / "out/node5.dcf");
  ASSERT_TRUE(read.ok()) << read.diagnostics.format();
  const cfg::DeviceDescription& dcf = *read.device;
  // Segment 1 (BOOLEAN ro, A000h): start_button, stop_button; segment 2 (UNSIGNED8 ro, A001h):
  // level; segment 5 (UNSIGNED16 rww, A101h): setpoint; segment 4 (BOOLEAN wo, A100h): valve.
  ASSERT_NE(dcf.sub(0xA000, 2), nullptr);
  EXPECT_EQ(dcf.sub(0xA000, 1)->name, "start_button");
  EXPECT_EQ(dcf.sub(0xA000, 2)->name, "stop_button");
  EXPECT_EQ(dcf.sub(0xA000, 0)->default_value, "2");
  EXPECT_EQ(dcf.sub(0xA001, 1)->name, "level");
  EXPECT_EQ(dcf.sub(0xA101, 1)->name, "setpoint");
  EXPECT_EQ(dcf.sub(0xA101, 1)->access, cfg::AccessType::Rww);
  EXPECT_EQ(dcf.sub(0xA100, 1)->name, "valve");
  EXPECT_EQ(dcf.sub(0xA100, 1)->access, cfg::AccessType::Wo);
  EXPECT_TRUE(dcf.sub(0xA100, 1)->pdo_mapping);
  EXPECT_EQ(dcf.node_id(), 5);
  ASSERT_TRUE(cfg::dynamic_channels_of(dcf));
  EXPECT_EQ(cfg::dynamic_channels_of(dcf)->segments.size(), 6U);
}

TEST(BuildVariables, ABadVariablesFileOrNodeIsAnErrorNamingIt) {
  ScratchDir dir;
  const std::string net = tool_test::data_path("dynamic/network/nodelist.cpj");
  const std::string bad = tool_test::data_path("dynamic/network/bad.csv");
  const auto r = cfgmgr(dir, {"build", net, "-o", dir / "o", "--variables", "5=" + bad});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr(bad + ":2: expected name,type,direction"));
  EXPECT_EQ(cfgmgr(dir, {"build", net, "-o", dir / "o", "--variables", "6=" + bad}).exit_code, 1);
  EXPECT_EQ(cfgmgr(dir, {"build", net, "-o", dir / "o", "--variables", "x"}).exit_code, 2);
  // The sample network's nodes have no [DynamicChannels].
  const auto none =
      cfgmgr(dir, {"build", sample_network("nodelist.cpj"), "-o", dir / "o", "--variables",
                   "3=" + tool_test::data_path("dynamic/network/plc5.csv")});
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_THAT(none.err, HasSubstr("has no [DynamicChannels] segments"));
}

}  // namespace
