// The order in which configuration values are written to a device: the one place of the PDO
// ordering rule (DSP 302 v3.2.1 §6.2, application hint; CiA 301 §7.5.2.35-38 PDO rules).
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "cfg/concise_dcf.hpp"

namespace cfg {

/// Current value of a PDO COB-ID (14xxh/18xxh sub 1) on the device, when the writes do not
/// carry it; nullopt if unknown.
using CobIdLookup = std::function<std::optional<std::uint32_t>(std::uint16_t comm_index)>;

/// Orders writes for download. For every PDO (1400h-15FFh/1600h-17FFh, 1800h-19FFh/1A00h-1BFFh)
/// whose parameters are written: first its COB-ID with bit 31 set (PDO invalid), then
/// communication sub-indices 2 and up, then mapping sub-index 0 = 0, the mapping entries,
/// mapping sub-index 0 = n, and last the COB-ID as configured. Every other object in index
/// order (sub-index order within an object). Input order does not matter.
std::vector<ObjectWrite> pdo_safe_order(std::span<const ObjectWrite> writes,
                                        const CobIdLookup& current_cob_id = {});

}  // namespace cfg
