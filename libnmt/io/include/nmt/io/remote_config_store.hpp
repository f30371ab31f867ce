// A running master's configuration manager (DSP 302 §6) over SDO, as nmt::StoreObjects for
// nmt::ConfigStoreClient (nmt/manager/config_store_client.hpp): `cfgmgr store --bus URL --master
// N`. Reads and writes go to the master's default SDO server (600h/580h + node-ID) through an
// nmt::SdoSession; files are long, so block transfer (CiA 301 §7.2.4.3.9), segmented when the
// server has none.
#pragma once

#include <memory>
#include <string>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/manager/config_store_client.hpp"

namespace nmt {

/// Opens the bus at `url` (socketcan:IF, udp://GROUP:PORT) with an SDO client of `master`'s
/// default SDO. Each read or write waits up to `timeout` for every answer; no answer is an
/// access with abort 0504 0000h and StoreAccess::io set. Fails (category Io) when the bus
/// cannot be opened.
cfg::Result<std::unique_ptr<StoreObjects>> open_remote_store(const std::string& url,
                                                             cfg::NodeId master, Duration timeout);

}  // namespace nmt
