// Value spellings that exported DCFs of vendor tools use, read through the whole path: reader,
// writer, concise DCF. Every text here is written by hand in the shape the tools write; the
// corpus file that shows the shape is cited, none is copied.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/value.hpp"
#include "device_text_support.hpp"

namespace cfg {
namespace {

using test_support::line_of;

using ::testing::HasSubstr;
using Bytes = std::vector<std::uint8_t>;

// A DCF with the mandatory objects, NodeID 3, and `objects` (manufacturer sections 2000h-20FFh
// listed in [ManufacturerObjects] by the caller's `listed`).
std::string dcf(std::string_view objects, std::string_view listed) {
  return "[FileInfo]\nFileName=vendor.dcf\nFileVersion=1\nFileRevision=0\nEDSVersion=4.0\n"
         "Description=vendor value spellings\nCreationTime=09:00AM\nCreationDate=01-02-2024\n"
         "CreatedBy=tests\n\n"
         "[DeviceInfo]\nVendorName=Test\nVendorNumber=0x00000001\nProductName=Drive\n"
         "ProductNumber=0x00000002\nRevisionNumber=0x00010000\nBaudRate_500=1\n"
         "SimpleBootUpSlave=1\nGranularity=8\nNrOfRXPDO=0\nNrOfTXPDO=0\nLSS_Supported=0\n\n"
         "[DeviceComissioning]\nNodeID=3\nNodeName=drive3\nBaudrate=500\n\n"
         "[MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n\n" +
         std::string(listed) +
         "\n[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
         "DefaultValue=0x00020192\nPDOMapping=0\n\n"
         "[1001]\nParameterName=Error register\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\n"
         "DefaultValue=0\nPDOMapping=0\n\n"
         "[1018]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=2\n\n"
         "[1018sub0]\nParameterName=Highest sub-index supported\nObjectType=0x7\n"
         "DataType=0x0005\nAccessType=ro\nDefaultValue=1\nPDOMapping=0\n\n"
         "[1018sub1]\nParameterName=Vendor-ID\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
         "DefaultValue=0x00000001\nPDOMapping=0\n\n" +
         std::string(objects);
}

// One rw VAR `index` of `data_type` with `keys`.
std::string var(std::string_view index, std::string_view data_type, std::string_view keys) {
  return "[" + std::string(index) +
         "]\nParameterName=Vendor parameter\nObjectType=0x7\nDataType=" + std::string(data_type) +
         "\nAccessType=rw\nPDOMapping=0\n" + std::string(keys) + "\n";
}

ReadResult parse(std::string_view text, ReadMode mode = ReadMode::Tolerant) {
  return test_support::parse_text(text, mode, "vendor.dcf");
}

Bytes bytes_of(const SubObject& s, const OptionalText& text) {
  auto v = parse_value(*s.basic_type(), *text);
  EXPECT_TRUE(v.ok()) << *text << ": " << (v.ok() ? "" : v.error().message);
  return v.ok() ? encode(v.value()) : Bytes{};
}

// `count` hex digit pairs of a fixed pattern (not from any device), and the bytes they are.
struct LongDomain {
  std::string digits;
  Bytes bytes;
};
LongDomain long_domain(std::size_t count) {
  LongDomain d;
  static constexpr char kDigits[] = "0123456789ABCDEF";
  for (std::size_t i = 0; i < count; ++i) {
    const auto b = static_cast<std::uint8_t>((i * 37 + 11) & 0xFF);
    d.bytes.push_back(b);
    d.digits += kDigits[b >> 4];
    d.digits += kDigits[b & 0xF];
  }
  return d;
}

// ---------------------------------------------------------------------------------------------
// DOMAIN and OCTET_STRING as one 0x-prefixed run of hex digits (motor-controller vendor tools)

const std::string kObjects =
    var("2000", "0x000F", "ParameterValue=0x0400003700002401010000320000240101000001000024") +
    var("2001", "0x000A", "DefaultValue=0X00ff10\nparametervalue=0xA0b1C2");
const std::string kListed = "[ManufacturerObjects]\nSupportedObjects=2\n1=0x2000\n2=0x2001\n";

TEST(VendorValues, HexPrefixedDomainAndOctetStringAreReadAsTheirBytes) {
  const std::string text = dcf(kObjects, kListed);
  for (ReadMode mode : {ReadMode::Tolerant, ReadMode::Strict}) {
    auto r = parse(text, mode);
    ASSERT_TRUE(r.device);
    EXPECT_TRUE(r.diagnostics.empty()) << r.diagnostics.format();
    const SubObject* domain = r.device->sub(0x2000, 0);
    const SubObject* octets = r.device->sub(0x2001, 0);
    ASSERT_NE(domain, nullptr);
    ASSERT_NE(octets, nullptr);
    EXPECT_EQ(bytes_of(*domain, domain->parameter_value),
              (Bytes{0x04, 0x00, 0x00, 0x37, 0x00, 0x00, 0x24, 0x01, 0x01, 0x00, 0x00, 0x32,
                     0x00, 0x00, 0x24, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x24}));
    EXPECT_EQ(bytes_of(*octets, octets->default_value), (Bytes{0x00, 0xFF, 0x10}));
    EXPECT_EQ(bytes_of(*octets, octets->parameter_value), (Bytes{0xA0, 0xB1, 0xC2}));
  }
}

TEST(VendorValues, WriterKeepsItsFormForHexPrefixedValuesAndTheBytesSurvive) {
  auto r = parse(dcf(kObjects, kListed));
  ASSERT_TRUE(r.ok()) << r.diagnostics.format();
  const std::string written = write_device_description(*r.device);
  // The writer writes DOMAIN/OCTET_STRING values as plain digit pairs, as for any other file.
  EXPECT_THAT(written, HasSubstr("ParameterValue=0400003700002401010000320000240101000001000024"));
  EXPECT_THAT(written, HasSubstr("DefaultValue=00ff10"));
  EXPECT_THAT(written, ::testing::Not(HasSubstr("=0x04000037")));
  auto again = parse(written);
  ASSERT_TRUE(again.ok()) << again.diagnostics.format();
  for (std::uint16_t index : {std::uint16_t{0x2000}, std::uint16_t{0x2001}}) {
    const SubObject* before = r.device->sub(index, 0);
    const SubObject* after = again.device->sub(index, 0);
    ASSERT_NE(after, nullptr);
    EXPECT_EQ(bytes_of(*after, after->parameter_value), bytes_of(*before, before->parameter_value));
  }
  EXPECT_EQ(*again.device, canonical_form(*r.device));
}

TEST(VendorValues, TensOfThousandsOfDigitsOnOneLineAreReadWrittenAndConverted) {
  const LongDomain d = long_domain(20000);  // 40002 characters on the line
  const std::string text = dcf(var("2000", "0x000F", "ParameterValue=0x" + d.digits),
                               "[ManufacturerObjects]\nSupportedObjects=1\n1=0x2000\n");
  auto r = parse(text);
  ASSERT_TRUE(r.ok()) << r.diagnostics.format();
  const SubObject* s = r.device->sub(0x2000, 0);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(bytes_of(*s, s->parameter_value), d.bytes);

  auto again = parse(write_device_description(*r.device));
  ASSERT_TRUE(again.ok()) << again.diagnostics.format();
  EXPECT_EQ(bytes_of(*again.device->sub(0x2000, 0), again.device->sub(0x2000, 0)->parameter_value),
            d.bytes);

  // DSP 302 §6.2: the concise DCF entry carries the DOMAIN's bytes as they are.
  Diagnostics diagnostics;
  ConciseOptions options;
  options.file_name = "vendor.dcf";
  auto writes = concise_writes_from_dcf(*r.device, options, diagnostics);
  ASSERT_TRUE(writes) << diagnostics.format();
  ASSERT_EQ(writes->size(), 1u);
  EXPECT_EQ((*writes)[0].index, 0x2000);
  EXPECT_EQ((*writes)[0].data, d.bytes);
}

TEST(VendorValues, OddDigitCountIsAnErrorOnTheValuesLine) {
  const LongDomain d = long_domain(5000);
  const std::string text = dcf(var("2000", "0x000F", "ParameterValue=0x" + d.digits + "7") +
                                   var("2001", "0x000A", "ParameterValue=0xABC"),
                               "[ManufacturerObjects]\nSupportedObjects=2\n1=0x2000\n2=0x2001\n");
  auto r = parse(text);
  EXPECT_FALSE(r.ok());
  int errors = 0;
  for (const Diagnostic& diagnostic : r.diagnostics.items()) {
    if (diagnostic.severity != Severity::Error) continue;
    ++errors;
    EXPECT_THAT(diagnostic.message, HasSubstr("odd number of hex digits"));
    // A value of 10001 digits is not repeated whole in the message.
    EXPECT_LT(diagnostic.message.size(), 400u) << diagnostic.message.substr(0, 400);
  }
  EXPECT_EQ(errors, 2);
  ASSERT_GE(r.diagnostics.size(), 2u);
  EXPECT_EQ(r.diagnostics.items()[0].line, line_of(text, "ParameterValue=0x" + d.digits));
  EXPECT_EQ(r.diagnostics.items()[1].line, line_of(text, "ParameterValue=0xABC"));
}

TEST(VendorValues, HexPrefixedValueInAValueSectionOfACompactArray) {
  // [xxxxValue] entries are ParameterValues too (CiA 306 §4.6.3.3).
  const std::string text =
      dcf("[2002]\nParameterName=Tables\nObjectType=0x8\nDataType=0x000F\nAccessType=rw\n"
          "PDOMapping=0\nCompactSubObj=2\n\n[2002Value]\nNrOfEntries=2\n1=0x0102\n2=0XfffE\n",
          "[ManufacturerObjects]\nSupportedObjects=1\n1=0x2002\n");
  auto r = parse(text);
  ASSERT_TRUE(r.ok()) << r.diagnostics.format();
  const SubObject* one = r.device->sub(0x2002, 1);
  const SubObject* two = r.device->sub(0x2002, 2);
  ASSERT_NE(one, nullptr);
  ASSERT_NE(two, nullptr);
  EXPECT_EQ(bytes_of(*one, one->parameter_value), (Bytes{0x01, 0x02}));
  EXPECT_EQ(bytes_of(*two, two->parameter_value), (Bytes{0xFF, 0xFE}));
}

// ---------------------------------------------------------------------------------------------
// Other spellings exported DCFs use for strings and times

TEST(VendorValues, LelyDcfSpellingsOfStringsOctetsAndTimes) {
  // The shapes of lely-core's DCFs (corpus lely-core/co-sdev.dcf [2009]-[200D]): strings in
  // double quotes, OCTET_STRING as lower-case digits without blanks, TIME_OF_DAY and
  // TIME_DIFFERENCE as "DAYS MS". Quoted strings are kept as written (the quotes are part of the
  // text: CiA 306 has no quoting), lower-case digits are bytes, "DAYS MS" is the 48-bit value
  // with the days in bits 32-47 and the milliseconds in bits 0-27 (CiA 301 §7.1).
  const std::string text =
      dcf(var("2009", "0x0009", "ParameterValue=\"Motor 1, left\"") +
              var("200A", "0x000A", "ParameterValue=00aa55ff") +
              var("200B", "0x000B", "ParameterValue=\"Achse 2\"") +
              var("200C", "0x000C", "ParameterValue=10 3600000") +
              var("200D", "0x000D", "ParameterValue=2 500"),
          "[ManufacturerObjects]\nSupportedObjects=5\n1=0x2009\n2=0x200A\n3=0x200B\n4=0x200C\n"
          "5=0x200D\n");
  auto r = parse(text, ReadMode::Strict);
  ASSERT_TRUE(r.ok()) << r.diagnostics.format();
  const DeviceDescription& d = *r.device;
  EXPECT_EQ(d.sub(0x2009, 0)->parameter_value, "\"Motor 1, left\"");
  EXPECT_EQ(bytes_of(*d.sub(0x200A, 0), d.sub(0x200A, 0)->parameter_value),
            (Bytes{0x00, 0xAA, 0x55, 0xFF}));
  // UNICODE_STRING: UTF-16LE of the text as written, quotes included.
  const Bytes unicode = bytes_of(*d.sub(0x200B, 0), d.sub(0x200B, 0)->parameter_value);
  ASSERT_EQ(unicode.size(), 18u);
  EXPECT_EQ(unicode[0], '"');
  EXPECT_EQ(unicode[1], 0);
  EXPECT_EQ(unicode[2], 'A');
  // 10 days, 3600000 ms: 0x000A 0036EE80 little-endian in 6 bytes.
  EXPECT_EQ(bytes_of(*d.sub(0x200C, 0), d.sub(0x200C, 0)->parameter_value),
            (Bytes{0x80, 0xEE, 0x36, 0x00, 0x0A, 0x00}));
  EXPECT_EQ(bytes_of(*d.sub(0x200D, 0), d.sub(0x200D, 0)->parameter_value),
            (Bytes{0xF4, 0x01, 0x00, 0x00, 0x02, 0x00}));
}

TEST(VendorValues, PythonCanopenTestEdsSpellings) {
  // The shapes of python-canopen's datatypes.eds (corpus python-canopen/datatypes.eds [200B],
  // [200F]): UNICODE_STRING as UTF-8 text, DOMAIN DefaultValue "@" + letters (not hex). The
  // UTF-8 text becomes UTF-16LE; the DOMAIN default is not a value of its type, which for a
  // DefaultValue is a warning (the configuration is the ParameterValue).
  const std::string text = dcf(var("200B", "0x000B", "DefaultValue=Z\xC3\xA4hler \xE2\x9C\x93") +
                                   var("200F", "0x000F", "DefaultValue=@XYZ"),
                               "[ManufacturerObjects]\nSupportedObjects=2\n1=0x200B\n2=0x200F\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(bytes_of(*r.device->sub(0x200B, 0), r.device->sub(0x200B, 0)->default_value),
            (Bytes{'Z', 0, 0xE4, 0, 'h', 0, 'l', 0, 'e', 0, 'r', 0, ' ', 0, 0x13, 0x27}));
  ASSERT_EQ(r.diagnostics.size(), 1u) << r.diagnostics.format();
  EXPECT_EQ(r.diagnostics.items()[0].severity, Severity::Warning);
  EXPECT_EQ(r.diagnostics.items()[0].line, line_of(text, "DefaultValue=@XYZ"));
  EXPECT_THAT(r.diagnostics.items()[0].message, HasSubstr("is not a valid DOMAIN"));
}

TEST(VendorValues, StringAndTimeSpellingsOfEditorsReachTheConciseDcf) {
  // What the shared corpus shows beside lely's and python-canopen's forms above: editors write an
  // empty VISIBLE_STRING as an empty key (`ParameterValue=`, CANopenEditor's export of an empty
  // string), keep ';' inside a text (a device name), and the CiA 301 §7.1 time types also come
  // as their raw 48-bit number, 0x-prefixed, decimal, or 'h'-suffixed as in CiA documents. Each
  // is read as its value and becomes the bytes of CiA 301 §7.1 in the concise DCF (DSP 302 §6.2):
  // a text as its bytes, TIME_OF_DAY/TIME_DIFFERENCE 6 bytes little-endian (ms in bits 0-27, days
  // in bits 32-47). The empty string is kept as the empty text, but the concise stage writes
  // nothing for it: CANopenEditor writes every entry the user did not set as an empty key, so an
  // empty ParameterValue means "not configured" (the choice in concise_dcf.cpp).
  const std::string text =
      dcf(var("2010", "0x0009", "ParameterValue=") +
              var("2011", "0x0009", "ParameterValue=Axis 1 ; left") +
              var("2012", "0x000C", "ParameterValue=0x016D02932E00") +
              var("2013", "0x000D", "ParameterValue=0") +
              var("2014", "0x000C", "ParameterValue=0001 0000 0064h"),
          "[ManufacturerObjects]\nSupportedObjects=5\n1=0x2010\n2=0x2011\n3=0x2012\n4=0x2013\n"
          "5=0x2014\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device) << r.diagnostics.format();
  EXPECT_FALSE(r.diagnostics.has_errors()) << r.diagnostics.format();
  const DeviceDescription& d = *r.device;
  EXPECT_EQ(d.sub(0x2010, 0)->parameter_value, "");  // given, and empty: not "not given"
  EXPECT_EQ(d.sub(0x2011, 0)->parameter_value, "Axis 1 ; left");
  EXPECT_EQ(d.sub(0x2014, 0)->parameter_value, "0x000100000064");  // stored in 0x form
  // 'h'-suffix hex is not CiA 306 syntax: one warning, on its line.
  ASSERT_EQ(r.diagnostics.count(Severity::Warning), 1u) << r.diagnostics.format();
  EXPECT_EQ(r.diagnostics.items()[0].line, line_of(text, "ParameterValue=0001 0000 0064h"));

  ConciseOptions options;
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(d, options, diagnostics);
  ASSERT_TRUE(writes) << diagnostics.format();
  auto data_of = [&](std::uint16_t index) {
    auto it = std::find_if(writes->begin(), writes->end(),
                           [index](const ObjectWrite& w) { return w.index == index; });
    EXPECT_NE(it, writes->end()) << index;
    return it == writes->end() ? Bytes{} : it->data;
  };
  EXPECT_EQ(std::count_if(writes->begin(), writes->end(),
                          [](const ObjectWrite& w) { return w.index == 0x2010; }),
            0);
  EXPECT_EQ(data_of(0x2011),
            (Bytes{'A', 'x', 'i', 's', ' ', '1', ' ', ';', ' ', 'l', 'e', 'f', 't'}));
  // 365 days (016Dh) and 43200000 ms (02932E00h): noon of the 365th day.
  EXPECT_EQ(data_of(0x2012), (Bytes{0x00, 0x2E, 0x93, 0x02, 0x6D, 0x01}));
  EXPECT_EQ(data_of(0x2013), (Bytes{0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(data_of(0x2014), (Bytes{0x64, 0x00, 0x00, 0x00, 0x01, 0x00}));
}

}  // namespace
}  // namespace cfg
