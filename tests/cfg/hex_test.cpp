// cfg/hex.hpp: the one hex formatter (upper-case digits, as CANopen documents and CiA 306 files
// write numbers). Expected texts are written out by hand.
#include "cfg/hex.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <string_view>

namespace cfg {
namespace {

TEST(Hex, DigitsAreUpperCaseAndZeroPadded) {
  EXPECT_EQ(hex_digits(0x1A, 4), "001A");
  EXPECT_EQ(hex_digits(0x1A), "1A");
  EXPECT_EQ(hex_digits(0), "0");
  EXPECT_EQ(hex_digits(0x12345, 4), "12345");  // padding never cuts digits
  EXPECT_EQ(hex_digits(UINT64_MAX), "FFFFFFFFFFFFFFFF");
  EXPECT_EQ(hex(1000, 4), "0x03E8");
  EXPECT_EQ(hex(0x80000180, 8), "0x80000180");  // a PDO COB-ID with bit 31 set (CiA 301)
}

// The buffer form writes exactly the characters, no terminator, and says where it stopped.
TEST(Hex, WriteHexDigitsFillsTheBufferAndReturnsItsEnd) {
  struct Case {
    std::uint64_t value;
    int min_digits;
    std::string_view text;
  };
  for (const Case& c :
       {Case{0, 1, "0"}, Case{0, 16, "0000000000000000"}, Case{0xF, 1, "F"}, Case{0x10, 1, "10"},
        Case{0x1A, 4, "001A"}, Case{0x1017, 4, "1017"}, Case{0xABCDEF, 2, "ABCDEF"},
        Case{0x0123456789ABCDEF, 1, "123456789ABCDEF"}, Case{UINT64_MAX, 1, "FFFFFFFFFFFFFFFF"},
        Case{0x7, 20, "00000000000000000007"}}) {
    char buf[32];
    std::string(sizeof buf, '#').copy(buf, sizeof buf);
    char* end = write_hex_digits(buf, c.value, c.min_digits);
    EXPECT_EQ(std::string_view(buf, static_cast<std::size_t>(end - buf)), c.text) << c.text;
    if (end < buf + sizeof buf) {
      EXPECT_EQ(*end, '#') << c.text;  // nothing past the end
    }
  }
}

}  // namespace
}  // namespace cfg
