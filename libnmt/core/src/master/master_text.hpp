// The texts of the NMT master's events, shared by the master and its engines. Private to the
// library.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

#include "cfg/node_id.hpp"
#include "nmt/master/nmt_master.hpp"

namespace nmt {

/// "node 3" (messages).
std::string node_text(cfg::NodeId node);
/// An event with the fields every kind has; `node` nullopt: an event of the master, about no node.
MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, std::optional<cfg::NodeId> node);
inline MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, cfg::NodeId node) {
  return master_event(kind, at, std::optional<cfg::NodeId>(node));
}

}  // namespace nmt
