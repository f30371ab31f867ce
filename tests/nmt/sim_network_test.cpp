// A loaded network on the simulated bus (nmt/sim/sim_network.hpp): the `sim:` URL, node lists, and
// a simulated device per node with a DCF.
#include "nmt/sim/sim_network.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "cfg/network.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

TEST(SimUrl, BareSimIsTheDefaults) {
  EXPECT_TRUE(is_sim_url("sim:"));
  EXPECT_TRUE(is_sim_url("sim:?loss=0.1"));
  EXPECT_FALSE(is_sim_url("socketcan:vcan0"));
  const auto options = parse_sim_url("sim:");
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->bitrate_bps, 500'000U);
  EXPECT_EQ(options->latency_ms, 0.0);
  EXPECT_EQ(options->loss, 0.0);
  EXPECT_EQ(options->seed, 1U);
  EXPECT_TRUE(options->state_dir.empty());
  EXPECT_TRUE(options->unconfigured.empty());
}

TEST(SimUrl, ReadsEveryParameterInAnyOrder) {
  const auto options = parse_sim_url(
      "sim:?unconfigured=3,5-7&seed=0x10&state=/tmp/s&loss=0.25&latency_ms=1.5&bitrate=250000");
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->bitrate_bps, 250'000U);
  EXPECT_EQ(options->latency_ms, 1.5);
  EXPECT_EQ(options->loss, 0.25);
  EXPECT_EQ(options->seed, 16U);
  EXPECT_EQ(options->state_dir, "/tmp/s");
  EXPECT_EQ(options->unconfigured, (std::set<std::uint8_t>{3, 5, 6, 7}));
}

TEST(SimUrl, NamesTheParameterItRefuses) {
  const auto message = [](std::string_view url) {
    const auto parsed = parse_sim_url(url);
    return parsed.ok() ? std::string("ok") : parsed.error().message;
  };
  EXPECT_EQ(message("sim:?bitrate=0"), "sim: bitrate=0: expected 1 ... 1000000000 bit/s");
  EXPECT_EQ(message("sim:?loss=2"), "sim: loss=2: expected a probability 0 ... 1");
  EXPECT_EQ(message("sim:?seed=1&seed=2"), "sim: parameter 'seed' given twice");
  EXPECT_EQ(message("sim:?speed=1"),
            "sim: unknown parameter 'speed' (known: bitrate, latency_ms, loss, seed, state, "
            "unconfigured, device, emcy)");
  EXPECT_EQ(message("sim:?emcy=0@10:8130"),
            "sim: emcy=0@10:8130: expected NODE@MS:CODE[:REGISTER] (node-ID, ms after the "
            "start, EMCY error code and error register bits in hex, e.g. 3@1500:8130)");
  EXPECT_EQ(message("sim:?emcy=3@10:18130").substr(0, 24), "sim: emcy=3@10:18130: ex");
  EXPECT_EQ(message("sim:x"), "sim: expected '?' and parameters after 'sim:', got 'x'");
  EXPECT_EQ(message("sim:?unconfigured=0"), "sim: unconfigured=0: '0' is no node-ID 1..127");
  EXPECT_EQ(message("sim:?device=drive.eds"),
            "sim: device=drive.eds: expected FILE@NODES (an EDS or DCF and node-IDs, e.g. "
            "drive.eds@2-7)");
  EXPECT_EQ(message("sim:?device=a.eds@2-3&device=b.eds@3"),
            "sim: device=b.eds@3: node 3 has a device= already");
}

TEST(SimUrl, DeviceFilesAreRepeatableAndGiveEachNodeItsFile) {
  const auto options = parse_sim_url("sim:?device=/x/a@b.eds@2-3&loss=0&device=c.dcf@0x10");
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->device_files, (std::map<std::uint8_t, std::string>{
                                       {2, "/x/a@b.eds"}, {3, "/x/a@b.eds"}, {16, "c.dcf"}}));
}

