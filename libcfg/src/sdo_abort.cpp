#include "cfg/sdo_abort.hpp"

#include <algorithm>
#include <array>
#include <ostream>

#include "cfg/hex.hpp"

namespace cfg {

namespace {

// The CiA 301 abort code table, texts in lower case as the standard words them.
constexpr std::array<SdoAbortInfo, 31> kTable{{
    {SdoAbort::ToggleBitNotAlternated, "toggle bit not alternated"},
    {SdoAbort::Timeout, "SDO protocol timed out"},
    {SdoAbort::InvalidCommandSpecifier, "client/server command specifier not valid or unknown"},
    {SdoAbort::InvalidBlockSize, "invalid block size"},
    {SdoAbort::InvalidSequenceNumber, "invalid sequence number"},
    {SdoAbort::CrcError, "CRC error"},
    {SdoAbort::OutOfMemory, "out of memory"},
    {SdoAbort::UnsupportedAccess, "unsupported access to an object"},
    {SdoAbort::ReadOfWriteOnly, "attempt to read a write only object"},
    {SdoAbort::WriteOfReadOnly, "attempt to write a read only object"},
    {SdoAbort::ObjectDoesNotExist, "object does not exist in the object dictionary"},
    {SdoAbort::CannotBeMapped, "object cannot be mapped to the PDO"},
    {SdoAbort::PdoLengthExceeded,
     "the number and length of the objects to be mapped would exceed PDO length"},
    {SdoAbort::ParameterIncompatibility, "general parameter incompatibility reason"},
    {SdoAbort::InternalIncompatibility, "general internal incompatibility in the device"},
    {SdoAbort::HardwareError, "access failed due to a hardware error"},
    {SdoAbort::LengthMismatch,
     "data type does not match, length of service parameter does not match"},
    {SdoAbort::LengthTooHigh, "data type does not match, length of service parameter too high"},
    {SdoAbort::LengthTooLow, "data type does not match, length of service parameter too low"},
    {SdoAbort::SubIndexDoesNotExist, "sub-index does not exist"},
    {SdoAbort::ValueRangeExceeded, "invalid value for parameter (download only)"},
    {SdoAbort::ValueTooHigh, "value of parameter written too high (download only)"},
    {SdoAbort::ValueTooLow, "value of parameter written too low (download only)"},
    {SdoAbort::MaxLessThanMin, "maximum value is less than minimum value"},
    {SdoAbort::ResourceNotAvailable, "resource not available: SDO connection"},
    {SdoAbort::General, "general error"},
    {SdoAbort::CannotStoreOrTransfer, "data cannot be transferred or stored to the application"},
    {SdoAbort::LocalControl,
     "data cannot be transferred or stored to the application because of local control"},
    {SdoAbort::DeviceState,
     "data cannot be transferred or stored to the application because of the present device "
     "state"},
    {SdoAbort::NoObjectDictionary,
     "object dictionary dynamic generation fails or no object dictionary is present"},
    {SdoAbort::NoDataAvailable, "no data available"},
}};

static_assert(std::is_sorted(kTable.begin(), kTable.end(),
                             [](const SdoAbortInfo& a, const SdoAbortInfo& b) {
                               return to_u32(a.code) < to_u32(b.code);
                             }),
              "the table is kept in numeric order");

const SdoAbortInfo* find(SdoAbort code) {
  auto it = std::lower_bound(
      kTable.begin(), kTable.end(), code,
      [](const SdoAbortInfo& row, SdoAbort c) { return to_u32(row.code) < to_u32(c); });
  return it != kTable.end() && it->code == code ? &*it : nullptr;
}

}  // namespace

std::span<const SdoAbortInfo> sdo_abort_table() {
  return kTable;
}

bool is_known(SdoAbort code) {
  return code == SdoAbort::None || find(code) != nullptr;
}

std::string_view describe(SdoAbort code) {
  if (code == SdoAbort::None) return "no abort";
  const auto* row = find(code);
  return row ? row->text : "unknown abort code";
}

std::string to_string(SdoAbort code) {
  std::string out = hex(to_u32(code), 8);
  out += " (";
  out += describe(code);
  out += ')';
  return out;
}

std::ostream& operator<<(std::ostream& os, SdoAbort code) {
  return os << to_string(code);
}

}  // namespace cfg
