// Programmable-device I/O (CiA DSP 302 §8): [DynamicChannels] and DynamicChannelsSupported read,
// checked and written (§8.4), and dynamic index assignment (§8.2, §8.5). The files are
// hand-written under tests/data/dynamic/: spec_example.eds is the example of §8.4 verbatim.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/dynamic_channels.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

using ::testing::HasSubstr;

std::string data_file(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/dynamic/" + name;
}

// The 1-based line of the first line of the file starting with `start` (the key at fault).
int line_of(const std::string& name, const std::string& start) {
  std::ifstream in(data_file(name));
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (line.rfind(start, 0) == 0) return n;
  }
  ADD_FAILURE() << start << " is not in " << name;
  return -1;
}

// The diagnostics at a line, formatted, for matching.
std::string at_line(const Diagnostics& d, int line, Severity severity) {
  std::string out;
  for (const Diagnostic& x : d.items()) {
    if (x.line == line && x.severity == severity) out += x.message + "\n";
  }
  return out;
}

DeviceDescription read_ok(const std::string& name) {
  ReadResult r = read_device_file(data_file(name));
  EXPECT_TRUE(r.device.has_value()) << r.diagnostics.format();
  EXPECT_FALSE(r.diagnostics.has_errors()) << r.diagnostics.format();
  return r.device ? std::move(*r.device) : DeviceDescription{};
}

// ---- reader

TEST(DynamicChannels, ReadsTheTwoSegmentsOfTheSpecExample) {
  const DeviceDescription d = read_ok("spec_example.eds");
  EXPECT_EQ(dynamic_channels_supported(d), 1U);  // §8.4 example: DynamicChannelsSupported=1
  const std::optional<DynamicChannels> c = dynamic_channels_of(d);
  ASSERT_TRUE(c);
  ASSERT_EQ(c->segments.size(), 2U);
  // §8.4: "4 kByte of byte input variables" and "64 Boolean input variables".
  const DynamicSegment& bytes = c->segments[0];
  EXPECT_EQ(bytes.data_type, 0x0005);
  EXPECT_EQ(bytes.direction, SegmentDirection::Ro);
  EXPECT_EQ(bytes.first_index, 0x7001);
  EXPECT_EQ(bytes.last_index, 0x7017);
  EXPECT_EQ(bytes.pp_offset, 0U);
  EXPECT_FALSE(bytes.bit_distance);
  EXPECT_EQ(bytes.max_count, 4096U);
  const DynamicSegment& bits = c->segments[1];
  EXPECT_EQ(bits.data_type, 0x0001);
  EXPECT_EQ(bits.first_index, 0x7018);
  EXPECT_EQ(bits.last_index, 0x7018);
  EXPECT_EQ(bits.pp_offset, 4096U);
  EXPECT_EQ(bits.bit_distance, 1U);
  EXPECT_EQ(bits.max_count, 64U);
}

TEST(DynamicChannels, DynamicChannelsSupportedIsZeroWhenAbsent) {
  // §8.4: "If the entry does not exist, it is assumed to be 0."
  DeviceDescription d;
  EXPECT_EQ(dynamic_channels_supported(d), 0U);
  d.device_info.set("DynamicChannelsSupported", "0x0000000D");
  EXPECT_EQ(dynamic_channels_supported(d), 0xDU);
  d.device_info.set("DynamicChannelsSupported", "many");
  EXPECT_FALSE(dynamic_channels_supported(d));
}

TEST(DynamicChannels, ReadsEverySegmentOfADs405LikeFile) {
  const std::optional<DynamicChannels> c = dynamic_channels_of(read_ok("ds405_like.eds"));
  ASSERT_TRUE(c);
  ASSERT_EQ(c->segments.size(), 6U);
  EXPECT_EQ(c->segments[0].bit_distance, 8U);
  EXPECT_EQ(c->segments[4].direction, SegmentDirection::Rww);
  EXPECT_EQ(c->segments[5].m_specific, "PLC2:REAL outputs, word aligned");
  EXPECT_FALSE(c->segments[4].m_specific);
}

