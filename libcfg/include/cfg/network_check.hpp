// Checks across the nodes of a network description that no single DCF can show: what
// `cfgmgr check NETWORK` adds to the reader's and load_network's own diagnostics (missing files
// and node-ID clashes are load_network's, at the project file's line).
//  - COB-ID clashes: two valid TPDOs (of one node or of two) with one CAN identifier are an
//    error: both would transmit it, and CiA 301 §7.2.2 gives every PDO one producer. An RPDO
//    whose identifier no TPDO of the network produces is a note only: its producer may be a
//    device outside the description.
//  - Identifiers PDOs must not use: CiA 301 §7.3.5's restricted CAN-IDs (000h, 001h-07Fh,
//    101h-180h, 581h-5FFh, 601h-67Fh, 6E0h-6FFh, 701h-77Fh, 780h-7FFh) are an error for any PDO
//    and for the SDO manager's pool (1F02h, DSP 302 §7.2.3). A TPDO on an identifier a device of
//    the network uses otherwise (its EMCY 1014h, SYNC 1005h or TIME 1012h COB-ID, or a 1F02h
//    pool entry) is an error (a second producer); an RPDO on one is a warning.
//  - Each node's own writes (mapping length and mappability, access, limits, sizes, PDO rules)
//    run through the rules a CiA 301 device applies, as for a single DCF (check_download of
//    write_acceptance.hpp): a write the device will refuse is a warning naming the abort code.
//  - A master DCF alone: a slave it boots (1F81h sub X bits 0 and 2) whose 1F20h/1F22h sub X
//    name no file is a warning at its 1F81h entry: the master has no configuration for it.
// The values are those the node has after its download: the DCF's ParameterValue, else its
// DefaultValue (CiA 306 §4.6.3), with $NODEID resolved; a node given by a concise DCF alone is
// checked on its COB-IDs only (there is no dictionary to run its writes against).
#pragma once

#include "cfg/diagnostics.hpp"
#include "cfg/network.hpp"

namespace cfg {

/// Adds the cross-node diagnostics of `network` to `diagnostics`, each with the file and line
/// of the value concerned (the node's DCF; the concise DCF's path and line 0 for a node without
/// DCF). Never throws on bad values: a value that does not parse was reported by the reader and
/// is skipped here.
void check_network(const Network& network, Diagnostics& diagnostics);

}  // namespace cfg
