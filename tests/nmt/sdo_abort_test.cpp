// SDO abort codes, the CiA 301 abort code table (from public knowledge of CiA 301; not in spec/).
#include "nmt/sdo/sdo_abort.hpp"

#include <gtest/gtest.h>

#include <set>
#include <sstream>

namespace nmt {
namespace {

TEST(SdoAbort, CodesHaveTheValuesOfTheCiA301AbortTable) {
  EXPECT_EQ(to_u32(SdoAbort::ToggleBitNotAlternated), 0x05030000u);
  EXPECT_EQ(to_u32(SdoAbort::Timeout), 0x05040000u);
  EXPECT_EQ(to_u32(SdoAbort::InvalidCommandSpecifier), 0x05040001u);
  EXPECT_EQ(to_u32(SdoAbort::InvalidBlockSize), 0x05040002u);
  EXPECT_EQ(to_u32(SdoAbort::InvalidSequenceNumber), 0x05040003u);
  EXPECT_EQ(to_u32(SdoAbort::CrcError), 0x05040004u);
  EXPECT_EQ(to_u32(SdoAbort::OutOfMemory), 0x05040005u);
  EXPECT_EQ(to_u32(SdoAbort::UnsupportedAccess), 0x06010000u);
  EXPECT_EQ(to_u32(SdoAbort::ReadOfWriteOnly), 0x06010001u);
  EXPECT_EQ(to_u32(SdoAbort::WriteOfReadOnly), 0x06010002u);
  EXPECT_EQ(to_u32(SdoAbort::ObjectDoesNotExist), 0x06020000u);
  EXPECT_EQ(to_u32(SdoAbort::CannotBeMapped), 0x06040041u);
  EXPECT_EQ(to_u32(SdoAbort::PdoLengthExceeded), 0x06040042u);
  EXPECT_EQ(to_u32(SdoAbort::ParameterIncompatibility), 0x06040043u);
  EXPECT_EQ(to_u32(SdoAbort::InternalIncompatibility), 0x06040047u);
  EXPECT_EQ(to_u32(SdoAbort::HardwareError), 0x06060000u);
  EXPECT_EQ(to_u32(SdoAbort::LengthMismatch), 0x06070010u);
  EXPECT_EQ(to_u32(SdoAbort::LengthTooHigh), 0x06070012u);
  EXPECT_EQ(to_u32(SdoAbort::LengthTooLow), 0x06070013u);
  EXPECT_EQ(to_u32(SdoAbort::SubIndexDoesNotExist), 0x06090011u);
  EXPECT_EQ(to_u32(SdoAbort::ValueRangeExceeded), 0x06090030u);
  EXPECT_EQ(to_u32(SdoAbort::ValueTooHigh), 0x06090031u);
  EXPECT_EQ(to_u32(SdoAbort::ValueTooLow), 0x06090032u);
  EXPECT_EQ(to_u32(SdoAbort::MaxLessThanMin), 0x06090036u);
  EXPECT_EQ(to_u32(SdoAbort::ResourceNotAvailable), 0x060A0023u);
  EXPECT_EQ(to_u32(SdoAbort::General), 0x08000000u);
  EXPECT_EQ(to_u32(SdoAbort::CannotStoreOrTransfer), 0x08000020u);
  EXPECT_EQ(to_u32(SdoAbort::LocalControl), 0x08000021u);
  EXPECT_EQ(to_u32(SdoAbort::DeviceState), 0x08000022u);
  EXPECT_EQ(to_u32(SdoAbort::NoObjectDictionary), 0x08000023u);
  EXPECT_EQ(to_u32(SdoAbort::NoDataAvailable), 0x08000024u);
}

TEST(SdoAbort, TableHoldsEveryCodeOnceWithAText) {
  // The CiA 301 abort code table lists 31 codes.
  EXPECT_EQ(sdo_abort_table().size(), 31u);
  std::set<std::uint32_t> seen;
  for (const auto& row : sdo_abort_table()) {
    EXPECT_TRUE(seen.insert(to_u32(row.code)).second) << to_string(row.code);
    EXPECT_FALSE(row.text.empty());
    EXPECT_EQ(describe(row.code), row.text);
    EXPECT_TRUE(is_known(row.code));
  }
}

TEST(SdoAbort, FormatsCodeAsHexWithText) {
  EXPECT_EQ(to_string(SdoAbort::SubIndexDoesNotExist), "0x06090011 (sub-index does not exist)");
  EXPECT_EQ(to_string(SdoAbort::ToggleBitNotAlternated), "0x05030000 (toggle bit not alternated)");
  EXPECT_EQ(to_string(SdoAbort::None), "0x00000000 (no abort)");
  std::ostringstream os;
  os << SdoAbort::Timeout;
  EXPECT_EQ(os.str(), "0x05040000 (SDO protocol timed out)");
}

TEST(SdoAbort, UnknownCodesKeepTheirNumber) {
  const auto code = static_cast<SdoAbort>(0x12345678);
  EXPECT_FALSE(is_known(code));
  EXPECT_EQ(describe(code), "unknown abort code");
  EXPECT_EQ(to_string(code), "0x12345678 (unknown abort code)");
  // Neighbours of real codes are not real codes.
  EXPECT_FALSE(is_known(static_cast<SdoAbort>(0x06090012)));
}

}  // namespace
}  // namespace nmt