TEST(DynamicChannels, EachFaultIsReportedOnTheLineOfItsKey) {
  const std::string f = "broken.eds";
  const ReadResult r = read_device_file(data_file(f));
  ASSERT_TRUE(r.device);
  const Diagnostics& d = r.diagnostics;
  EXPECT_THAT(at_line(d, line_of(f, "NrOfSeg="), Severity::Error),
              HasSubstr("NrOfSeg is 11 but 10 segments are described"));
  // §8.2: "These segments must not overlap."
  EXPECT_THAT(at_line(d, line_of(f, "Range2="), Severity::Error),
              HasSubstr("range 6003h-6004h overlaps segment 1 (6000h-6003h"));
  EXPECT_THAT(at_line(d, line_of(f, "Type3="), Severity::Error),
              HasSubstr("Type 0x0020 is not a basic data type"));
  EXPECT_THAT(at_line(d, line_of(f, "Dir4="), Severity::Error), HasSubstr("is not ro, wo or rww"));
  EXPECT_THAT(at_line(d, line_of(f, "Range5="), Severity::Error),
              HasSubstr("range 1000h-1001h is outside the manufacturer (2000h-5FFFh)"));
  EXPECT_THAT(at_line(d, line_of(f, "Range6="), Severity::Error),
              HasSubstr("range starts at 6105h, after its end 6100h"));
  EXPECT_THAT(at_line(d, line_of(f, "PPOffset7="), Severity::Error),
              HasSubstr("bit distance, which only BOOLEAN segments have"));
  EXPECT_THAT(at_line(d, line_of(f, "Type8="), Severity::Error),
              HasSubstr("segment 8 has no MaxCnt8"));
  EXPECT_THAT(at_line(d, line_of(f, "Type9="), Severity::Error),
              HasSubstr("VISIBLE_STRING has no fixed size"));
  // §8.4: for BOOLEAN "the bit address difference has to be defined".
  EXPECT_THAT(at_line(d, line_of(f, "PPOffset10="), Severity::Error),
              HasSubstr("BOOLEAN segment's PPOffset needs the bit distance"));
  EXPECT_THAT(at_line(d, line_of(f, "Colour1="), Severity::Warning),
              HasSubstr("not a [DynamicChannels] key"));
  // Left out: segment 4 (Dir unreadable) and 8 (no MaxCnt); the others are kept as written.
  const std::optional<DynamicChannels> c = dynamic_channels_of(*r.device);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->segments.size(), 8U);
}

// What vendor tools write into a device that has no dynamic channels (DynamicChannelsSupported=0
// or absent, which §8.4 reads as 0): one placeholder segment of type 0000h over 0000h-0000h.
std::string placeholder_eds(std::string_view supported_line) {
  return "[DeviceInfo]\nVendorNumber=0x1\n" + std::string(supported_line) +
         "[DynamicChannels]\nNrOfSeg=1\nType1=0x0000\nDir1=ro\nRange1=0x0000-0x0000\n"
         "PPOffset1=0\nMaxCnt1=0\n";
}

TEST(DynamicChannels, PlaceholderSectionOfADeviceWithoutDynamicChannelsIsOnlyAWarning) {
  // §8.4: "If the entry DynamicChannelsSupported is non-zero, the section DynamicChannels
  // describes the usable segments": with 0 the device uses none, so the placeholder changes
  // nothing it is configured with. Tolerant: warnings on the keys' lines; strict: errors.
  for (const std::string_view supported : {"DynamicChannelsSupported=0\n", ""}) {
    const std::string text = placeholder_eds(supported);
    const int offset = supported.empty() ? 0 : 1;
    const ReadResult tolerant = parse_device_description(text);
    ASSERT_TRUE(tolerant.device);
    EXPECT_FALSE(tolerant.diagnostics.has_errors()) << tolerant.diagnostics.format();
    EXPECT_THAT(at_line(tolerant.diagnostics, 3 + offset, Severity::Warning),
                HasSubstr("DynamicChannelsSupported is"));
    EXPECT_THAT(at_line(tolerant.diagnostics, 5 + offset, Severity::Warning),
                HasSubstr("Type 0x0000 is not a basic data type"));
    EXPECT_THAT(at_line(tolerant.diagnostics, 7 + offset, Severity::Warning),
                HasSubstr("range 0000h-0000h is outside the manufacturer"));
    EXPECT_THAT(at_line(tolerant.diagnostics, 7 + offset, Severity::Warning),
                HasSubstr("the device does not use the section"));
    const ReadResult strict = parse_device_description(text, {ReadMode::Strict, "x.eds"});
    EXPECT_THAT(at_line(strict.diagnostics, 5 + offset, Severity::Error),
                HasSubstr("Type 0x0000 is not a basic data type"));
    EXPECT_THAT(at_line(strict.diagnostics, 7 + offset, Severity::Error),
                HasSubstr("is outside the manufacturer"));
  }
}

