#include "nmt/sim/simulated_device.hpp"

#include <string>
#include <utility>

namespace nmt {

cfg::Result<SimulatedDevice> SimulatedDevice::create(const cfg::DeviceDescription& description,
                                                     std::optional<std::uint8_t> node_id,
                                                     DeviceFaults faults,
                                                     SlaveNodeOptions options) {
  if (!node_id) node_id = description.node_id();
  if (!node_id) return cfg::Error{"no node-ID: none given and no NodeID in [DeviceComissioning]"};
  const auto valid = cfg::NodeId::from(*node_id);
  if (!valid) {
    return cfg::Error{"node-ID " + std::to_string(*node_id) + " is out of range 1..127"};
  }
  auto node = SlaveNode::create(description, *valid, options);
  if (!node) return node.error();
  return SimulatedDevice(std::move(node).value(), std::move(faults));
}

cfg::Result<SimulatedDevice> SimulatedDevice::create_unconfigured(
    const cfg::DeviceDescription& description, DeviceFaults faults, SlaveNodeOptions options) {
  auto node = SlaveNode::create_unconfigured(description, options);
  if (!node) return node.error();
  return SimulatedDevice(std::move(node).value(), std::move(faults));
}

}  // namespace nmt
