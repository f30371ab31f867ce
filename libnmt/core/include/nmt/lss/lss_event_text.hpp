// The words of the LSS engines' events (LssMasterEvent, nmt/lss/lss_master.hpp; LssProcedureEvent,
// nmt/lss/lss_procedure.hpp) for people: made here, outside the engines, from the events' typed
// fields. A program that needs a fact reads the field; a log or terminal prints describe(event).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "cfg/node_id.hpp"
#include "nmt/engine.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_procedure.hpp"

namespace nmt {

/// One line for people: the service, then how it ended: "configure node-ID: refused: node-ID out
/// of range (error code 1)", "switch state selective: no answer within 100 ms", "Fastscan: found
/// vendor 0000001Eh product ...". No trailing newline; every event gives a line.
std::string describe(const LssMasterEvent& event);

/// One line for people: "scan: vendor ... got node-ID 5, stored", "scan: 2 unconfigured devices
/// found"; Failed: the service's line ("configure node-ID: refused: node-ID out of range (error
/// code 1)"), for a Fastscan the procedure's name in front of its words ("scan: the device
/// stopped answering (part 2)"). No trailing newline; every event gives a line.
std::string describe(const LssProcedureEvent& event);

/// What became of a device given a node-ID, the words after its address: "got node-ID 5,
/// stored", "left unconfigured: configure node-ID refused: node-ID out of range (error code 1)".
/// `node_id` the node-ID given ("?" when unknown); `error_code`/`spec_error` the refusal's (CiA
/// 305, lss::error_text); `timeout` the wait of a service that went unanswered. Part of both
/// describe(LssProcedureEvent) and the NMT master's describe(MasterEvent).
std::string describe(LssScanOutcome outcome, std::optional<cfg::NodeId> node_id,
                     std::uint8_t error_code, std::uint8_t spec_error, Duration timeout);

}  // namespace nmt