TEST(DynamicChannels, PlaceholderSectionOfADeviceThatUsesDynamicChannelsIsAnError) {
  // The same segment where DynamicChannelsSupported is non-zero: the device says it uses it, and
  // network variables cannot be allocated into it.
  const ReadResult r = parse_device_description(placeholder_eds("DynamicChannelsSupported=1\n"));
  ASSERT_TRUE(r.device);
  EXPECT_THAT(at_line(r.diagnostics, 6, Severity::Error), HasSubstr("Type 0x0000 is not a basic"));
  EXPECT_THAT(at_line(r.diagnostics, 8, Severity::Error), HasSubstr("is outside the manufacturer"));
}

TEST(DynamicChannels, DynamicChannelsSupportedWithoutTheSectionIsAWarningOnItsLine) {
  const std::string f = "supported_without_section.eds";
  const ReadResult r = read_device_file(data_file(f));
  ASSERT_TRUE(r.device);
  EXPECT_FALSE(r.diagnostics.has_errors()) << r.diagnostics.format();
  EXPECT_THAT(at_line(r.diagnostics, line_of(f, "DynamicChannelsSupported="), Severity::Warning),
              HasSubstr("no [DynamicChannels] section"));
  EXPECT_FALSE(dynamic_channels_of(*r.device));
}

TEST(DynamicChannels, UpperCaseDirIsAWarningAndAStrictError) {
  const std::string text =
      "[DeviceInfo]\nDynamicChannelsSupported=1\n[DynamicChannels]\nNrOfSeg=1\nType1=5\n"
      "Dir1=RO\nRange1=0x2000-0x2000\nPPOffset1=0\nMaxCnt1=254\n";
  const ReadResult tolerant = parse_device_description(text);
  ASSERT_TRUE(tolerant.device);
  const std::optional<DynamicChannels> c = dynamic_channels_of(*tolerant.device);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->segments.at(0).direction, SegmentDirection::Ro);
  EXPECT_THAT(at_line(tolerant.diagnostics, 6, Severity::Warning), HasSubstr("lower case"));
  const ReadResult strict = parse_device_description(text, {ReadMode::Strict, "x.eds"});
  EXPECT_THAT(at_line(strict.diagnostics, 6, Severity::Error), HasSubstr("lower case"));
}

TEST(DynamicChannels, RangeNumbersNeedTheLeading0xOfHex) {
  // §8.4: "The numbers are unsigned16 hexadecimal with leading 0x": 7001 is not 0x7001.
  const std::string text =
      "[DeviceInfo]\nDynamicChannelsSupported=1\n[DynamicChannels]\nNrOfSeg=1\nType1=5\n"
      "Dir1=ro\nRange1=7001-7017\nPPOffset1=0\nMaxCnt1=254\n";
  const ReadResult r = parse_device_description(text);
  EXPECT_THAT(at_line(r.diagnostics, 7, Severity::Error), HasSubstr("leading 0x"));
  ASSERT_TRUE(r.device);
  const std::optional<DynamicChannels> c = dynamic_channels_of(*r.device);
  ASSERT_TRUE(c);
  EXPECT_TRUE(c->segments.empty());
}

TEST(DynamicChannels, MaxCntBeyondWhatTheRangeHoldsIsAWarning) {
  // §8.2: arrays of sub-index 01h..FEh, so one index holds 254 variables.
  const std::string text =
      "[DeviceInfo]\nDynamicChannelsSupported=1\n[DynamicChannels]\nNrOfSeg=1\nType1=5\n"
      "Dir1=ro\nRange1=0x2000-0x2000\nPPOffset1=0\nMaxCnt1=255\n";
  const ReadResult r = parse_device_description(text);
  EXPECT_THAT(at_line(r.diagnostics, 9, Severity::Warning), HasSubstr("holds at most 254"));
}

