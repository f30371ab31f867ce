// What the cfgmgr commands that run a network (master; push of the configuration-manager issue)
// share: the loaded network as the NMT master's configuration source, and the `sim:` bus with a
// simulated device per node built from the network's own DCFs.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/network.hpp"
#include "cfg/result.hpp"
#include "nmt/fault_injection.hpp"
#include "nmt/lss.hpp"
#include "nmt/nmt_master.hpp"
#include "nmt/simulated_device.hpp"

namespace cfgmgr {

/// nmt::ConfigurationSource over a loaded network: a node's writes are its DCF's configured
/// values (or its concise DCF's entries), as cfg::load_network made them. Shares the network.
class NetworkSource final : public nmt::ConfigurationSource {
 public:
  explicit NetworkSource(std::shared_ptr<const cfg::Network> network);
  /// The node's writes; nullopt for a node the network has no file for.
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override;
  /// The node's concise DCF as `cfgmgr build` writes it (cfg::node_concise_dcf), the master's
  /// 1F22h for a node with nothing stored; nullopt for a node the network has no file for.
  std::optional<std::vector<std::uint8_t>> concise_dcf(cfg::NodeId node) const override;
  /// The node's DCF file as it is on disk now (read at each call: nothing is kept in memory),
  /// the master's 1F20h for a node with nothing stored; nullopt for a node given by a concise
  /// DCF alone or not in the network; an error (naming the file) when it cannot be read.
  cfg::Result<std::optional<std::string>> dcf(cfg::NodeId node) const override;
  /// The node's program image (DSP 302 §9, 1F50h sub 1) as cfg::load_network or --program read
  /// it at start-up (never read from disk while the master runs); nullopt when the network
  /// gives the node no image.
  std::optional<std::vector<std::uint8_t>> program(cfg::NodeId node) const override;

 private:
  std::shared_ptr<const cfg::Network> network_;
};

/// `sim:` with optional
/// `?bitrate=500000&latency_ms=1&loss=0.01&seed=N&state=DIR&unconfigured=3,5-7` (any order, each at
/// most once).
struct SimBusOptions {
  std::uint32_t bitrate_bps = 500'000;  ///< 1 ... 1 000 000 000
  double latency_ms = 0;                ///< every SDO response of a device leaves this late
  double loss = 0;                      ///< probability of losing each frame, 0..1
  std::uint64_t seed = 1;               ///< of the loss
  /// Where the devices keep what 1010h 'save' stored between runs (nmt/device_state.hpp, one
  /// file per node); empty: nowhere, every run starts from the DCFs' values.
  std::string state_dir;
  /// Nodes whose devices power on without node-ID and wait for LSS (CiA 305) to give them one;
  /// their DCFs must say LSS_Supported=1.
  std::set<std::uint8_t> unconfigured;
};

/// A list of node-IDs as "3,5-7" -> {3, 5, 6, 7}; fails with a message naming the bad part.
cfg::Result<std::set<std::uint8_t>> parse_node_list(std::string_view text);

/// True for URLs of the simulated bus ("sim:" and "sim:?...").
bool is_sim_url(std::string_view url);
/// Parses a `sim:` URL. Fails with a message naming the parameter that is unknown, repeated,
/// or out of range.
cfg::Result<SimBusOptions> parse_sim_url(std::string_view url);

/// `faults` with the identity a device built from `file` answers at node `node`: its 1000h and
/// 1018h sub 1-4, [DeviceInfo] where 1018h has no value (cfg::identity_of), as the real device
/// would and as a master derived from the same file expects. `sim:` and `cfgmgr simulate` both
/// build their devices with it.
nmt::DeviceFaults with_identity_of(const cfg::DeviceDescription& file, cfg::NodeId node,
                                   nmt::DeviceFaults faults);

/// The LSS addresses (CiA 305) of the network's nodes, for Execute LSS (`--lss`,
/// nmt::ExecuteLssOptions::addresses): vendor-ID, product code, revision and serial number as
/// cfg::identity_of gives them (the serial number from [DeviceComissioning] LSS_SerialNumber,
/// else 1018h sub 4), for each node whose DCF gives all four non-zero. Nodes that share one
/// address are left out, and `notes` gets a line naming them.
std::map<cfg::NodeId, nmt::LssAddress> lss_addresses(const cfg::Network& network,
                                                     std::vector<std::string>& notes);

/// One simulated device for each node of the network that has a DCF (a node given only by a
/// concise DCF has no dictionary to simulate: it is left out, and `skipped` gets its node-ID),
/// with the SDO latency of `options`, answering the identity cfg::identity_of gives (its DCF's
/// 1000h/1018h, else [DeviceInfo], as the real device would), and with the values it saved in an
/// earlier run when `options.state_dir` has them. Fails with a message naming the node's file
/// when a device cannot be built from it, or the saved values' file when it is damaged.
cfg::Result<std::vector<nmt::SimulatedDevice>> simulated_devices(
    const cfg::Network& network, const SimBusOptions& options,
    std::vector<cfg::NodeId>* skipped = nullptr);

}  // namespace cfgmgr
