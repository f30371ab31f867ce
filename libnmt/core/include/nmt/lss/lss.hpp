// Layer Setting Services (LSS, CiA 305): the protocol's constants, frames and words, shared by
// the LSS master (nmt/lss/lss_master.hpp) and the LSS slave (nmt/lss/lss_slave.hpp).
//
// CiA 305 is not in ../shared/spec. What this code relies on, and where it was learned (public
// material, read and restated; nothing copied):
// - CANopenNode, 305/CO_LSS.h (documents CiA DSP 305 V3.0.0): COB-IDs 7E5h master -> slave and
//   7E4h slave -> master; the command specifiers 04h switch state global (mode 0 waiting,
//   1 configuration), 40h-43h switch state selective with vendor-ID, product code, revision
//   number, serial number and the answer 44h, 11h configure node-ID, 13h configure bit timing,
//   15h activate bit timing, 17h store configuration, 51h Fastscan and its answer 4Fh, 5Ah-5Dh
//   inquire vendor-ID/product code/revision/serial number, 5Eh inquire node-ID; the error codes
//   (configure node-ID: 0 success, 1 node-ID out of range, FFh manufacturer-specific; configure
//   bit timing: 0, 1 bit rate not supported, FFh; store: 0, 1 not supported, 2 storage media
//   access error, FFh); the bit timing table of table selector 0 (index 0 1000 kbit/s, 1 800,
//   2 500, 3 250, 4 125, 5 reserved, 6 50, 7 20, 8 10, 9 automatic bit rate detection); Fastscan
//   BitCheck 0..31 (the lowest bit of IDNumber compared) and 80h (every waiting slave answers, its
//   scan restarts), LSSSub/LSSNext 0 vendor-ID, 1 product code, 2 revision, 3 serial number;
//   node-ID FFh means "not configured".
// - CANopenNode, 305/CO_LSSslave.c: frames of 8 data bytes only; Fastscan is answered only by a
//   slave in LSS waiting whose active and pending node-ID are both FFh, and only while its
//   position equals LSSSub; a match moves it to LSSNext, and a match with BitCheck 0 and
//   LSSNext < LSSSub puts it into LSS configuration; switch state global to waiting of a device
//   that was unconfigured and now has a pending node-ID makes it reset communication on its own.
// - lely-core, src/co/lss.c (cites figures of CiA 305 V3.0.0): identify remote slave is six
//   frames 46h vendor-ID, 47h product code, 48h/49h revision low/high, 4Ah/4Bh serial number
//   low/high (bounds inclusive), every slave inside the range answers 4Fh; identify
//   non-configured remote slave is 4Ch, answered 50h by slaves whose active and pending node-ID
//   are FFh; the answers of configure/store carry the error code in byte 1 and, for FFh, the
//   manufacturer's code in byte 2; inquire answers carry the value little-endian in bytes 1-4
//   (node-ID in byte 1); a Fastscan master reads "no answer" to a bit query as "that bit is 1".
// - python-canopen, canopen/lss.py: the same command specifier values; switch state global has
//   no answer.
// - CiA DSP 305 V2.2 (2008, its public title page and history): Fastscan came with version 2.2.
// All LSS frames carry 8 data bytes; bytes a service does not use are 0 (both implementations
// above send them so).
#pragma once

#include <array>
#include <compare>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "nmt/protocol/frame.hpp"

namespace nmt {

/// The LSS address of a device: 1018h sub 1-4 (CiA 305). Ordered as Fastscan finds addresses:
/// vendor-ID first, each value from its most significant bit.
struct LssAddress {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;

