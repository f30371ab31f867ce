// A loaded network as the master's configuration source (nmt/master/network_source.hpp).
#include "nmt/master/network_source.hpp"

#include <utility>

#include "cfg/device_file.hpp"
#include "cfg/object_index.hpp"

namespace nmt {

NetworkSource::NetworkSource(std::shared_ptr<const cfg::Network> network)
    : network_(std::move(network)) {}

std::optional<std::vector<cfg::ObjectWrite>> NetworkSource::configuration(cfg::NodeId node) const {
  const cfg::NetworkNode* found = network_ ? network_->find(node) : nullptr;
  if (found == nullptr) return std::nullopt;
  return found->writes;
}

std::optional<std::vector<std::uint8_t>> NetworkSource::concise_dcf(cfg::NodeId node) const {
  const cfg::NetworkNode* found = network_ ? network_->find(node) : nullptr;
  if (found == nullptr) return std::nullopt;
  return cfg::node_concise_dcf(*found);
}

cfg::Result<std::optional<std::string>> NetworkSource::dcf(cfg::NodeId node) const {
  const cfg::NetworkNode* found = network_ ? network_->find(node) : nullptr;
  if (found == nullptr || !found->dcf) return std::optional<std::string>{};
  auto text = cfg::read_file(found->file);
  if (!text) return cfg::Error{found->file + ": " + text.error().message, text.error().category};
  return std::optional<std::string>{std::string(text->view())};
}

std::optional<std::vector<std::uint8_t>> NetworkSource::program(cfg::NodeId node) const {
  const cfg::NetworkNode* found = network_ ? network_->find(node) : nullptr;
  if (found == nullptr || !found->program || found->program->image.empty()) return std::nullopt;
  return found->program->image;
}

std::map<cfg::NodeId, LssAddress> lss_addresses(const cfg::Network& network,
                                                std::vector<std::string>& notes) {
  std::map<LssAddress, std::vector<cfg::NodeId>> by_address;
  for (const auto& node : network.nodes) {
    if (!node.dcf) continue;
    const cfg::DeviceIdentity identity = cfg::identity_of(*node.dcf, node.node_id);
    const LssAddress address{identity.vendor_id.value_or(0), identity.product_code.value_or(0),
                             identity.revision_number.value_or(0),
                             identity.serial_number.value_or(0)};
    // 0 is "not given" (an EDS default serial number is no device's), as in 1F85h-1F88h.
    if (address.vendor_id == 0 || address.product_code == 0 || address.revision == 0 ||
        address.serial == 0) {
      continue;
    }
    by_address[address].push_back(node.node_id);
  }
  std::map<cfg::NodeId, LssAddress> addresses;
  for (const auto& [address, nodes] : by_address) {
    if (nodes.size() == 1) {
      addresses[nodes.front()] = address;
      continue;
    }
    std::string list;
    for (const auto n : nodes) list += (list.empty() ? "" : ", ") + std::to_string(n);
    notes.push_back("nodes " + list + " share the LSS address " + address_digits(address) +
                    ": none of them gets its node-ID by LSS");
  }
  return addresses;
}

std::map<cfg::NodeId, EmcySource> emcy_sources(const cfg::Network& network) {
  std::map<cfg::NodeId, EmcySource> sources;
  for (const auto& node : network.nodes) {
    EmcySource source;
    if (auto cob = cfg::configured_value(node, cfg::object::kCobIdEmcy, 0)) {
      source.cob_id = cfg::CobId::from_word(*cob);
    }
    source.device_type = cfg::configured_value(node, cfg::object::kDeviceType, 0);
    sources.emplace(node.node_id, source);
  }
  return sources;
}

}  // namespace nmt
