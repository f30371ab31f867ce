// SDO abort codes (the abort code table of CiA 301 §7.2.4.3.17): the one enum and the one table
// of texts, in the vocabulary both libraries share: libcfg answers with them (the configuration
// manager, a device's write rules), libnmt sends and reports them (nmt/sdo/sdo_abort.hpp names them
// nmt::SdoAbort). Implemented from public knowledge of CiA 301 (the standard is not in spec/).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <span>
#include <string>
#include <string_view>

namespace cfg {

/// An SDO abort code as sent on the bus (bytes 4..7 of an abort frame, little-endian).
/// `None` (0) is not a code of the standard: it means "no abort", the success value of every
/// SDO-side operation in this library. Values outside the list may arrive from a device; they
/// keep their number and describe() calls them "unknown abort code".
enum class SdoAbort : std::uint32_t {
  None = 0,
  ToggleBitNotAlternated = 0x05030000,
  Timeout = 0x05040000,
  InvalidCommandSpecifier = 0x05040001,
  InvalidBlockSize = 0x05040002,
  InvalidSequenceNumber = 0x05040003,
  CrcError = 0x05040004,
  OutOfMemory = 0x05040005,
  UnsupportedAccess = 0x06010000,
  ReadOfWriteOnly = 0x06010001,
  WriteOfReadOnly = 0x06010002,
  ObjectDoesNotExist = 0x06020000,
  CannotBeMapped = 0x06040041,
  PdoLengthExceeded = 0x06040042,
  ParameterIncompatibility = 0x06040043,
  InternalIncompatibility = 0x06040047,
  HardwareError = 0x06060000,
  LengthMismatch = 0x06070010,
  LengthTooHigh = 0x06070012,
  LengthTooLow = 0x06070013,
  SubIndexDoesNotExist = 0x06090011,
  ValueRangeExceeded = 0x06090030,
  ValueTooHigh = 0x06090031,
  ValueTooLow = 0x06090032,
  MaxLessThanMin = 0x06090036,
  ResourceNotAvailable = 0x060A0023,
  General = 0x08000000,
  CannotStoreOrTransfer = 0x08000020,
  LocalControl = 0x08000021,
  DeviceState = 0x08000022,
  NoObjectDictionary = 0x08000023,
  NoDataAvailable = 0x08000024,
};

/// One row of the abort-code table.
struct SdoAbortInfo {
  SdoAbort code;
  std::string_view text;  ///< lower-case description after the CiA 301 abort code table
};

/// Every code of the CiA 301 abort code table (not `None`), in numeric order.
std::span<const SdoAbortInfo> sdo_abort_table();

/// True for `None` and every code of the table.
bool is_known(SdoAbort code);

/// The text of a code: "sub-index does not exist"; "no abort" for None; "unknown abort code" for
/// a value outside the table.
std::string_view describe(SdoAbort code);

/// `0x06090011 (sub-index does not exist)`; unknown values: `0x12345678 (unknown abort code)`.
std::string to_string(SdoAbort code);

/// Writes to_string(code), so test failures and logs show the code and its text.
std::ostream& operator<<(std::ostream& os, SdoAbort code);

/// The raw 32-bit value (as on the bus).
constexpr std::uint32_t to_u32(SdoAbort code) {
  return static_cast<std::uint32_t>(code);
}

}  // namespace cfg