// ---- writer

TEST(DynamicChannels, WriterWritesTheSpecSyntaxAndReadsBackTheSameSegments) {
  const DeviceDescription d = read_ok("ds405_like.eds");
  for (FileKind kind : {FileKind::Eds, FileKind::Dcf}) {
    WriteOptions o;
    o.kind = kind;
    o.line_ending = LineEnding::Lf;
    const std::string text = write_device_description(d, o);
    // §8.4 syntax: Range "0xAAAA-0xBBBB", a BOOLEAN PPOffset "offset,bit distance".
    EXPECT_THAT(text, HasSubstr("[DynamicChannels]\nNrOfSeg=6\nType1=0x0001\nDir1=ro\n"
                                "Range1=0xA000-0xA000\nPPOffset1=0,8\nMaxCnt1=16\n"));
    EXPECT_THAT(text, HasSubstr("Dir5=rww\n"));
    EXPECT_THAT(text, HasSubstr("MSpecific6=PLC2:REAL outputs, word aligned\n"));
    const ReadResult back = parse_device_description(text);
    ASSERT_TRUE(back.device);
    EXPECT_FALSE(back.diagnostics.has_errors()) << back.diagnostics.format();
    EXPECT_EQ(dynamic_channels_of(*back.device), dynamic_channels_of(d));
    EXPECT_EQ(*back.device, canonical_form(d, o));
    EXPECT_EQ(write_device_description(*back.device, o), text);
  }
}

TEST(DynamicChannels, BrokenSegmentsRoundTripAsRead) {
  const ReadResult r = read_device_file(data_file("broken.eds"));
  ASSERT_TRUE(r.device);
  const std::string text = write_device_description(*r.device);
  const ReadResult back = parse_device_description(text);
  ASSERT_TRUE(back.device);
  EXPECT_EQ(*back.device, canonical_form(*r.device));
}

// ---- dynamic index assignment (§8.2)

DynamicChannels spec_segments() {
  return dynamic_channels_of(read_ok("spec_example.eds")).value_or(DynamicChannels{});
}

NetworkVariable var(std::string name, DataType type, VariableDirection d) {
  return {std::move(name), static_cast<std::uint16_t>(type), d};
}

TEST(DynamicIndexAssignment, FillsSubIndex01hToFEhThenTakesTheNextIndex) {
  std::vector<NetworkVariable> vars;
  for (int i = 0; i < 256; ++i) {
    vars.push_back(var("in" + std::to_string(i), DataType::Unsigned8, VariableDirection::Input));
  }
  auto a = allocate_variables(spec_segments(), vars);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->at(0).address, (ObjectAddress{0x7001, 0x01}));
  EXPECT_EQ(a->at(253).address, (ObjectAddress{0x7001, 0xFE}));
  // §8.2: "If all elements of an array are defined (sub-index 01h to FEh), the next free object".
  EXPECT_EQ(a->at(254).address, (ObjectAddress{0x7002, 0x01}));
  EXPECT_EQ(a->at(255).address, (ObjectAddress{0x7002, 0x02}));
  // PPOffset 0 + position x 1 byte.
  EXPECT_EQ(a->at(254).pp_byte_offset(), 254U);
  EXPECT_EQ(a->at(254).pp_bit(), 0U);
}

TEST(DynamicIndexAssignment, PackedBooleansTakeOneBitEachAfterPPOffset) {
  // §8.4 example: PPOffset2=4096,1: Booleans packed one bit after the other from byte 4096.
  std::vector<NetworkVariable> vars;
  for (int i = 0; i < 10; ++i) {
    vars.push_back(var("b" + std::to_string(i), DataType::Boolean, VariableDirection::Input));
  }
  auto a = allocate_variables(spec_segments(), vars);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->at(0).address, (ObjectAddress{0x7018, 0x01}));
  EXPECT_EQ(a->at(0).pp_byte_offset(), 4096U);
  EXPECT_EQ(a->at(0).pp_bit(), 0U);
  EXPECT_EQ(a->at(9).address, (ObjectAddress{0x7018, 0x0A}));
  EXPECT_EQ(a->at(9).pp_byte_offset(), 4097U);
  EXPECT_EQ(a->at(9).pp_bit(), 1U);
}

