// The CiA 301 basic data type table (CiA 301 §7.1 encodings, §7.4.7.1 data type indices).
// CiA 301 is not in spec/: the indices and sizes below are from the public descriptions of
// CiA 301 v4.2 Table 44 and §7.1.
#include "cfg/data_type.hpp"

#include <gtest/gtest.h>

#include <string_view>

namespace cfg {
namespace {

struct Row {
  std::uint16_t index;
  std::string_view name;
  std::uint8_t size_bytes;  // 0: variable size
};

// CiA 301 Table 44 with the sizes of §7.1 (INTEGERn / UNSIGNEDn are n/8 bytes,
// TIME_OF_DAY and TIME_DIFFERENCE 48 bits).
constexpr Row kCia301Types[] = {
    {0x0001, "BOOLEAN", 1},         {0x0002, "INTEGER8", 1},       {0x0003, "INTEGER16", 2},
    {0x0004, "INTEGER32", 4},       {0x0005, "UNSIGNED8", 1},      {0x0006, "UNSIGNED16", 2},
    {0x0007, "UNSIGNED32", 4},      {0x0008, "REAL32", 4},         {0x0009, "VISIBLE_STRING", 0},
    {0x000A, "OCTET_STRING", 0},    {0x000B, "UNICODE_STRING", 0}, {0x000C, "TIME_OF_DAY", 6},
    {0x000D, "TIME_DIFFERENCE", 6}, {0x000F, "DOMAIN", 0},         {0x0010, "INTEGER24", 3},
    {0x0011, "REAL64", 8},          {0x0012, "INTEGER40", 5},      {0x0013, "INTEGER48", 6},
    {0x0014, "INTEGER56", 7},       {0x0015, "INTEGER64", 8},      {0x0016, "UNSIGNED24", 3},
    {0x0018, "UNSIGNED40", 5},      {0x0019, "UNSIGNED48", 6},     {0x001A, "UNSIGNED56", 7},
    {0x001B, "UNSIGNED64", 8},
};

TEST(DataType, TableMatchesCia301IndicesNamesAndSizes) {
  for (const Row& row : kCia301Types) {
    SCOPED_TRACE(row.name);
    const DataTypeInfo* info = find_data_type(row.index);
    ASSERT_NE(info, nullptr);
    EXPECT_EQ(static_cast<std::uint16_t>(info->type), row.index);
    EXPECT_EQ(info->name, row.name);
    EXPECT_EQ(info->size_bytes, row.size_bytes);
    EXPECT_EQ(is_variable_size(info->type), row.size_bytes == 0);
  }
}

TEST(DataType, Unsigned40IsFiveBytesAndInteger24IsThree) {
  EXPECT_EQ(data_type_info(DataType::Unsigned40).size_bytes, 5);
  EXPECT_EQ(data_type_info(DataType::Integer24).size_bytes, 3);
  EXPECT_EQ(data_type_info(DataType::Unsigned56).size_bytes, 7);
}

TEST(DataType, ComplexAndReservedIndicesAreNotBasicTypes) {
  EXPECT_EQ(find_data_type(0x0000), nullptr);
  EXPECT_EQ(find_data_type(0x000E), nullptr);  // reserved in CiA 301 Table 44
  EXPECT_EQ(find_data_type(0x0017), nullptr);  // reserved between UNSIGNED24 and UNSIGNED40
  EXPECT_EQ(find_data_type(0x0020), nullptr);  // PDO_COMMUNICATION_PARAMETER (DEFSTRUCT)
  EXPECT_EQ(find_data_type(0x0023), nullptr);  // IDENTITY (DEFSTRUCT)
}

TEST(DataType, NamesLookUpCaseInsensitively) {
  EXPECT_EQ(data_type_from_name("unsigned16"), DataType::Unsigned16);
  EXPECT_EQ(data_type_from_name("Visible_String"), DataType::VisibleString);
  EXPECT_EQ(data_type_from_name("UNSIGNED17"), std::nullopt);
  EXPECT_EQ(to_string(DataType::TimeDifference), "TIME_DIFFERENCE");
}

TEST(DataType, IntegerClassification) {
  EXPECT_TRUE(is_integer(DataType::Integer56));
  EXPECT_TRUE(is_integer(DataType::Unsigned24));
  EXPECT_FALSE(is_integer(DataType::Boolean));
  EXPECT_FALSE(is_integer(DataType::Real32));
  EXPECT_FALSE(is_integer(DataType::TimeOfDay));
  EXPECT_EQ(data_type_info(DataType::Integer40).type_class, TypeClass::Signed);
  EXPECT_EQ(data_type_info(DataType::Unsigned48).type_class, TypeClass::Unsigned);
}

}  // namespace
}  // namespace cfg
