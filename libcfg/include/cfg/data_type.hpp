// CiA 301 basic data types (§7.1 / object dictionary indices 0001h-001Bh) and their sizes.
// This is the one table of type sizes and names in the project.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace cfg {

/// Data type index as used in DataType= of an EDS/DCF and in the object dictionary (CiA 301
/// §7.4.7.1).
enum class DataType : std::uint16_t {
  Boolean = 0x0001,
  Integer8 = 0x0002,
  Integer16 = 0x0003,
  Integer32 = 0x0004,
  Unsigned8 = 0x0005,
  Unsigned16 = 0x0006,
  Unsigned32 = 0x0007,
  Real32 = 0x0008,
  VisibleString = 0x0009,
  OctetString = 0x000A,
  UnicodeString = 0x000B,
  TimeOfDay = 0x000C,
  TimeDifference = 0x000D,
  Domain = 0x000F,
  Integer24 = 0x0010,
  Real64 = 0x0011,
  Integer40 = 0x0012,
  Integer48 = 0x0013,
  Integer56 = 0x0014,
  Integer64 = 0x0015,
  Unsigned24 = 0x0016,
  Unsigned40 = 0x0018,
  Unsigned48 = 0x0019,
  Unsigned56 = 0x001A,
  Unsigned64 = 0x001B,
};

/// How values of a type are represented and encoded.
enum class TypeClass {
  Boolean,        ///< one byte, 0 or 1
  Signed,         ///< two's complement, little-endian, size_bytes wide
  Unsigned,       ///< little-endian, size_bytes wide
  Real,           ///< IEEE 754 binary32 / binary64, little-endian
  VisibleString,  ///< bytes, no terminator on the bus
  OctetString,    ///< bytes
  UnicodeString,  ///< UTF-16LE code units
  Time,           ///< TIME_OF_DAY / TIME_DIFFERENCE: 48 bits (ms: 28 bits, 4 reserved, days: 16)
  Domain,         ///< arbitrary bytes
};

struct DataTypeInfo {
  DataType type;
  std::string_view name;  ///< CiA 301 name, e.g. "UNSIGNED24"
  TypeClass type_class;
  std::uint8_t size_bytes;  ///< encoded size; 0 for variable-size types (strings, DOMAIN)
};

/// The basic type with that index, or nullptr (unknown index, or a complex type such as 0020h).
const DataTypeInfo* find_data_type(std::uint16_t index);
const DataTypeInfo& data_type_info(DataType type);
/// Looks up a type by its CiA 301 name, case-insensitively ("unsigned16" -> Unsigned16).
std::optional<DataType> data_type_from_name(std::string_view name);

inline std::string_view to_string(DataType type) {
  return data_type_info(type).name;
}
inline bool is_integer(DataType type) {
  auto c = data_type_info(type).type_class;
  return c == TypeClass::Signed || c == TypeClass::Unsigned;
}
/// Variable-size types: VISIBLE_STRING, OCTET_STRING, UNICODE_STRING, DOMAIN.
inline bool is_variable_size(DataType type) {
  return data_type_info(type).size_bytes == 0;
}

}  // namespace cfg
