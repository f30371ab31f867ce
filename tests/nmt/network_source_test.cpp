// A loaded network as the NMT master sees it (nmt/master/network_source.hpp): the configurations a
// node with nothing stored reads, the LSS addresses of Execute LSS (CiA 305), and the master built
// as the network's configuration manager (MasterConfig::from_network, DSP 302 §6).
#include "nmt/master/network_source.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "cfg/config_manager.hpp"
#include "cfg/device_file.hpp"
#include "cfg/network.hpp"
#include "nmt/master/master_config.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

std::shared_ptr<const cfg::Network> load(const std::string& relative) {
  auto load = cfg::load_network(CANOPEN_TEST_DATA_DIR + "/" + relative);
  EXPECT_TRUE(load.ok()) << relative;
  if (!load.network) return nullptr;
  return std::make_shared<const cfg::Network>(std::move(*load.network));
}

cfg::NodeId id(std::uint8_t value) {
  return *cfg::NodeId::from(value);
}

// tests/data/network/README.md: node 2 (io_node2.dcf) configures 2000h = 12h among its values;
// node 5 is named but not present, so the network has nothing for it.
TEST(NetworkSource, GivesANodesConfigurationConciseDcfAndDcfFromTheNetwork) {
  const auto network = load("network/nodelist.cpj");
  ASSERT_TRUE(network);
  const NetworkSource source(network);
  const cfg::NetworkNode* node2 = network->find(id(2));
  ASSERT_NE(node2, nullptr);
  EXPECT_EQ(source.configuration(id(2)), node2->writes);
  EXPECT_EQ(source.concise_dcf(id(2)), cfg::node_concise_dcf(*node2));
  const auto on_disk = cfg::read_file(node2->file);
  ASSERT_TRUE(on_disk.ok());
  const auto dcf = source.dcf(id(2));
  ASSERT_TRUE(dcf.ok());
  EXPECT_EQ(dcf.value(), std::string(on_disk.value().view()));
  EXPECT_EQ(source.program(id(2)), std::nullopt);
  EXPECT_EQ(source.configuration(id(5)), std::nullopt);
  EXPECT_EQ(source.concise_dcf(id(5)), std::nullopt);
  ASSERT_TRUE(source.dcf(id(5)).ok());
  EXPECT_EQ(source.dcf(id(5)).value(), std::nullopt);
}

// CiA 305: node 16's DCF gives vendor-ID 7E57C0DEh, product 305h, revision 00010002h and
// LSS_SerialNumber 1003h; a second node with the same address makes the address no one's.
TEST(NetworkSource, LssAddressesOfTheNodesAndNoneForASharedOne) {
  const auto network = load("lss/nodelist.cpj");
  ASSERT_TRUE(network);
  std::vector<std::string> notes;
  const auto addresses = lss_addresses(*network, notes);
  ASSERT_EQ(addresses.size(), 1U);
  EXPECT_EQ(addresses.at(id(16)), (LssAddress{0x7E57C0DE, 0x305, 0x00010002, 0x1003}));
  EXPECT_TRUE(notes.empty());

  cfg::Network twice = *network;
  twice.nodes.push_back(twice.nodes.front());
  twice.nodes.back().node_id = id(17);
  const auto shared = lss_addresses(twice, notes);
  EXPECT_TRUE(shared.empty());
  ASSERT_EQ(notes.size(), 1U);
  EXPECT_EQ(notes[0], "nodes 16, 17 share the LSS address " +
                          address_digits(LssAddress{0x7E57C0DE, 0x305, 0x00010002, 0x1003}) +
                          ": none of them gets its node-ID by LSS");
}

// Without a node-ID in the description the master takes 7Fh; master.dcf says node 1.
TEST(MasterConfigFromNetwork, DefaultNodeIdIsTheMasterDcfsElse7Fh) {
  const auto project = load("network/nodelist.cpj");
  ASSERT_TRUE(project);
  EXPECT_EQ(MasterConfig::default_node_id(*project), id(0x7F));
  const auto master_dcf = load("network/master.dcf");
  ASSERT_TRUE(master_dcf);
  EXPECT_EQ(MasterConfig::default_node_id(*master_dcf), id(1));
}

// DSP 302 §6: the master is the network's configuration manager: its configurations come from
// the network, and without a store a manager in memory holds what is written over SDO.
TEST(MasterConfigFromNetwork, IsTheConfigurationManagerOfTheNetwork) {
  const auto network = load("network/nodelist.cpj");
  ASSERT_TRUE(network);
  auto config = MasterConfig::from_network(network, id(0x7F));
  ASSERT_TRUE(config.ok()) << config.error().message;
  EXPECT_EQ(config->node_id, id(0x7F));
  ASSERT_TRUE(config->options.manager);
  EXPECT_FALSE(config->options.manager->persistent());
  ASSERT_TRUE(config->options.configurations);
  EXPECT_EQ(config->options.configurations->configuration(id(2)), network->find(id(2))->writes);
  auto master = config->build();
  ASSERT_TRUE(master.ok()) << master.error().message;
  EXPECT_EQ(master->node_id(), id(0x7F));
  EXPECT_EQ(master->config_manager(), config->options.manager.get());
}

TEST(MasterConfigFromNetwork, RefusesTheNodeIdOfANode) {
  const auto network = load("network/nodelist.cpj");
  ASSERT_TRUE(network);
  const auto config = MasterConfig::from_network(network, id(3));
  ASSERT_FALSE(config.ok());
  EXPECT_EQ(config.error().message,
            "the master's node-ID 3 is also the node-ID of " + network->find(id(3))->file);
}

}  // namespace
}  // namespace nmt
