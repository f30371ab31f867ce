// The words of the NMT master's events (MasterEvent, nmt/master/master_event.hpp) for people: made
// here, outside the engine, from the event's typed fields. A program that needs a fact reads
// the field; a log or terminal prints describe(event).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "nmt/master/master_event.hpp"

namespace nmt {

/// One line for people: "node 3: boot error C: value of object 1000h differs from object 1F84h
/// (device type) (1000h is 0x00020192, 1F84h expects 0x00030192)". No trailing newline; every
/// kind gives a line (never empty).
std::string describe(const MasterEvent& event);

/// A BootError's words after its "node 3: boot error C: " head: Table 1's text, the reason in
/// parentheses and, for a mandatory slave's last B, "; boot time 1F89h (N ms) elapsed".
std::string describe_boot_error(const MasterEvent& event);

/// An EMCY in words: "8130h life guard error or heartbeat error; error register 11h (generic,
/// communication); manufacturer bytes 00 00 00 00 00", the code read in the profile of
/// `device_type` (1000h) where it has words for it (nmt/protocol/emcy_text.hpp). Part of
/// describe() for MasterEvent::Emergency.
std::string describe_emergency(const Emergency& emcy, std::optional<std::uint32_t> device_type);

/// A BootError's or SlaveBooted's boot_emergency: "the node sent emergency 8130h life guard error
/// or heartbeat error during its boot"; empty without one. Part of describe_boot_error().
std::string describe_boot_emergency(const MasterEvent& event);

/// The reason of a failed boot in words, without the status letter and Table 1's text:
/// "1000h is 0x00020192, 1F84h expects 0x00030192" (`node` is the slave). Part of describe().
std::string describe(const BootFailure& failure, cfg::NodeId node);

/// A SlaveBooted with `no_configuration`: "no configuration for node 3 (1F22h sub 03h empty)",
/// the words describe() and the tools use for a slave booted with nothing to configure it with.
std::string describe_no_configuration(cfg::NodeId node);

/// "1018h sub 01h upload failed: 0x05040000 (SDO protocol timed out)"; for a transfer the
/// client refused, "... download could not start: " and its words (SdoResult::refusal).
std::string describe_transfer_failure(const SdoResult& result);

/// Names for logs and JSON (as to_string(MasterEvent::Kind)): "value_differs", "power_on",
/// "stored", "slave_does_not_answer", ...
std::string_view to_string(BootFailure::Reason reason);
std::string_view to_string(FlyingMasterReason reason);
std::string_view to_string(LssScanOutcome outcome);
std::string_view to_string(SdoManagerReason::Kind kind);

}  // namespace nmt
