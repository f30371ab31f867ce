// The texts of the NMT master's events, shared by the master and its engines. Private to the
// library.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

#include "cfg/node_id.hpp"
#include "nmt/nmt_master.hpp"

namespace nmt {

/// "node 3" (messages).
std::string node_text(cfg::NodeId node);
/// An event with the fields every kind has; `node` nullopt: an event of the master, about no node.
MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, std::optional<cfg::NodeId> node,
                         std::string text);
inline MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, cfg::NodeId node,
                                std::string text) {
  return master_event(kind, at, std::optional<cfg::NodeId>(node), std::move(text));
}
/// The same for the callers in manager/ that still hold raw node numbers (issue 21: they go
/// when the SDO manager's internals are cfg::NodeId): 0 and numbers above 127 name no node.
std::string node_text(std::uint8_t node);
MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, std::uint8_t node, std::string text);

}  // namespace nmt