TEST(DynamicIndexAssignment, BooleansInByteCellsTakeOneByteEach) {
  // ds405_like.eds segment 1: PPOffset1=0,8 ("each stored in a byte cell", §8.2).
  const DynamicChannels c =
      dynamic_channels_of(read_ok("ds405_like.eds")).value_or(DynamicChannels{});
  const std::vector<NetworkVariable> vars = {var("x", DataType::Boolean, VariableDirection::Input),
                                             var("y", DataType::Boolean, VariableDirection::Input)};
  auto a = allocate_variables(c, vars);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->at(1).pp_byte_offset(), 1U);
  EXPECT_EQ(a->at(1).pp_bit(), 0U);
}

TEST(DynamicIndexAssignment, MaxCntReachedFailsNamingTheVariableAndSegment) {
  std::vector<NetworkVariable> vars;
  for (int i = 0; i < 65; ++i) {
    vars.push_back(var("b" + std::to_string(i), DataType::Boolean, VariableDirection::Input));
  }
  auto a = allocate_variables(spec_segments(), vars);  // MaxCnt2=64
  ASSERT_FALSE(a);
  EXPECT_THAT(a.error().message, HasSubstr("variable 'b64'"));
  EXPECT_THAT(a.error().message, HasSubstr("segment 2 (7018h-7018h) is full (MaxCnt 64 reached)"));
}

TEST(DynamicIndexAssignment, AFullIndexRangeFailsEvenBelowMaxCnt) {
  DynamicChannels c;
  c.segments.push_back({0x0006, SegmentDirection::Wo, 0x2000, 0x2000, 0, {}, 1000, {}});
  std::vector<NetworkVariable> vars;
  for (int i = 0; i < 255; ++i) {
    vars.push_back(var("w" + std::to_string(i), DataType::Unsigned16, VariableDirection::Output));
  }
  auto a = allocate_variables(c, vars);
  ASSERT_FALSE(a);
  EXPECT_THAT(a.error().message, HasSubstr("'w254'"));
  EXPECT_THAT(a.error().message, HasSubstr("its index range holds 254"));
}

TEST(DynamicIndexAssignment, NoSegmentOfTheTypeAndDirectionFails) {
  const std::vector<NetworkVariable> vars = {
      var("speed", DataType::Unsigned8, VariableDirection::Output)};
  auto a = allocate_variables(spec_segments(), vars);  // the example has inputs only
  ASSERT_FALSE(a);
  EXPECT_THAT(a.error().message, HasSubstr("variable 'speed': the device has no segment for "
                                           "UNSIGNED8 outputs"));
}

TEST(DynamicIndexAssignment, DuplicateNamesAndStringTypesAreRefused) {
  const std::vector<NetworkVariable> twice = {
      var("x", DataType::Unsigned8, VariableDirection::Input),
      var("x", DataType::Unsigned8, VariableDirection::Input)};
  auto a = allocate_variables(spec_segments(), twice);
  ASSERT_FALSE(a);
  EXPECT_THAT(a.error().message, HasSubstr("'x' is given twice"));
  const std::vector<NetworkVariable> text = {
      var("s", DataType::VisibleString, VariableDirection::Input)};
  auto b = allocate_variables(spec_segments(), text);
  ASSERT_FALSE(b);
  EXPECT_THAT(b.error().message, HasSubstr("not a fixed-size basic data type"));
}