// emcy=NODE@MS:CODE[:REGISTER], repeatable: the EMCYs each node's device raises.
TEST(SimUrl, EmergenciesAreRepeatableWithTimeCodeAndRegister) {
  const auto options = parse_sim_url("sim:?emcy=3@1500:8130&emcy=3@1600:0x2310:02&emcy=5@0:0");
  ASSERT_TRUE(options.ok()) << options.error().message;
  ASSERT_EQ(options->emergencies.size(), 2U);
  const auto& three = options->emergencies.at(3);
  ASSERT_EQ(three.size(), 2U);
  EXPECT_EQ(three[0].at, TimePoint{} + std::chrono::milliseconds(1500));
  EXPECT_EQ(three[0].error_code, 0x8130);
  EXPECT_EQ(three[0].error_register_bits, 0);
  EXPECT_EQ(three[1].error_code, 0x2310);
  EXPECT_EQ(three[1].error_register_bits, 0x02);
  EXPECT_EQ(options->emergencies.at(5)[0].error_code, 0x0000);
}

TEST(NodeList, RangesAndSingleNodes) {
  const auto nodes = parse_node_list("3,5-7,0x10");
  ASSERT_TRUE(nodes.ok()) << nodes.error().message;
  EXPECT_EQ(nodes.value(), (std::set<std::uint8_t>{3, 5, 6, 7, 16}));
  EXPECT_EQ(parse_node_list("7-5").error().message, "range 7-5 is empty");
  EXPECT_EQ(parse_node_list("3,128").error().message, "'128' is no node-ID 1..127");
}

// tests/data/network/README.md: nodes 2 and 3 have DCFs, node 5 is not present; each device
// answers the identity of its DCF (io_node2.dcf: 1000h = 00030191h, 1018h sub 1 = ABCh).
TEST(SimulatedDevices, OneDevicePerNodeWithADcf) {
  auto load = cfg::load_network(CANOPEN_TEST_DATA_DIR + "/network/nodelist.cpj");
  ASSERT_TRUE(load.ok());
  std::vector<cfg::NodeId> skipped;
  auto devices = simulated_devices(*load.network, SimBusOptions{}, &skipped);
  ASSERT_TRUE(devices.ok()) << devices.error().message;
  ASSERT_EQ(devices->size(), 2U);
  EXPECT_TRUE(skipped.empty());
  const DeviceFaults identity =
      with_identity_of(*load.network->find(*cfg::NodeId::from(2))->dcf, *cfg::NodeId::from(2), {});
  EXPECT_EQ(identity.device_type, 0x00030191U);
  EXPECT_EQ(identity.vendor_id, 0xABCU);
}

// tests/data/network/master.dcf: node 2 by a DCF (1F20h sub 2), node 3 by a concise DCF alone
// (1F22h sub 3), which has no dictionary to simulate unless device= gives one; device= also adds
// a node-ID the network does not have (9), after the network's nodes.
TEST(SimulatedDevices, DeviceFilesSimulateNodesGivenByAConciseDcfAlone) {
  auto load = cfg::load_network(CANOPEN_TEST_DATA_DIR + "/network/master.dcf");
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  std::vector<cfg::NodeId> skipped;
  std::vector<cfg::NodeId> owners;
  auto plain = simulated_devices(*load.network, SimBusOptions{}, &skipped, &owners);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_EQ(plain->size(), 1U);
  EXPECT_EQ(skipped, (std::vector<cfg::NodeId>{*cfg::NodeId::from(3)}));
  EXPECT_EQ(owners, (std::vector<cfg::NodeId>{*cfg::NodeId::from(2)}));

  SimBusOptions options;
  const std::string eds = CANOPEN_TEST_DATA_DIR + "/network/nodes/io_node2.dcf";
  options.device_files = {{3, eds}, {9, eds}};
  skipped.clear();
  owners.clear();
  auto devices = simulated_devices(*load.network, options, &skipped, &owners);
  ASSERT_TRUE(devices.ok()) << devices.error().message;
  EXPECT_EQ(devices->size(), 3U);
  EXPECT_TRUE(skipped.empty());
  EXPECT_EQ(owners, (std::vector<cfg::NodeId>{*cfg::NodeId::from(2), *cfg::NodeId::from(3),
                                              *cfg::NodeId::from(9)}));

  options.device_files = {{3, CANOPEN_TEST_DATA_DIR + "/network/no_such.eds"}};
  const auto missing = simulated_devices(*load.network, options);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("device=" + CANOPEN_TEST_DATA_DIR +
                                         "/network/no_such.eds: cannot simulate it"),
            std::string::npos)
      << missing.error().message;
}

}  // namespace
}  // namespace nmt
