#include "cfg/data_type.hpp"

#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>

#include "cfg/object_dictionary.hpp"

namespace cfg {
namespace {

// CiA 301 §7.4.7.1 Table 44 (data type indices) with the encoded sizes of §7.1.
constexpr std::array<DataTypeInfo, 25> kDataTypes{{
    {DataType::Boolean, "BOOLEAN", TypeClass::Boolean, 1},
    {DataType::Integer8, "INTEGER8", TypeClass::Signed, 1},
    {DataType::Integer16, "INTEGER16", TypeClass::Signed, 2},
    {DataType::Integer32, "INTEGER32", TypeClass::Signed, 4},
    {DataType::Unsigned8, "UNSIGNED8", TypeClass::Unsigned, 1},
    {DataType::Unsigned16, "UNSIGNED16", TypeClass::Unsigned, 2},
    {DataType::Unsigned32, "UNSIGNED32", TypeClass::Unsigned, 4},
    {DataType::Real32, "REAL32", TypeClass::Real, 4},
    {DataType::VisibleString, "VISIBLE_STRING", TypeClass::VisibleString, 0},
    {DataType::OctetString, "OCTET_STRING", TypeClass::OctetString, 0},
    {DataType::UnicodeString, "UNICODE_STRING", TypeClass::UnicodeString, 0},
    {DataType::TimeOfDay, "TIME_OF_DAY", TypeClass::Time, 6},
    {DataType::TimeDifference, "TIME_DIFFERENCE", TypeClass::Time, 6},
    {DataType::Domain, "DOMAIN", TypeClass::Domain, 0},
    {DataType::Integer24, "INTEGER24", TypeClass::Signed, 3},
    {DataType::Real64, "REAL64", TypeClass::Real, 8},
    {DataType::Integer40, "INTEGER40", TypeClass::Signed, 5},
    {DataType::Integer48, "INTEGER48", TypeClass::Signed, 6},
    {DataType::Integer56, "INTEGER56", TypeClass::Signed, 7},
    {DataType::Integer64, "INTEGER64", TypeClass::Signed, 8},
    {DataType::Unsigned24, "UNSIGNED24", TypeClass::Unsigned, 3},
    {DataType::Unsigned40, "UNSIGNED40", TypeClass::Unsigned, 5},
    {DataType::Unsigned48, "UNSIGNED48", TypeClass::Unsigned, 6},
    {DataType::Unsigned56, "UNSIGNED56", TypeClass::Unsigned, 7},
    {DataType::Unsigned64, "UNSIGNED64", TypeClass::Unsigned, 8},
}};

// Position in kDataTypes by index (0001h-001Bh), -1 where CiA 301 defines no basic type: a
// value check asks for its type's entry several times per value (and a file holds tens of
// thousands of values), so the lookup is one load, not a scan.
constexpr std::size_t kLastBasicIndex = 0x1B;
constexpr auto kPositionByIndex = [] {
  std::array<std::int8_t, kLastBasicIndex + 1> positions{};
  positions.fill(-1);
  for (std::size_t i = 0; i < kDataTypes.size(); ++i) {
    positions[static_cast<std::size_t>(kDataTypes[i].type)] = static_cast<std::int8_t>(i);
  }
  return positions;
}();

}  // namespace

const DataTypeInfo* find_data_type(std::uint16_t index) {
  if (index > kLastBasicIndex || kPositionByIndex[index] < 0) return nullptr;
  return &kDataTypes[static_cast<std::size_t>(kPositionByIndex[index])];
}

const DataTypeInfo& data_type_info(DataType type) {
  const DataTypeInfo* info = find_data_type(static_cast<std::uint16_t>(type));
  assert(info != nullptr && "DataType enumerators are all in the table");
  return *info;
}

std::optional<DataType> data_type_from_name(std::string_view name) {
  for (const auto& info : kDataTypes) {
    if (iequals(info.name, name)) return info.type;
  }
  return std::nullopt;
}

}  // namespace cfg
