// What `cfgmgr build NETWORK -o DIR` writes, as lely's dcfgen does for its own input: the
// master's DCF and one concise DCF (DSP 302 v3.2.1 §6.2 stream) per slave, so that a CANopen
// manager that reads a master DCF alone (this project's load_network, or another stack) has the
// whole network in files. No file I/O here: the tool writes what this returns.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cfg/network.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_dictionary.hpp"

namespace cfg {

/// One slave's concise DCF.
struct BuiltNode {
  NodeId node_id = *NodeId::from(1);
  std::string name;       ///< as in the network (may be empty)
  std::string file_name;  ///< the name the master DCF's 1F22h sub node-ID gives it
  /// The node's writes as a concise DCF, in the network's (PDO-safe) order: exactly what the
  /// master downloads from it.
  std::vector<std::uint8_t> concise_dcf;
  std::size_t entries = 0;
  /// The node's program image (NetworkNode::program), empty without one, and the name the
  /// master DCF's 1F58h sub node-ID gives it (CiA 302-3 program data, as dcfgen's
  /// software_file): the concise DCF's name with ".img" for ".bin".
  std::vector<std::uint8_t> program_image;
  std::string program_file_name;
};

struct NetworkBuild {
  /// The master's dictionary (the network's master DCF, else derive_master's: 1F80h, 1F81h,
  /// 1F84h-1F88h, 1F26h/1F27h, 1016h) with 1F22h (concise DCF, an ARRAY of DOMAIN, sub-index =
  /// node-ID) naming each slave's file: DownloadFile= (what load_network reads) and UploadFile=
  /// (what lely's master reads) both; 1F20h sub-indices with DownloadFile= are removed, since
  /// 1F22h now configures the nodes. The nodes with a program image get 1F58h sub node-ID
  /// naming it the same two ways (load_network reads it back as the node's program).
  /// [DeviceComissioning] says CANopenManager=1, NodeID (when the network knows the master's)
  /// and NetworkName.
  DeviceDescription master;
  std::vector<BuiltNode> nodes;  ///< by ascending node-ID
};

/// Names a node's concise DCF file; the default gives "node<ID>.bin" (decimal node-ID).
using NodeFileName = std::function<std::string(const NetworkNode&)>;

/// The build of `network`. Never fails: every node of a loaded network has its writes.
NetworkBuild build_network(const Network& network, const NodeFileName& file_name = {});

}  // namespace cfg
