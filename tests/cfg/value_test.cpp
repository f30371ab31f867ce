// Typed values: CiA 306 value text (§4.6.3) and CiA 301 §7.1 little-endian encodings.
// CiA 301 and CiA 306 are not in spec/; expected bytes are computed by hand from the public
// descriptions (two's complement little-endian integers, IEEE 754 reals; the REAL bytes were
// checked with Python's struct.pack('<f') / ('<d')).
#include "cfg/value.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace cfg {
namespace {

using ::testing::HasSubstr;

using Bytes = std::vector<std::uint8_t>;

Value parsed(DataType type, std::string_view text,
             std::optional<std::uint8_t> node_id = std::nullopt) {
  auto r = parse_value(type, text, node_id);
  EXPECT_TRUE(r.ok()) << "\"" << text << "\": " << (r.ok() ? "" : r.error().message);
  return r.ok() ? r.value() : Value{};
}

std::string error_of(DataType type, std::string_view text,
                     std::optional<std::uint8_t> node_id = std::nullopt) {
  auto r = parse_value(type, text, node_id);
  EXPECT_FALSE(r.ok()) << "\"" << text << "\" was accepted as " << format_value(r.value());
  return r.ok() ? std::string() : r.error().message;
}

Bytes encoded(DataType type, std::string_view text) {
  return encode(parsed(type, text));
}

// lely's DCFs (corpus lely-core/co-sdev.dcf) write REALs as hex IEEE 754 bit patterns and
// TIME_OF_DAY as "DAYS MS". Pi: 0x40490FDB (binary32), 0x400921FB54442D18 (binary64).
TEST(Value, RealAsHexIsTheIeee754BitPattern) {
  EXPECT_EQ(parsed(DataType::Real32, "0x40490FDB").as_real(),
            static_cast<double>(3.14159274101257324f));
  EXPECT_EQ(encoded(DataType::Real32, "0x40490FDB"), (Bytes{0xDB, 0x0F, 0x49, 0x40}));
  EXPECT_EQ(parsed(DataType::Real64, "0x400921FB54442D18").as_real(), 3.141592653589793);
  error_of(DataType::Real32, "0x140490FDB");  // 33 bits do not fit a binary32
}

// CiA 301 §7.1 TIME_OF_DAY: ms (28 bits), 4 reserved bits, days (16 bits), little-endian.
// 365 days, 43200000 ms (12:00): ms 0x02932E00, days 0x016D.
TEST(Value, TimeOfDayAsDaysAndMilliseconds) {
  EXPECT_EQ(encoded(DataType::TimeOfDay, "365 43200000"),
            (Bytes{0x00, 0x2E, 0x93, 0x02, 0x6D, 0x01}));
  EXPECT_EQ(encoded(DataType::TimeDifference, "365 43200000"),
            (Bytes{0x00, 0x2E, 0x93, 0x02, 0x6D, 0x01}));
  error_of(DataType::TimeOfDay, "1 268435456");  // ms needs more than 28 bits
  error_of(DataType::TimeOfDay, "65536 0");      // days needs more than 16 bits
}

// ---- Ranges (CiA 301 §7.1: INTEGERn is two's complement, UNSIGNEDn 0..2^n-1) ----

TEST(Value, IntegerRangesFollowTheirBitWidth) {
  EXPECT_EQ(signed_min(DataType::Integer8), -128);
  EXPECT_EQ(signed_max(DataType::Integer8), 127);
  EXPECT_EQ(signed_min(DataType::Integer24), -8388608);
  EXPECT_EQ(signed_max(DataType::Integer24), 8388607);
  EXPECT_EQ(signed_min(DataType::Integer40), -549755813888);
  EXPECT_EQ(signed_max(DataType::Integer56), 36028797018963967);
  EXPECT_EQ(signed_min(DataType::Integer64), std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(unsigned_max(DataType::Unsigned8), 255U);
  EXPECT_EQ(unsigned_max(DataType::Unsigned24), 16777215U);
  EXPECT_EQ(unsigned_max(DataType::Unsigned40), 1099511627775U);
  EXPECT_EQ(unsigned_max(DataType::Unsigned64), std::numeric_limits<std::uint64_t>::max());
}

TEST(Value, RejectsUnsigned8AboveRangeNamingTheRange) {
  EXPECT_EQ(error_of(DataType::Unsigned8, "300"), "value 300 out of range for UNSIGNED8 (0..255)");
}

TEST(Value, RejectsInteger24OutsideRange) {
  EXPECT_EQ(parsed(DataType::Integer24, "-8388608").as_signed(), -8388608);
  EXPECT_EQ(parsed(DataType::Integer24, "8388607").as_signed(), 8388607);
  EXPECT_EQ(error_of(DataType::Integer24, "8388608"),
            "value 8388608 out of range for INTEGER24 (-8388608..8388607)");
  EXPECT_EQ(error_of(DataType::Integer24, "-8388609"),
            "value -8388609 out of range for INTEGER24 (-8388608..8388607)");
}

TEST(Value, RejectsNegativeNumbersForUnsignedTypes) {
  EXPECT_EQ(error_of(DataType::Unsigned16, "-1"),
            "value -1 out of range for UNSIGNED16 (0..65535)");
  error_of(DataType::Unsigned32, "-0x10");
  error_of(DataType::Boolean, "-1");
  // "-0" is zero, not a negative number.
  EXPECT_EQ(parsed(DataType::Unsigned8, "-0").as_unsigned(), 0U);
}

TEST(Value, AcceptsFullUnsigned64AndRejectsBeyond64Bits) {
  EXPECT_EQ(parsed(DataType::Unsigned64, "18446744073709551615").as_unsigned(),
            std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(parsed(DataType::Unsigned64, "0xFFFFFFFFFFFFFFFF").as_unsigned(),
            std::numeric_limits<std::uint64_t>::max());
  error_of(DataType::Unsigned64, "18446744073709551616");
  error_of(DataType::Unsigned64, "0x10000000000000000");
  EXPECT_EQ(parsed(DataType::Integer64, "-9223372036854775808").as_signed(),
            std::numeric_limits<std::int64_t>::min());
  error_of(DataType::Integer64, "9223372036854775808");
  error_of(DataType::Integer64, "-9223372036854775809");
}

// ---- Number syntax (CiA 306 §4.6.3: decimal, 0x hex, leading 0 octal) ----

TEST(Value, ReadsDecimalHexAndOctal) {
  EXPECT_EQ(parsed(DataType::Unsigned16, "4660").as_unsigned(), 0x1234U);
  EXPECT_EQ(parsed(DataType::Unsigned16, "0x1234").as_unsigned(), 0x1234U);
  EXPECT_EQ(parsed(DataType::Unsigned16, "0X1234").as_unsigned(), 0x1234U);
  EXPECT_EQ(parsed(DataType::Unsigned16, "0xabCD").as_unsigned(), 0xABCDU);
  EXPECT_EQ(parsed(DataType::Unsigned16, "010").as_unsigned(), 8U);  // octal, as in C
  EXPECT_EQ(parsed(DataType::Unsigned16, "0").as_unsigned(), 0U);
  EXPECT_EQ(parsed(DataType::Unsigned16, "00").as_unsigned(), 0U);
  EXPECT_EQ(parsed(DataType::Integer16, "-010").as_signed(), -8);
  EXPECT_EQ(parsed(DataType::Integer32, "-5").as_signed(), -5);
  EXPECT_EQ(parsed(DataType::Unsigned32, "  1000 ").as_unsigned(), 1000U);
}

TEST(Value, RejectsJunk) {
  for (std::string_view junk : {"12abc", "0x", "0X", "--5", "+5", "- 5", "08", "0x1G", "1 2", "abc",
                                "0x1234567890ABCDEFLL", "1.5", "1e3", "-", "$", "0x 12"}) {
    SCOPED_TRACE(junk);
    error_of(DataType::Integer64, junk);
    error_of(DataType::Unsigned32, junk);
  }
}

TEST(Value, RejectsEmptyTextForNumericTypes) {
  for (DataType t : {DataType::Boolean, DataType::Integer8, DataType::Unsigned32, DataType::Real32,
                     DataType::Real64, DataType::TimeOfDay}) {
    SCOPED_TRACE(to_string(t));
    EXPECT_EQ(error_of(t, ""), "empty value for " + std::string(to_string(t)));
    error_of(t, "   ");
  }
}

TEST(Value, SignedHexIsTheTwosComplementBitPatternOfTheWidth) {
  // Real device files write limits this way (e.g. python-canopen's sample.eds LowLimit of an
  // INTEGER32: 0x80000000); the value is the pattern read in the type's width.
  EXPECT_EQ(parsed(DataType::Integer32, "0x80000000").as_signed(), -2147483648);
  EXPECT_EQ(parsed(DataType::Integer64, "0xFFFFFFFFFFFFFFF6").as_signed(), -10);
  EXPECT_EQ(parsed(DataType::Integer8, "0xFF").as_signed(), -1);
  EXPECT_EQ(parsed(DataType::Integer8, "0x7F").as_signed(), 127);
  EXPECT_EQ(parsed(DataType::Integer24, "0x800000").as_signed(), -8388608);
  error_of(DataType::Integer8, "0x100");  // wider than 8 bits
  // Decimal is taken as written: 255 is not an INTEGER8.
  EXPECT_EQ(error_of(DataType::Integer8, "255"), "value 255 out of range for INTEGER8 (-128..127)");
}

// ---- $NODEID (CiA 306 §4.6.3 / DCF: "$NODEID+0x180") ----

TEST(Value, NodeIdFormulasInAnyCaseSpacingAndOrder) {
  for (std::string_view text :
       {"$NODEID+0x180", "0x180 + $NodeId", "$NodeID + 0x180", "$nodeid+384", "  0x180+$NODEID  ",
        "0x100 + $NODEID + 0x80", "$NODEID+0600"}) {
    SCOPED_TRACE(text);
    EXPECT_EQ(parsed(DataType::Unsigned32, text, 5).as_unsigned(), 0x185U);
  }
  EXPECT_EQ(parsed(DataType::Unsigned8, "$NODEID", 127).as_unsigned(), 127U);
  // EMCY COB-ID with the "invalid" bit kept (CiA 301 §7.5.2, object 1014h, bit 31).
  EXPECT_EQ(parsed(DataType::Unsigned32, "$NODEID+0x80000080", 3).as_unsigned(), 0x80000083U);
}

TEST(Value, NodeIdFormulaWithoutNodeIdSaysItNeedsOne) {
  const std::string message = error_of(DataType::Unsigned32, "$NODEID+0x180");
  EXPECT_NE(message.find("needs a node-ID"), std::string::npos) << message;
}

TEST(Value, RejectsMalformedNodeIdFormulas) {
  for (std::string_view text :
       {"$NODEID+", "+$NODEID", "$NODEID+$NODEID", "$NODEID-1", "$NODEID+0x", "$NODEID+12abc",
        "$NODEIDX+1", "2*$NODEID", "$NODEID++1"}) {
    SCOPED_TRACE(text);
    error_of(DataType::Unsigned32, text, 5);
  }
  error_of(DataType::Real32, "$NODEID+1", 5);
}

TEST(Value, NodeIdFormulaIsRangeChecked) {
  EXPECT_EQ(error_of(DataType::Unsigned8, "$NODEID+0xF0", 127),
            "value 367 out of range for UNSIGNED8 (0..255)");
}

TEST(Value, MentionsNodeIdInAnyCase) {
  EXPECT_TRUE(mentions_node_id("$NodeId+0x180"));
  EXPECT_TRUE(mentions_node_id("0x600+$nodeid"));
  EXPECT_FALSE(mentions_node_id("0x180"));
  EXPECT_FALSE(mentions_node_id("NODEID"));
}

// ---- BOOLEAN ----

TEST(Value, BooleanAcceptsZeroOneTrueFalse) {
  EXPECT_FALSE(parsed(DataType::Boolean, "0").as_bool());
  EXPECT_TRUE(parsed(DataType::Boolean, "1").as_bool());
  EXPECT_TRUE(parsed(DataType::Boolean, "0x1").as_bool());
  EXPECT_TRUE(parsed(DataType::Boolean, "TRUE").as_bool());
  EXPECT_FALSE(parsed(DataType::Boolean, "False").as_bool());
  EXPECT_EQ(error_of(DataType::Boolean, "2"), "value 2 out of range for BOOLEAN (0..1)");
  error_of(DataType::Boolean, "yes");
  EXPECT_EQ(encode(Value::from_bool(true)), (Bytes{0x01}));
}

// ---- Encodings (CiA 301 §7.1: little-endian, exact size of the type) ----

TEST(Value, EncodesIntegersLittleEndianWithExactTypeSize) {
  EXPECT_EQ(encoded(DataType::Unsigned16, "0x1234"), (Bytes{0x34, 0x12}));
  EXPECT_EQ(encoded(DataType::Integer24, "-2"), (Bytes{0xFE, 0xFF, 0xFF}));
  EXPECT_EQ(encoded(DataType::Unsigned24, "0x123456"), (Bytes{0x56, 0x34, 0x12}));
  EXPECT_EQ(encoded(DataType::Unsigned40, "0x0102030405"), (Bytes{0x05, 0x04, 0x03, 0x02, 0x01}));
  EXPECT_EQ(encoded(DataType::Integer40, "-1"), (Bytes{0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(encoded(DataType::Integer48, "-549755813888"),  // -2^39
            (Bytes{0x00, 0x00, 0x00, 0x00, 0x80, 0xFF}));
  EXPECT_EQ(encoded(DataType::Unsigned56, "0x01020304050607"),
            (Bytes{0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01}));
  EXPECT_EQ(encoded(DataType::Integer8, "-128"), (Bytes{0x80}));
  EXPECT_EQ(encoded(DataType::Integer16, "-32768"), (Bytes{0x00, 0x80}));
  EXPECT_EQ(encoded(DataType::Unsigned32, "1000"), (Bytes{0xE8, 0x03, 0x00, 0x00}));
  EXPECT_EQ(encoded(DataType::Integer64, "-2"),
            (Bytes{0xFE, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
}

TEST(Value, EncodesRealsAsIeee754LittleEndian) {
  EXPECT_EQ(encoded(DataType::Real32, "1.5"), (Bytes{0x00, 0x00, 0xC0, 0x3F}));
  EXPECT_EQ(encoded(DataType::Real32, "-2.0"), (Bytes{0x00, 0x00, 0x00, 0xC0}));
  EXPECT_EQ(encoded(DataType::Real32, "0.1"), (Bytes{0xCD, 0xCC, 0xCC, 0x3D}));
  EXPECT_EQ(encoded(DataType::Real32, "1.5e0"), (Bytes{0x00, 0x00, 0xC0, 0x3F}));
  EXPECT_EQ(encoded(DataType::Real64, "1.5"),
            (Bytes{0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x3F}));
  EXPECT_EQ(encoded(DataType::Real64, "0.1"),
            (Bytes{0x9A, 0x99, 0x99, 0x99, 0x99, 0x99, 0xB9, 0x3F}));
}

TEST(Value, Real32MustBeRepresentable) {
  // FLT_MAX = 3.4028234663852886e38 (IEEE 754 binary32, bytes FF FF 7F 7F).
  EXPECT_EQ(encoded(DataType::Real32, "3.4028234663852886e38"), (Bytes{0xFF, 0xFF, 0x7F, 0x7F}));
  EXPECT_EQ(encoded(DataType::Real32, "-3.402823E+38").size(), 4U);  // as vendor files write it
  const std::string message = error_of(DataType::Real32, "3.5e38");
  EXPECT_NE(message.find("out of range for REAL32"), std::string::npos) << message;
  error_of(DataType::Real32, "-1e39");
  EXPECT_EQ(parsed(DataType::Real64, "3.5e38").as_real(), 3.5e38);
  error_of(DataType::Real64, "1e400");
}

TEST(Value, Real32KeepsTheNearestBinary32) {
  // 0.1 is not a binary32; the value is what the bus carries (0x3DCCCCCD).
  EXPECT_EQ(parsed(DataType::Real32, "0.1").as_real(), static_cast<double>(0.1f));
}

TEST(Value, RejectsRealJunk) {
  for (std::string_view junk : {"1.5x", "1,5", "e5", "1e", "+1.0", "--1", "0x", "1.5 2"}) {
    SCOPED_TRACE(junk);
    error_of(DataType::Real32, junk);
  }
}

TEST(Value, TimeTypesAreTheir48BitRawValue) {
  // Project choice (documented in value.cpp): TIME_OF_DAY text is the raw 48-bit value, or
  // "DAYS MS" as lely writes it (TimeOfDayAsDaysAndMilliseconds).
  // 0x0001_02932E00: 43200000 ms (noon) = 0x2932E00 in the low 28 bits, day 1 in the high 16.
  EXPECT_EQ(encoded(DataType::TimeOfDay, "0x000102932E00"),
            (Bytes{0x00, 0x2E, 0x93, 0x02, 0x01, 0x00}));
  EXPECT_EQ(parsed(DataType::TimeDifference, "0xFFFFFFFFFFFF").as_unsigned(), 0xFFFFFFFFFFFFU);
  error_of(DataType::TimeDifference, "0x1000000000000");
  error_of(DataType::TimeOfDay, "365 43200000 7");  // "DAYS MS" (below) has two numbers
}

// ---- Strings and DOMAIN ----

TEST(Value, VisibleStringIsTakenAsItIs) {
  EXPECT_EQ(parsed(DataType::VisibleString, "IO module 8DI/8DO").as_bytes(), "IO module 8DI/8DO");
  EXPECT_EQ(parsed(DataType::VisibleString, "").as_bytes(), "");
  EXPECT_EQ(encoded(DataType::VisibleString, "AB"), (Bytes{0x41, 0x42}));
}

TEST(Value, OctetStringAndDomainAreHexPairs) {
  EXPECT_EQ(encoded(DataType::OctetString, "0123456789abcdef"),
            (Bytes{0x01, 0x23, 0x45, 0x67, 0x89, 0xAB, 0xCD, 0xEF}));
  EXPECT_EQ(encoded(DataType::Domain, "01 A2  FF"), (Bytes{0x01, 0xA2, 0xFF}));
  EXPECT_EQ(encoded(DataType::OctetString, ""), Bytes{});
  error_of(DataType::OctetString, "ABC");   // odd digit count
  error_of(DataType::OctetString, "A BC");  // space inside a pair
  error_of(DataType::Domain, "@ABCD");
}

// Motor-controller vendor tools export DOMAIN and OCTET_STRING values as one 0x-prefixed run of
// hex digits (hand-written values of that shape). The digits are the bytes in order.
TEST(Value, DomainAndOctetStringAcceptOne0xPrefixedRunOfDigits) {
  EXPECT_EQ(encoded(DataType::Domain, "0x0400003700002401"),
            (Bytes{0x04, 0x00, 0x00, 0x37, 0x00, 0x00, 0x24, 0x01}));
  EXPECT_EQ(encoded(DataType::Domain, "0XabCD"), (Bytes{0xAB, 0xCD}));
  EXPECT_EQ(encoded(DataType::OctetString, "0x00ff"), (Bytes{0x00, 0xFF}));
  // The prefix is the same bytes as the plain digits.
  EXPECT_EQ(parsed(DataType::Domain, "0x0102FF"), parsed(DataType::Domain, "0102FF"));
}

TEST(Value, OddHexDigitCountIsAnErrorThatSaysWhere) {
  // A value of tens of thousands of digits is not quoted whole: the message says where it breaks.
  const std::string long_value = "0x" + std::string(20001, 'A');
  const std::string message = error_of(DataType::Domain, long_value);
  EXPECT_THAT(message, HasSubstr("odd number of hex digits"));
  EXPECT_THAT(message, HasSubstr("character 20003"));
  EXPECT_LT(message.size(), 300u);
  EXPECT_THAT(error_of(DataType::Domain, "0x01G2"), HasSubstr("\"G\" at character 5"));
  EXPECT_THAT(error_of(DataType::OctetString, "0x"), HasSubstr("no digits after 0x"));
  EXPECT_THAT(error_of(DataType::OctetString, "0x1"), HasSubstr("odd number of hex digits"));
}

TEST(Value, UnicodeStringIsUtf16LittleEndian) {
  // U+00E9, U+20AC, U+1F600 (a surrogate pair D83D DE00), as Python's 'utf-16le' encodes them.
  EXPECT_EQ(encoded(DataType::UnicodeString, "\xC3\xA9\xE2\x82\xAC\xF0\x9F\x98\x80"),
            (Bytes{0xE9, 0x00, 0xAC, 0x20, 0x3D, 0xD8, 0x00, 0xDE}));
  EXPECT_EQ(encoded(DataType::UnicodeString, "Hi"), (Bytes{0x48, 0x00, 0x69, 0x00}));
  EXPECT_EQ(encoded(DataType::UnicodeString, ""), Bytes{});
}

TEST(Value, UnicodeStringRejectsInvalidUtf8) {
  for (std::string_view bad :
       {std::string_view("\xC3"), std::string_view("\xC0\xAF"), std::string_view("\xED\xA0\x80"),
        std::string_view("\xF4\x90\x80\x80"), std::string_view("\xFF"),
        std::string_view("a\x80")}) {
    error_of(DataType::UnicodeString, bad);
  }
}

// ---- decode ----

TEST(Value, DecodesLittleEndianAndSignExtends) {
  const Bytes i24{0xFE, 0xFF, 0xFF};
  EXPECT_EQ(decode(DataType::Integer24, i24)->as_signed(), -2);
  const Bytes u40{0x05, 0x04, 0x03, 0x02, 0x01};
  EXPECT_EQ(decode(DataType::Unsigned40, u40)->as_unsigned(), 0x0102030405U);
  const Bytes r32{0x00, 0x00, 0xC0, 0x3F};
  EXPECT_EQ(decode(DataType::Real32, r32)->as_real(), 1.5);
  const Bytes i8{0x80};
  EXPECT_EQ(decode(DataType::Integer8, i8)->as_signed(), -128);
}

TEST(Value, DecodeNeedsExactlyTheTypeSize) {
  const Bytes three{1, 2, 3};
  auto r = decode(DataType::Unsigned32, three);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, "UNSIGNED32 needs 4 byte(s), got 3");
  EXPECT_FALSE(decode(DataType::Integer24, Bytes{1, 2, 3, 4}).ok());
  EXPECT_FALSE(decode(DataType::Boolean, Bytes{}).ok());
  EXPECT_FALSE(decode(DataType::Boolean, Bytes{2}).ok());
  EXPECT_FALSE(decode(DataType::UnicodeString, Bytes{0x41}).ok());
  EXPECT_EQ(decode(DataType::Domain, Bytes{})->as_bytes(), "");
}

// ---- format_value / describe_value ----

TEST(Value, FormatsCanonicalText) {
  EXPECT_EQ(format_value(Value::from_unsigned(DataType::Unsigned32, 0x185)), "0x185");
  EXPECT_EQ(format_value(Value::from_signed(DataType::Integer16, -5)), "-5");
  EXPECT_EQ(format_value(Value::from_bool(true)), "1");
  EXPECT_EQ(format_value(parsed(DataType::Real32, "1.5")), "1.5");
  EXPECT_EQ(format_value(parsed(DataType::Real32, "0.1")), "0.1");
  EXPECT_EQ(format_value(parsed(DataType::OctetString, "01 a2 ff")), "01A2FF");
}

TEST(Value, DescribesForPeople) {
  EXPECT_EQ(describe_value(Value::from_unsigned(DataType::Unsigned32, 1000)), "1000 (0x000003E8)");
  EXPECT_EQ(describe_value(Value::from_unsigned(DataType::Unsigned8, 5)), "5 (0x05)");
  EXPECT_EQ(describe_value(Value::from_signed(DataType::Integer32, -5)), "-5");
  EXPECT_EQ(describe_value(parsed(DataType::VisibleString, "drive")), "\"drive\"");
  EXPECT_EQ(describe_value(parsed(DataType::Domain, "0102")), "01 02 (2 bytes)");
}

// format_value's promise: parse_value reads its text back to the same value, for every type.
void expect_round_trip(const Value& v) {
  const std::string text = format_value(v);
  auto back = parse_value(v.type(), text);
  ASSERT_TRUE(back.ok()) << to_string(v.type()) << " \"" << text << "\": " << back.error().message;
  EXPECT_EQ(back.value(), v) << to_string(v.type()) << " \"" << text << "\"";
  EXPECT_EQ(encode(back.value()), encode(v));
}

TEST(Value, FormatThenParseRoundTripsIntegerExtremes) {
  for (DataType t :
       {DataType::Integer8, DataType::Integer16, DataType::Integer24, DataType::Integer32,
        DataType::Integer40, DataType::Integer48, DataType::Integer56, DataType::Integer64}) {
    SCOPED_TRACE(to_string(t));
    for (std::int64_t v : {signed_min(t), signed_min(t) + 1, std::int64_t{-1}, std::int64_t{0},
                           std::int64_t{1}, signed_max(t) - 1, signed_max(t)}) {
      expect_round_trip(Value::from_signed(t, v));
      // And through the wire: decode(encode(v)) == v.
      EXPECT_EQ(decode(t, encode(Value::from_signed(t, v))).value(), Value::from_signed(t, v));
    }
  }
  for (DataType t :
       {DataType::Unsigned8, DataType::Unsigned16, DataType::Unsigned24, DataType::Unsigned32,
        DataType::Unsigned40, DataType::Unsigned48, DataType::Unsigned56, DataType::Unsigned64,
        DataType::TimeOfDay, DataType::TimeDifference}) {
    SCOPED_TRACE(to_string(t));
    for (std::uint64_t v :
         {std::uint64_t{0}, std::uint64_t{1}, unsigned_max(t) - 1, unsigned_max(t)}) {
      expect_round_trip(Value::from_unsigned(t, v));
      EXPECT_EQ(decode(t, encode(Value::from_unsigned(t, v))).value(), Value::from_unsigned(t, v));
    }
  }
  expect_round_trip(Value::from_bool(false));
  expect_round_trip(Value::from_bool(true));
}

TEST(Value, FormatThenParseRoundTripsRealEdgeCases) {
  const float f_values[] = {0.0f,
                            -0.0f,
                            1.5f,
                            0.1f,
                            -3.25f,
                            std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::lowest(),
                            std::numeric_limits<float>::min(),
                            std::numeric_limits<float>::denorm_min(),
                            std::numeric_limits<float>::epsilon(),
                            16777217.0f,
                            std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity()};
  for (float f : f_values) {
    SCOPED_TRACE(f);
    const Value v = Value::from_real(DataType::Real32, static_cast<double>(f));
    expect_round_trip(v);
    EXPECT_EQ(decode(DataType::Real32, encode(v)).value(), v);
  }
  const double d_values[] = {0.0,
                             1.5,
                             0.1,
                             1.0 / 3.0,
                             std::numeric_limits<double>::max(),
                             std::numeric_limits<double>::lowest(),
                             std::numeric_limits<double>::min(),
                             std::numeric_limits<double>::denorm_min(),
                             std::numeric_limits<double>::infinity()};
  for (double d : d_values) {
    SCOPED_TRACE(d);
    expect_round_trip(Value::from_real(DataType::Real64, d));
  }
  // NaN never compares equal; check it stays a NaN through text.
  auto nan =
      parse_value(DataType::Real64, format_value(Value::from_real(DataType::Real64, std::nan(""))));
  ASSERT_TRUE(nan.ok());
  EXPECT_TRUE(std::isnan(nan->as_real()));
}

TEST(Value, FormatThenParseRoundTripsStringsAndBytes) {
  expect_round_trip(Value::from_bytes(DataType::VisibleString, "IO module"));
  expect_round_trip(Value::from_bytes(DataType::VisibleString, ""));
  expect_round_trip(Value::from_bytes(DataType::OctetString, std::string("\x00\x01\xFF", 3)));
  expect_round_trip(Value::from_bytes(DataType::Domain, ""));
  expect_round_trip(Value::from_bytes(DataType::Domain, "binary\x7F"));
  expect_round_trip(parsed(DataType::UnicodeString, "\xC3\xA9\xE2\x82\xAC\xF0\x9F\x98\x80"));
}

}  // namespace
}  // namespace cfg

// integer_value is the reader's shortcut for plain literals: it must give what parse_value gives
// for the same text, range checks (the widths of CiA 301's basic types) and signed hex bit patterns
// included.
TEST(Value, IntegerValueOfALiteralIsWhatParseValueReads) {
  struct Case {
    cfg::DataType type;
    const char* text;
  };
  const std::vector<Case> cases = {
      {cfg::DataType::Boolean, "0"},
      {cfg::DataType::Boolean, "1"},
      {cfg::DataType::Boolean, "2"},
      {cfg::DataType::Unsigned8, "255"},
      {cfg::DataType::Unsigned8, "0x100"},
      {cfg::DataType::Unsigned8, "017"},
      {cfg::DataType::Unsigned24, "0xFFFFFF"},
      {cfg::DataType::Unsigned24, "16777216"},
      {cfg::DataType::Unsigned64, "0xFFFFFFFFFFFFFFFF"},
      {cfg::DataType::Integer8, "0x80"},
      {cfg::DataType::Integer8, "127"},
      {cfg::DataType::Integer8, "128"},
      {cfg::DataType::Integer8, "0x1FF"},
      {cfg::DataType::Integer24, "0x800000"},
      {cfg::DataType::Integer32, "2147483648"},
      {cfg::DataType::Integer64, "0xFFFFFFFFFFFFFFF6"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    const auto literal = cfg::parse_integer_literal(c.text).literal;
    ASSERT_TRUE(literal.has_value());
    const auto direct = cfg::integer_value(c.type, *literal);
    const auto parsed = cfg::parse_value(c.type, c.text);
    ASSERT_EQ(direct.ok(), parsed.ok());
    if (direct.ok()) {
      EXPECT_EQ(direct.value(), parsed.value());
    } else {
      EXPECT_EQ(direct.error().message, parsed.error().message);
    }
  }
  // The spec's own ranges, not just agreement: INTEGER8 0x80 is -128, UNSIGNED8 0x100 is out.
  EXPECT_EQ(cfg::integer_value(cfg::DataType::Integer8, {0x80, true}).value().as_signed(), -128);
  EXPECT_FALSE(cfg::integer_value(cfg::DataType::Unsigned8, {0x100, true}).ok());
  EXPECT_FALSE(cfg::integer_value(cfg::DataType::Real32, {1, false}).ok());
}
