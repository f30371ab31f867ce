// Slowscan: every LSS device of one vendor-ID and product code by identify remote slave (CiA
// 305 46h-4Bh, nmt/lss/lss_search.hpp). The bus is a set of devices answering as the LSS slave
// does: any device whose vendor-ID and product code equal the range's and whose revision and
// serial number lie inside its bounds (both included, lely-core src/co/lss.c) answers.
#include <gtest/gtest.h>

#include <vector>

#include "nmt/lss/lss_search.hpp"

namespace nmt {
namespace {

bool answers(const std::vector<LssAddress>& devices, const LssAddressRange& r) {
  for (const auto& d : devices) {
    if (d.vendor_id == r.vendor_id && d.product_code == r.product_code &&
        d.revision >= r.revision_low && d.revision <= r.revision_high && d.serial >= r.serial_low &&
        d.serial <= r.serial_high) {
      return true;
    }
  }
  return false;
}

LssAddressSearch search(const std::vector<LssAddress>& devices, std::uint32_t vendor,
                        std::uint32_t product) {
  LssAddressSearch s(vendor, product);
  for (int guard = 0; guard < 100000; ++guard) {
    const auto range = s.next();
    if (!range) break;
    s.answered(answers(devices, *range));
  }
  EXPECT_FALSE(s.next().has_value()) << "the search ends";
  return s;
}

TEST(LssAddressSearch, FirstIdentifiesTheWholeRevisionAndSerialRangeOfTheProduct) {
  LssAddressSearch s(0x7E57C0DE, 0x305);
  const auto first = s.next();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->vendor_id, 0x7E57C0DEu);
  EXPECT_EQ(first->product_code, 0x305u);
  EXPECT_EQ(first->revision_low, 0u);
  EXPECT_EQ(first->revision_high, 0xFFFFFFFFu);
  EXPECT_EQ(first->serial_low, 0u);
  EXPECT_EQ(first->serial_high, 0xFFFFFFFFu);
  s.answered(false);
  EXPECT_FALSE(s.next()) << "no device of the product: one request";
  EXPECT_TRUE(s.found().empty());
  EXPECT_EQ(s.requests(), 1u);
}

TEST(LssAddressSearch, OneDeviceTakesOneRequestAndTwoPerHalvingOf64Bits) {
  // 32 halvings of the revision range and 32 of the serial range, each probing both halves.
  const std::vector<LssAddress> devices{{0x7E57C0DE, 0x305, 0x00010002, 0x00001001}};
  const auto s = search(devices, 0x7E57C0DE, 0x305);
  EXPECT_EQ(s.found(), devices);
  EXPECT_EQ(s.requests(), 1u + 2u * 64u);
}

TEST(LssAddressSearch, FindsEveryDeviceOfTheProductAscendingAndNoOther) {
  // Two serial numbers that differ in one bit, the extremes of both ranges, and devices of
  // another product and another vendor, which are not asked for.
  const std::vector<LssAddress> devices{
      {0x7E57C0DE, 0x305, 0x00010002, 0x00001003}, {0x7E57C0DE, 0x305, 0xFFFFFFFF, 0xFFFFFFFF},
      {0x7E57C0DE, 0x305, 0x00010002, 0x00001001}, {0x7E57C0DE, 0x305, 0, 0},
      {0x7E57C0DE, 0x306, 0x00010002, 0x00001001}, {0x0000012F, 0x305, 0x00010002, 0x00001001}};
  const auto s = search(devices, 0x7E57C0DE, 0x305);
  EXPECT_EQ(s.found(), (std::vector<LssAddress>{{0x7E57C0DE, 0x305, 0, 0},
                                                {0x7E57C0DE, 0x305, 0x00010002, 0x00001001},
                                                {0x7E57C0DE, 0x305, 0x00010002, 0x00001003},
                                                {0x7E57C0DE, 0x305, 0xFFFFFFFF, 0xFFFFFFFF}}));
}

}  // namespace
}  // namespace nmt
