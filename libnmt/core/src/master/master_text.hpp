// The texts of the NMT master's events, shared by the master and its engines. Private to the
// library.
#pragma once

#include <cstdint>
#include <string>

#include "nmt/nmt_master.hpp"

namespace nmt {

/// "node 3" (messages).
std::string node_text(std::uint8_t node);
/// An event with the fields every kind has.
MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, std::uint8_t node, std::string text);

}  // namespace nmt
