// The CiA 301 SDO abort codes libcfg answers with (the abort code table of CiA 301 §7.2.4.3.17):
// the configuration manager's (config_manager.hpp) and the write rules of a device
// (write_acceptance.hpp). libcfg cannot use libnmt's nmt::SdoAbort, so ConfigAbort carries the
// same numbers; nmt::to_sdo_abort (nmt/sdo_abort.hpp) converts, and libnmt's table has the texts.
#pragma once

#include <cstdint>

namespace cfg {

/// A CiA 301 SDO abort code; `None` (0) is no abort.
enum class ConfigAbort : std::uint32_t {
  None = 0,
  OutOfMemory = 0x05040005,
  ReadOfWriteOnly = 0x06010001,
  WriteOfReadOnly = 0x06010002,
  ObjectDoesNotExist = 0x06020000,
  CannotBeMapped = 0x06040041,
  PdoLengthExceeded = 0x06040042,
  ParameterIncompatibility = 0x06040043,
  LengthMismatch = 0x06070010,
  LengthTooHigh = 0x06070012,
  LengthTooLow = 0x06070013,
  SubIndexDoesNotExist = 0x06090011,
  ValueRangeExceeded = 0x06090030,
  ValueTooHigh = 0x06090031,
  ValueTooLow = 0x06090032,
  MaxLessThanMin = 0x06090036,
  CannotStoreOrTransfer = 0x08000020,
  DeviceState = 0x08000022,
  DataSetEmpty = 0x08000024,
};

}  // namespace cfg
