// The library's network pieces under the names the cfgmgr commands use: the loaded network as
// the master's configuration source and its LSS addresses (libnmt core,
// nmt/master/network_source.hpp), the `sim:` bus with a simulated device per node (libnmt sim,
// nmt/sim/sim_network.hpp).
#pragma once

#include "nmt/master/network_source.hpp"
#include "nmt/sim/sim_network.hpp"

namespace cfgmgr {

using nmt::is_sim_url;
using nmt::lss_addresses;
using nmt::NetworkSource;
using nmt::parse_node_list;
using nmt::parse_sim_url;
using nmt::SimBusOptions;
using nmt::simulated_devices;
using nmt::with_identity_of;

}  // namespace cfgmgr