  /// The part Fastscan's LSSSub names: 0 vendor-ID, 1 product code, 2 revision, 3 serial.
  std::uint32_t part(int sub) const;
  std::uint32_t& part(int sub);
  auto operator<=>(const LssAddress&) const = default;
};
/// "vendor 0000001Eh product 00000002h revision 00010000h serial 12345678h"
std::string to_string(const LssAddress& address);
/// "0000001E:00000002:00010000:12345678": the four parts in hex, as `cfgmgr lss` reads and
/// prints them; `separator` '-' gives a file-name form.
std::string address_digits(const LssAddress& address, char separator = ':');

/// LSS states of a slave (the mode byte of switch state global).
enum class LssState : std::uint8_t { Waiting = 0, Configuration = 1 };
std::string_view to_string(LssState state);

namespace lss {

inline constexpr std::uint32_t kMasterCobId = 0x7E5;  ///< master -> slave
inline constexpr std::uint32_t kSlaveCobId = 0x7E4;   ///< slave -> master
/// The node-ID of a device that has none (CiA 305 "not configured").
inline constexpr std::uint8_t kUnconfigured = 0xFF;
/// Fastscan BitCheck value that asks every unconfigured waiting slave to answer and restart.
inline constexpr std::uint8_t kFastscanReset = 0x80;
/// The bit timing table index of automatic bit rate detection.
inline constexpr std::uint8_t kAutoBitRateIndex = 9;

/// Command specifiers, byte 0 of every LSS frame.
enum class Cs : std::uint8_t {
  SwitchStateGlobal = 0x04,
  ConfigureNodeId = 0x11,
  ConfigureBitTiming = 0x13,
  ActivateBitTiming = 0x15,
  StoreConfiguration = 0x17,
  SwitchSelectiveVendor = 0x40,
  SwitchSelectiveProduct = 0x41,
  SwitchSelectiveRevision = 0x42,
  SwitchSelectiveSerial = 0x43,
  SwitchSelectiveAnswer = 0x44,
  IdentifyVendor = 0x46,
  IdentifyProduct = 0x47,
  IdentifyRevisionLow = 0x48,
  IdentifyRevisionHigh = 0x49,
  IdentifySerialLow = 0x4A,
  IdentifySerialHigh = 0x4B,
  IdentifyNonConfigured = 0x4C,
  IdentifyAnswer = 0x4F,  ///< identify remote slave and Fastscan answer
  IdentifyNonConfiguredAnswer = 0x50,
  Fastscan = 0x51,
  InquireVendor = 0x5A,
  InquireProduct = 0x5B,
  InquireRevision = 0x5C,
  InquireSerial = 0x5D,
  InquireNodeId = 0x5E,
};

/// An 8-byte LSS frame on `cob_id`: `cs`, then `value` little-endian in bytes 1-4, the rest 0.
CanFrame make_frame(std::uint32_t cob_id, Cs cs, std::uint32_t value = 0);
/// An 8-byte LSS frame with bytes 1.. given (unused bytes 0).
CanFrame make_frame(std::uint32_t cob_id, Cs cs, std::initializer_list<std::uint8_t> bytes);
/// A Fastscan request: IDNumber, BitCheck, LSSSub, LSSNext.
CanFrame make_fastscan(std::uint32_t id_number, std::uint8_t bit_check, std::uint8_t lss_sub,
                       std::uint8_t lss_next);
/// True for an LSS frame on `cob_id`: data frame, standard identifier, 8 data bytes.
bool is_lss_frame(const CanFrame& frame, std::uint32_t cob_id);

/// kbit/s of bit timing table index `index` (table selector 0); nullopt for 5 (reserved),
/// 9 (automatic detection, no rate) and indices past the table.
std::optional<std::uint16_t> bit_rate_kbit(std::uint8_t index);
/// The table index of `kbit` kbit/s; nullopt when the table has no such rate.
std::optional<std::uint8_t> bit_timing_index(std::uint16_t kbit);

/// The error code of a configure node-ID / configure bit timing / store configuration answer in
/// words, e.g. "node-ID out of range (error code 1)"; `spec_error` is named for FFh.
std::string error_text(Cs service, std::uint8_t error_code, std::uint8_t spec_error);

}  // namespace lss
}  // namespace nmt