TEST(DynamicIndexAssignment, MixedTypeSegmentsAtPPOffset0LeaveOutOverlappingIndices) {
  // §8.2: "Other devices mix different data types in the same segment. For those devices all
  // PPOffset attributes will have the value 0 ... indexes have to be left out to avoid
  // overlapping." mixed_offsets.eds: UNSIGNED8 2000h-, UNSIGNED16 2010h-, UNSIGNED32 2020h.
  const DynamicChannels c =
      dynamic_channels_of(read_ok("mixed_offsets.eds")).value_or(DynamicChannels{});
  const std::vector<NetworkVariable> vars = {
      var("a", DataType::Unsigned8, VariableDirection::Input),   // byte 0
      var("b", DataType::Unsigned16, VariableDirection::Input),  // 2010sub1 = bytes 0-1: taken
      var("c", DataType::Unsigned8, VariableDirection::Input),   // byte 1
      var("d", DataType::Unsigned32, VariableDirection::Input),  // bytes 0-3 taken -> 4-7
      var("e", DataType::Unsigned8, VariableDirection::Input)};  // bytes 2..7 taken -> 8
  auto a = allocate_variables(c, vars);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->at(0).address, (ObjectAddress{0x2000, 0x01}));
  EXPECT_EQ(a->at(1).address, (ObjectAddress{0x2010, 0x02}));
  EXPECT_EQ(a->at(1).pp_byte_offset(), 2U);
  EXPECT_EQ(a->at(2).address, (ObjectAddress{0x2000, 0x02}));
  EXPECT_EQ(a->at(2).pp_byte_offset(), 1U);
  EXPECT_EQ(a->at(3).address, (ObjectAddress{0x2020, 0x02}));
  EXPECT_EQ(a->at(3).pp_byte_offset(), 4U);
  EXPECT_EQ(a->at(4).address, (ObjectAddress{0x2000, 0x09}));
  EXPECT_EQ(a->at(4).pp_byte_offset(), 8U);
}

TEST(DynamicIndexAssignment, InputsAndOutputsAreSeparateProcessPictures) {
  // ds405_like.eds: BOOLEAN inputs at PPOffset 0 and BOOLEAN outputs at PPOffset 0.
  const DynamicChannels c =
      dynamic_channels_of(read_ok("ds405_like.eds")).value_or(DynamicChannels{});
  const std::vector<NetworkVariable> vars = {
      var("i", DataType::Boolean, VariableDirection::Input),
      var("o", DataType::Boolean, VariableDirection::Output)};
  auto a = allocate_variables(c, vars);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(a->at(0).address, (ObjectAddress{0xA000, 0x01}));
  EXPECT_EQ(a->at(1).address, (ObjectAddress{0xA100, 0x01}));
  EXPECT_EQ(a->at(1).pp_bit_offset, 0U);
}

TEST(DynamicIndexAssignment, WritesArrayObjectsNamedAfterTheVariablesIntoTheDcf) {
  DeviceDescription d = read_ok("ds405_like.eds");
  const DynamicChannels c = dynamic_channels_of(d).value_or(DynamicChannels{});
  const std::vector<NetworkVariable> vars = {
      var("start_button", DataType::Boolean, VariableDirection::Input),
      var("level", DataType::Unsigned8, VariableDirection::Input),
      var("setpoint", DataType::Unsigned16, VariableDirection::Output)};
  auto a = allocate_variables(c, vars);
  ASSERT_TRUE(a) << a.error().message;
  ASSERT_TRUE(add_variable_objects(d, c, *a));
  WriteOptions o;
  o.line_ending = LineEnding::Lf;
  const std::string dcf = write_device_description(d, o);
  const ReadResult back = parse_device_description(dcf);
  ASSERT_TRUE(back.device);
  EXPECT_FALSE(back.diagnostics.has_errors()) << back.diagnostics.format();
  const Object* level = back.device->object(0xA001);
  ASSERT_NE(level, nullptr);
  EXPECT_EQ(level->object_type, ObjectType::Array);
  EXPECT_EQ(level->name, "UNSIGNED8 inputs");
  const SubObject* count = level->sub(0);
  ASSERT_NE(count, nullptr);
  EXPECT_EQ(count->default_value, "1");
  const SubObject* v = level->sub(1);
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(v->name, "level");
  EXPECT_EQ(v->data_type, 0x0005);
  EXPECT_EQ(v->access, AccessType::Ro);  // Dir2=ro: an input, mapped into a TPDO
  EXPECT_TRUE(v->pdo_mapping);
  const SubObject* setpoint = back.device->sub(0xA101, 1);
  ASSERT_NE(setpoint, nullptr);
  EXPECT_EQ(setpoint->name, "setpoint");
  EXPECT_EQ(setpoint->access, AccessType::Rww);  // Dir5=rww
  EXPECT_EQ(back.device->sub(0xA000, 1)->name, "start_button");
  // A second allocation into the programmed description is refused: the objects exist.
  auto again = add_variable_objects(d, c, *a);
  ASSERT_FALSE(again);
  EXPECT_THAT(again.error().message, HasSubstr("object A000h exists already"));
}

