// A loaded network on the simulated bus: the `sim:` URL's options and a simulated device per
// node built from the network's own DCFs, answering the identity a master derived from the same
// files expects (`cfgmgr master/push/verify --bus sim:`, `cfgmgr simulate`).
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/network.hpp"
#include "cfg/result.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace nmt {

/// `sim:` with optional
/// `?bitrate=500000&latency_ms=1&loss=0.01&seed=N&state=DIR&unconfigured=3,5-7` (any order, each
/// at most once), `&device=FILE@3,5-7` (repeatable, each node-ID in one only) and
/// `&emcy=NODE@MS:CODE[:REGISTER]` (repeatable: the device at NODE raises the EMCY with error
/// code CODE, hex, and error register bits REGISTER, hex, MS ms of simulated time after the
/// run's start, through its EmcyProducer).
struct SimBusOptions {
  std::uint32_t bitrate_bps = 500'000;  ///< 1 ... 1 000 000 000
  double latency_ms = 0;                ///< every SDO response of a device leaves this late
  double loss = 0;                      ///< probability of losing each frame, 0..1
  std::uint64_t seed = 1;               ///< of the loss
  /// Where the devices keep what 1010h 'save' stored between runs (nmt/sim/device_state.hpp, one
  /// file per node); empty: nowhere, every run starts from the DCFs' values.
  std::string state_dir;
  /// Nodes whose devices power on without node-ID and wait for LSS (CiA 305) to give them one;
  /// their DCFs must say LSS_Supported=1.
  std::set<std::uint8_t> unconfigured;
  /// device=FILE@NODES: the device at each of these node-IDs is built from the EDS/DCF FILE, in
  /// place of the network's DCF, and also where the network has none to simulate (a node given
  /// by a concise DCF alone, or not given at all: a slave a master DCF lists in 1F81h). So a
  /// master DCF with concise DCFs (lely dcfgen's master.dcf) runs against the slaves' EDSs.
  std::map<std::uint8_t, std::string> device_files;
  /// emcy=: the emergencies each node's device raises (DeviceFaults::emergencies).
  std::map<std::uint8_t, std::vector<ScheduledEmergency>> emergencies;
};

/// A list of node-IDs (1..127, each a number as cfg::parse_integer_literal reads it) as "3,5-7"
/// -> {3, 5, 6, 7}; fails with a message naming the bad part.
cfg::Result<std::set<std::uint8_t>> parse_node_list(std::string_view text);

/// True for URLs of the simulated bus ("sim:" and "sim:?...").
bool is_sim_url(std::string_view url);
/// Parses a `sim:` URL. Fails with a message naming the parameter that is unknown, repeated,
/// or out of range.
cfg::Result<SimBusOptions> parse_sim_url(std::string_view url);

/// `faults` with the identity a device built from `file` answers at node `node`: its 1000h and
/// 1018h sub 1-4, [DeviceInfo] where 1018h has no value (cfg::identity_of), as the real device
/// would and as a master derived from the same file expects.
DeviceFaults with_identity_of(const cfg::DeviceDescription& file, cfg::NodeId node,
                              DeviceFaults faults);

/// One simulated device for each node of the network that has a DCF or a device= file (a node
/// given only by a concise DCF has no dictionary to simulate: it is left out, and `skipped` gets
/// its node-ID), then one for each device= node-ID the network does not have, ascending;
/// `owners` gets each device's node-ID, in the order of the devices,
/// with the SDO latency of `options`, answering the identity cfg::identity_of gives (its DCF's
/// 1000h/1018h, else [DeviceInfo], as the real device would), and with the values it saved in an
/// earlier run when `options.state_dir` has them. Fails with a message naming the node's file
/// when a device cannot be built from it, or the saved values' file when it is damaged.
cfg::Result<std::vector<SimulatedDevice>> simulated_devices(
    const cfg::Network& network, const SimBusOptions& options,
    std::vector<cfg::NodeId>* skipped = nullptr, std::vector<cfg::NodeId>* owners = nullptr);

}  // namespace nmt
