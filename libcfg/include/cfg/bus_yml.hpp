// A network described as lely-core's dcfgen and ros2_canopen read it: a YAML `bus.yml` with
// the slaves' EDS/DCF files, read into the same model as a CiA 306-3 project file (network.hpp):
// each slave's EDS with the YAML's settings applied as ParameterValues (so its writes come from
// concise_writes_from_dcf, in the network's PDO-safe order), and the master's dictionary
// derive_master makes, with the YAML's master settings in it.
//
// Two layouts, told apart by a top-level `nodes` key:
//  - lely's: `options`, `master`, and one top-level key per slave (keys starting with '.' are
//    skipped, as dcfgen does, so they can hold YAML anchors);
//  - ros2_canopen's: `options`, `master`, `defaults`, `nodes` (one key per slave). A node gets
//    each key of `defaults` it does not set itself. ros2_canopen's cogen.py copies every key of
//    `defaults` over the node's own (so there the default wins); we let the node's own key win,
//    which is what a reader of the file expects, and warn at the node's key wherever the two
//    readings give different values.
// YAML anchors, aliases and merge keys (`<<: *anchor`) work.
//
// The keys and their meaning are dcfgen's (lely-core python/dcf-tools/dcfgen/cli.py and its
// master.dcf.em template); docs/bus-yml.md lists them with what each becomes. The differences:
// a slave's configuration is written whether or not it equals the EDS's default (as for every
// DCF, tests/cfg/dcfgen-differences.md); a PDO's settings are checked against the EDS at their
// line (an object the EDS lacks is an error, not a Python KeyError); the master's 1F26h/1F27h
// come from each slave's configuration (derive_master) so that an unchanged slave is not
// downloaded again. The keys ros2_canopen's drivers read (driver, package, period, namespace,
// polling, boot_timeout_ms, sdo_timeout_ms, scale_*, diagnostics, ...) are accepted and named
// once, as a note, as not used by cfgmgr.
//
// Paths (`dcf`, `software_file`) are relative to the bus.yml's directory; `dcf_path` is where
// dcfgen tells the master the generated files will be, not where the inputs are, and is not
// read. `@NAME@` (a CMake configure_file placeholder, ros2_canopen's `@BUS_CONFIG_PATH@`) is
// replaced with NetworkOptions::placeholders[NAME]; a path still holding one is an error.
#pragma once

#include <string>
#include <string_view>

#include "cfg/network.hpp"

namespace cfg {

/// True when `path` names a bus.yml description: its extension is .yml or .yaml (any case).
/// load_network reads such a file with load_bus_yml.
bool is_bus_yml_path(std::string_view path);

/// Reads a bus.yml network description. Never throws on bad input. Diagnostics name the
/// bus.yml and the line of the key concerned (`bus.yml:12: error: ...`). Errors: YAML that does
/// not parse (at the parser's line), a key of the wrong type, a slave without `dcf`, an EDS/DCF
/// that cannot be read, a node-ID outside 1..127 or given twice (or the master's), a PDO the EDS
/// does not have, a mapped object the EDS lacks, an `sdo` entry the EDS lacks or whose value is
/// not one of its type, two valid TPDOs with one CAN identifier, `cob_id: auto` beyond 6DFh, an
/// unresolved `@NAME@` in a path. Warnings: an unknown key, a setting dcfgen ignores (a PDO left
/// invalid, an RPDO's inhibit time, ...), a mapped object without PDOMapping=1, a mapping over 64
/// bits, a write to a read-only entry (not written), the defaults/nodes difference above, a
/// software update (`software_file`, `software_version`: CiA 302-3 1F55h-1F58h, which cfgmgr's
/// master does not do; the node's software is neither checked nor updated).
NetworkLoad load_bus_yml(const std::string& path, const NetworkOptions& options = {});

}  // namespace cfg