TEST(DynamicIndexAssignment, DirectionWordsOfTheVariablesFile) {
  EXPECT_EQ(variable_direction_from_string("in"), VariableDirection::Input);
  EXPECT_EQ(variable_direction_from_string("OUTPUT"), VariableDirection::Output);
  EXPECT_EQ(variable_direction_from_string("rww"), VariableDirection::Output);
  EXPECT_FALSE(variable_direction_from_string("rw"));
}

TEST(DynamicIndexAssignment, VariablesFileLinesAreNameTypeDirection) {
  auto ok = parse_network_variables(
      "name,type,direction\n# comment\n\nstart, BOOLEAN ,in\r\nlevel,unsigned8,out\n"
      "raw,0x0007,input\n",
      "plc.csv");
  ASSERT_TRUE(ok) << ok.error().message;
  ASSERT_EQ(ok->size(), 3U);
  EXPECT_EQ(ok->at(0), var("start", DataType::Boolean, VariableDirection::Input));
  EXPECT_EQ(ok->at(1), var("level", DataType::Unsigned8, VariableDirection::Output));
  EXPECT_EQ(ok->at(2), var("raw", DataType::Unsigned32, VariableDirection::Input));
  auto fields = parse_network_variables("a,BOOLEAN,in\nb,BOOLEAN\n", "plc.csv");
  ASSERT_FALSE(fields);
  EXPECT_EQ(fields.error().message, "plc.csv:2: expected name,type,direction (3 fields), found 2");
  auto type = parse_network_variables("s,VISIBLE_STRING,in\n", "plc.csv");
  ASSERT_FALSE(type);
  EXPECT_THAT(type.error().message, HasSubstr("plc.csv:1: 'VISIBLE_STRING' is not a fixed-size"));
  auto dir = parse_network_variables("s,REAL32,sideways\n", "plc.csv");
  ASSERT_FALSE(dir);
  EXPECT_THAT(dir.error().message, HasSubstr("plc.csv:1: direction 'sideways' is not in or out"));
}

// §8.4: the objects of a segment come into being when variables are allocated; an EDS must not
// define one (issue 33: such a file passed `cfgmgr check --strict`). An error under strict, a
// warning when tolerant, at the object's line; a DCF (the programmed device's, §8.5) may.
TEST(DynamicChannels, AnEdsThatDefinesAnObjectInsideASegmentIsAnErrorUnderStrict) {
  std::ifstream in(data_file("spec_example.eds"));
  std::stringstream text;
  text << in.rdbuf();
  const std::string eds = text.str() +
                          "\r\n[7002]\r\nParameterName=Inside\r\nObjectType=0x7\r\n"
                          "DataType=0x0005\r\nAccessType=ro\r\nPDOMapping=1\r\n";
  const int line = 1 + static_cast<int>(std::count(
                           eds.begin(), eds.begin() + static_cast<long>(eds.find("[7002]")), '\n'));
  for (const ReadMode mode : {ReadMode::Strict, ReadMode::Tolerant}) {
    ReadOptions options;
    options.mode = mode;
    options.file_name = "inside.eds";
    const ReadResult r = parse_device_description(eds, options);
    const Severity expected = mode == ReadMode::Strict ? Severity::Error : Severity::Warning;
    EXPECT_THAT(at_line(r.diagnostics, line, expected),
                HasSubstr("object 7002h lies in dynamic channel segment 1 (7001h-7017h)"))
        << r.diagnostics.format();
  }
  // The same object in a DCF: allowed.
  ReadOptions options;
  options.mode = ReadMode::Strict;
  const ReadResult dcf =
      parse_device_description(eds + "\r\n[DeviceComissioning]\r\nNodeID=5\r\n", options);
  EXPECT_EQ(dcf.diagnostics.format().find("lies in dynamic channel"), std::string::npos)
      << dcf.diagnostics.format();
}

}  // namespace
}  // namespace cfg
