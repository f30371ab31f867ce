// The order in which configuration values are written to a device: the one place of the PDO
// ordering rule (DSP 302 v3.2.1 §6.2, application hint; CiA 301 §7.5.2.35-38 PDO rules).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/object_index.hpp"

namespace cfg {

/// Current value of a PDO COB-ID (14xxh/18xxh sub 1) on the device, when the writes do not
/// carry it; nullopt if unknown (or if the COB-ID cannot be written: DSP 302 §6.2 step 1 applies
/// only "if it is not readonly"). Asked with 1014h, the device's EMCY COB-ID (1014h sub 0).
using CobIdLookup = std::function<std::optional<std::uint32_t>(std::uint16_t comm_index)>;

/// Writes in download order, and the PDOs for which the ordering rule could not be applied in
/// full because a value it needs is unknown.
struct DownloadOrder {
  std::vector<ObjectWrite> writes;
  /// Communication indices (1400h-15FFh, 1800h-19FFh) of PDOs whose parameters are written but
  /// whose COB-ID is neither among the writes nor known to the lookup. Their writes are still in
  /// PDO order, but without the invalid/valid COB-ID pair around them: a device that has the PDO
  /// valid may refuse the mapping (CiA 301 allows mapping changes only while the PDO is invalid).
  /// The caller decides: warn (dcf2concise), or read the COB-ID from the device and order again
  /// (configuration manager).
  std::vector<std::uint16_t> unknown_cob_id;
  /// Mapping indices (1600h-17FFh, 1A00h-1BFFh) whose entries are written without sub-index 0:
  /// the number of mapped objects to restore is unknown, so the entries are written without
  /// the "sub-index 0 = 0 ... sub-index 0 = n" pair around them.
  std::vector<std::uint16_t> unknown_mapping_count;

  /// True when every PDO got the whole sequence.
  bool complete() const { return unknown_cob_id.empty() && unknown_mapping_count.empty(); }
};

/// Orders writes for download. For every PDO (1400h-15FFh/1600h-17FFh, 1800h-19FFh/1A00h-1BFFh)
/// whose parameters are written: first its COB-ID with bit 31 set (PDO invalid), then
/// communication sub-indices 2 and up, then mapping sub-index 0 = 0, the mapping entries,
/// mapping sub-index 0 = n, and last the COB-ID as configured. A valid EMCY COB-ID (1014h) is
/// written with bit 31 set first (CiA 301 §7.5.2.17) unless the lookup says the device has it
/// already, or has its EMCY not valid. Every other object in index
/// order (sub-index order within an object), except 1020h (verify configuration), which comes
/// after everything else: a device resets it when any other configuration value changes (DSP
/// 302 v3.2.1 §6.3). A PDO sorts at its communication index, so the whole sequence of RPDO n
/// sits where 1400h+n would.
///
/// The writes are taken as the values to configure: input order does not matter, except that
/// when one (index, sub-index) is written more than once the last write wins (as when a stream
/// is applied to a device), so ordering an already ordered stream gives it back unchanged.
///
/// Details: the COB-ID is written with bit 31 set using the configured COB-ID, or, when the
/// writes do not carry it, the lookup's value; then it is written back (configured or looked-up
/// value) unless that value itself has bit 31 set (a disabled PDO stays disabled, written
/// once). Mapping sub-index 0 is written as 0 first, and as n last unless n is 0.
DownloadOrder order_for_download(std::span<const ObjectWrite> writes,
                                 const CobIdLookup& current_cob_id = {});

/// order_for_download(...).writes: for callers that have nothing better to do about unknown
/// COB-IDs or mapping counts than to download what can be downloaded.
std::vector<ObjectWrite> pdo_safe_order(std::span<const ObjectWrite> writes,
                                        const CobIdLookup& current_cob_id = {});

/// What a configuration download ends with, after the configuration (CiA 302-2 §3.5 d).
struct DownloadTail {
  /// 1020h sub 1/2 = 1F26h/1F27h when not 0: last, as writing any other value resets 1020h (DSP
  /// 302 v3.2.1 §6.3).
  ConfigurationStamp stamp;
  /// Then 1010h sub 1 = 'save' (kSaveSignature), so that the device keeps all of it.
  bool save = false;
};

/// The one download plan of a configuration: order_for_download(configuration, current_cob_id),
/// then the tail's writes. The configuration manager's plan (ConfigManager::download_plan), the
/// master's check configuration (which writes the tail as steps of its own, so asks for none)
/// and `cfgmgr push --dry-run` all build it here.
DownloadOrder plan_download(std::span<const ObjectWrite> configuration,
                            const DownloadTail& tail = {}, const CobIdLookup& current_cob_id = {});

/// PDO parameter indices live with the other object names (object_index.hpp).
using object::pdo_indices_of;
using object::PdoIndices;

}  // namespace cfg
