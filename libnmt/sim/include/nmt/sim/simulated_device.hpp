// A simulated CANopen slave built from any EDS/DCF: a SlaveNode (nmt/slave/slave_node.hpp: NMT,
// SDO, heartbeat, guarding, EMCY, storage, PDO rules, program download) wrapped with the faults of
// nmt/sim/fault_injection.hpp. It is an nmt::Engine: it runs on the simulated bus in a
// SimEngineNode (nmt/sim/sim_bus.hpp) and on real buses through EngineRef
// (nmt/io/bus_event_loop.hpp).
//   auto device = nmt::SimulatedDevice::create(description, 5, faults);
//   nmt::SimEngineNode<nmt::SimulatedDevice> node(std::move(device).value());
//   bus.attach(node);
//   node.apply([](auto& d, nmt::TimePoint now, auto& out) { d.start(now, out); });
#pragma once

#include <cstdint>
#include <optional>

#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/slave/slave_node.hpp"

namespace nmt {

/// A simulated slave: a slave node with faults.
class SimulatedDevice : public FaultInjectedSlave {
 public:
  /// Builds the device. node_id: 1..127; nullopt takes [DeviceComissioning] NodeID. Fails with
  /// a message when there is no valid node-ID or a value of the file does not parse. The device
  /// is off until start().
  static cfg::Result<SimulatedDevice> create(const cfg::DeviceDescription& description,
                                             std::optional<std::uint8_t> node_id,
                                             DeviceFaults faults = {},
                                             SlaveNodeOptions options = {});
  /// Builds a device that powers on without a node-ID and waits for LSS to give it one
  /// (SlaveNode::create_unconfigured). Fails with a message when the file does not say
  /// [DeviceInfo] LSS_Supported=1 or a value of the file does not parse.
  static cfg::Result<SimulatedDevice> create_unconfigured(const cfg::DeviceDescription& description,
                                                          DeviceFaults faults = {},
                                                          SlaveNodeOptions options = {});

  using FaultInjectedSlave::FaultInjectedSlave;
};
static_assert(Engine<SimulatedDevice>);

}  // namespace nmt
