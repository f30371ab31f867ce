// Would a CiA 301 device accept this SDO write? The one implementation of the device-side write
// rules: libnmt's LocalDictionary and SlaveNode (the simulated devices) call it to answer SDO
// downloads, and `cfgmgr check` runs a file's download through it to say beforehand which write
// a device will refuse. Pure functions over the device's entries (its object dictionary with the
// current values) and one write; the answer is the CiA 301 abort code and why, in words.
//
// The rules, each with its abort code (CiA 301 §7.2.4.3.17 table):
//  - access (check_entry_access): no such object 0602 0000, no such sub-index 0609 0011, ro or
//    const 0601 0002, size not the type's 0607 0012 (too long) / 0607 0013 (too short)
//  - value (check_entry_value): BOOLEAN other than 0/1 0609 0030, UNICODE_STRING of an odd
//    length 0607 0010, HighLimit below LowLimit 0609 0036, above HighLimit 0609 0031, below
//    LowLimit 0609 0032
//  - objects (check_object_rules): 1010h/1011h without the 'save'/'load' signature 0800 0020
//    (§7.5.2.13/14); a COB-ID (1014h, 1200h-12FFh sub 1/2, PDO sub 1) whose bits 0-29 change
//    while it is valid 0609 0030 (§7.5.2.5/33/35/37); 1200h sub 1/2 other than the predefined
//    connection set 0601 0002; a second non-zero 1016h entry for one node 0604 0043
//    (§7.5.2.33); a TPDO's inhibit time or SYNC start value changed while the PDO exists
//    0609 0030 (§7.5.2.37); a mapping changed while the PDO is valid, or an entry written
//    while sub-index 0 is not 0, 0800 0022 (§7.5.2.36/38); a mapping entry of an object that
//    does not exist 0602 0000, that is not mappable (PDOMapping=0, access not fitting the
//    direction, length not the type's size, dummy not in [DummyUsage]) 0604 0041; mapping
//    sub-index 0 = n over more than 64 bits 0604 0042.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/data_type.hpp"
#include "cfg/diagnostics.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"
#include "cfg/sdo_abort.hpp"
#include "cfg/value.hpp"

namespace cfg {

/// Default largest size of variable-size entries (strings, DOMAIN): 1 MiB.
inline constexpr std::size_t kDefaultMaxVariableSize = std::size_t{1} << 20;

/// One value-carrying entry (index, sub-index) of a device's object dictionary, as the device
/// holds it: its attributes and its current value.
struct DeviceEntry {
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  std::string name;             ///< ParameterName of the sub-object (or object for a VAR)
  std::uint16_t data_type = 0;  ///< DataType= index as in the device file
  /// The basic type; nullopt for unknown or complex types (treated as DOMAIN bytes).
  std::optional<DataType> basic_type;
  AccessType access = AccessType::Rw;
  bool pdo_mapping = false;
  std::optional<Value> low_limit;   ///< LowLimit, $NODEID resolved (numeric types only)
  std::optional<Value> high_limit;  ///< HighLimit, $NODEID resolved (numeric types only)
  /// Largest value in bytes a write may store. Fixed-size types: their size. Variable-size
  /// types (strings, DOMAIN, unknown types): kDefaultMaxVariableSize unless the device says
  /// otherwise.
  std::size_t max_size = 0;
  std::vector<std::uint8_t> bytes;  ///< current value, little-endian as on the bus

  /// Size in bytes for fixed-size types, nullopt for variable-size ones.
  std::optional<std::size_t> fixed_size() const;
  /// The value as a little-endian unsigned number (first up to 8 bytes) for BOOLEAN and integer
  /// types; nullopt for the others.
  std::optional<std::uint64_t> unsigned_value() const;
};

/// A device's entries by ObjectAddress::key() (index << 8 | sub-index).
using DeviceEntries = std::map<std::uint32_t, DeviceEntry>;

/// The entries of node `node_id` (1..127) as a device built from `device` holds them before any
/// write: every sub-object, valued ParameterValue, else DefaultValue, else zeros of the type's
/// size (empty for variable-size types), with $NODEID resolved; LowLimit/HighLimit likewise.
/// Fails with a message naming the entry ("object 1017h sub 00h: ...") when a value or limit
/// does not parse, or when node_id is out of range.
Result<DeviceEntries> device_entries(const DeviceDescription& device, std::uint8_t node_id);

/// The entry at (index, sub); nullptr when absent.
const DeviceEntry* find_entry(const DeviceEntries& entries, std::uint16_t index, std::uint8_t sub);
/// True when any sub-index of `index` exists.
bool has_object(const DeviceEntries& entries, std::uint16_t index);

/// The answer to a write: accepted (code None), or the abort code a CiA 301 device answers with
/// and why, in words ("maps 2012h sub 00h with 32 bits, but its type UNSIGNED64 has 64").
struct WriteVerdict {
  SdoAbort code = SdoAbort::None;
  std::string reason;  ///< empty when accepted
  bool accepted() const { return code == SdoAbort::None; }
};

/// What a device knows besides its entries that decides writes: which dummy entries (data type
/// indices 0001h-0007h) its RPDOs may map ([DummyUsage] of its device file, CiA 306 §4.5.4).
struct DeviceWriteRules {
  const KeyValues* dummy_usage = nullptr;  ///< nullptr: no dummy mapping
};

/// The checks before the data is seen (an SDO server makes them at the initiate request):
/// existence, access, and the size when known.
WriteVerdict check_entry_access(const DeviceEntries& entries, std::uint16_t index, std::uint8_t sub,
                                std::optional<std::size_t> size);

/// The value checks of one entry: BOOLEAN 0/1, UNICODE_STRING length, LowLimit/HighLimit.
/// Precondition: `data` passed check_entry_access for this entry.
WriteVerdict check_entry_value(const DeviceEntry& entry, std::span<const std::uint8_t> data);

/// The rules of CiA 301's communication objects against the device's current values (store and
/// restore signatures, COB-IDs, consumer heartbeat, PDO parameters and mapping). Precondition:
/// the write passed check_entry_access and check_entry_value.
WriteVerdict check_object_rules(const DeviceEntries& entries, const DeviceWriteRules& rules,
                                std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data);

/// All three, in that order: what a CiA 301 device answers to an SDO download of `data` to
/// (index, sub) while holding `entries`.
WriteVerdict check_device_write(const DeviceEntries& entries, const DeviceWriteRules& rules,
                                std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data);

/// Runs a node's download through the device's rules: `writes` (concise_writes_from_dcf) in the
/// order the master sends them (pdo_safe_order with the COB-IDs the device holds for PDOs the
/// writes do not make invalid themselves) against a device built from `dcf` for `node`
/// (device_entries), each accepted write changing the device's value as it would. Each refused
/// write is a Warning at the line of the DCF value it comes from, naming the object, the value,
/// the abort code and why, prefixed by `label` (e.g. "node 3 (axis): "): CiA 301 devices refuse
/// it, so the download will fail there, though some vendor devices are laxer (a tool's strict
/// mode makes it an error). A refused write leaves the device's value; one entry is reported
/// once. After a refusal in a
/// PDO mapping, a refusal of its sub-index 0 or another 0800 0022 in it is not reported again
/// (the same cause). A DCF whose values do not parse (the reader reported them) is not run.
void check_download(const DeviceDescription& dcf, NodeId node, std::span<const ObjectWrite> writes,
                    const std::string& file, std::string_view label, Diagnostics& diagnostics);

}  // namespace cfg
