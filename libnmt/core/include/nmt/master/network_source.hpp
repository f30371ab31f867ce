// A loaded network (cfg::load_network: a CiA 306-3 project file or a master DCF naming its nodes'
// files) as the NMT master's configuration manager sees it (DSP 302 §6): the source of the
// slaves' configurations a node with nothing stored reads, and the LSS addresses Execute LSS
// looks for (CiA 305). Its twin over a configuration store is configuration_manager_source.hpp.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cfg/network.hpp"
#include "cfg/result.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/master/nmt_master.hpp"

namespace nmt {

/// ConfigurationSource over a loaded network: a node's writes are its DCF's configured values
/// (or its concise DCF's entries), as cfg::load_network made them. Shares the network.
class NetworkSource final : public ConfigurationSource {
 public:
  explicit NetworkSource(std::shared_ptr<const cfg::Network> network);
  /// The node's writes; nullopt for a node the network has no file for.
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override;
  /// The node's concise DCF as cfg::node_concise_dcf makes it, the master's 1F22h for a node
  /// with nothing stored; nullopt for a node the network has no file for.
  std::optional<std::vector<std::uint8_t>> concise_dcf(cfg::NodeId node) const override;
  /// The node's DCF file as it is on disk now (read at each call: nothing is kept in memory),
  /// the master's 1F20h for a node with nothing stored; nullopt for a node given by a concise
  /// DCF alone or not in the network; an error (naming the file) when it cannot be read.
  cfg::Result<std::optional<std::string>> dcf(cfg::NodeId node) const override;
  /// The node's program image (DSP 302 §9, 1F50h sub 1) as cfg::load_network read it (never
  /// read from disk while the master runs); nullopt when the network gives the node no image.
  std::optional<std::vector<std::uint8_t>> program(cfg::NodeId node) const override;

 private:
  std::shared_ptr<const cfg::Network> network_;
};

/// The LSS addresses (CiA 305) of the network's nodes, for Execute LSS
/// (ExecuteLssOptions::addresses): vendor-ID, product code, revision and serial number as
/// cfg::identity_of gives them (the serial number from [DeviceComissioning] LSS_SerialNumber,
/// else 1018h sub 4), for each node whose DCF gives all four non-zero. Nodes that share one
/// address are left out, and `notes` gets a line naming them.
std::map<cfg::NodeId, LssAddress> lss_addresses(const cfg::Network& network,
                                                std::vector<std::string>& notes);

/// What the master knows of the emergency producers of the network's nodes
/// (MasterOptions::emcy.sources): each node's 1014h and 1000h after its configuration
/// (cfg::configured_value; a node without 1014h: 80h + node-ID). MasterConfig::from_network
/// fills MasterOptions::emcy.sources with it when they are empty.
std::map<cfg::NodeId, EmcySource> emcy_sources(const cfg::Network& network);

}  // namespace nmt
