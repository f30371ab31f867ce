// The CiA 306 EDS/DCF writer: canonical order and form, stamps, and the round-trip contract
// parse(write(m)) == canonical_form(m).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"

namespace cfg {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

SubObject entry(std::uint8_t sub, std::string name, DataType type, AccessType access,
                std::optional<std::string> default_value = std::nullopt) {
  SubObject s;
  s.sub_index = sub;
  s.name = std::move(name);
  s.data_type = static_cast<std::uint16_t>(type);
  s.access = access;
  s.default_value = std::move(default_value);
  return s;
}

Object var(std::uint16_t index, std::string name, DataType type, AccessType access,
           std::optional<std::string> default_value = std::nullopt) {
  Object o;
  o.index = index;
  o.name = name;
  o.object_type = ObjectType::Var;
  o.subs.emplace(0, entry(0, std::move(name), type, access, std::move(default_value)));
  return o;
}

// A small DCF model built in code: 1000h, 1001h, 1018h (RECORD), 2000h (VAR with a
// ParameterValue and Denotation), commissioning, comments, one vendor section.
DeviceDescription model() {
  DeviceDescription d;
  d.file_info.set("FileName", "unit.dcf");
  d.file_info.set("CreatedBy", "writer test");
  d.file_info.set("CreationTime", "09:00AM");
  d.file_info.set("CreationDate", "01-02-2024");
  d.device_info.set("VendorName", "Test");
  d.device_info.set("VendorNumber", "0x00000001");
  d.dummy_usage.set("Dummy0005", "1");
  d.comments = {"first comment", "second ; comment"};
  d.objects.emplace(0x1000,
                    var(0x1000, "Device type", DataType::Unsigned32, AccessType::Ro, "0x00000191"));
  d.objects.emplace(0x1001, var(0x1001, "Error register", DataType::Unsigned8, AccessType::Ro));
  Object id;
  id.index = 0x1018;
  id.name = "Identity object";
  id.object_type = ObjectType::Record;
  id.sub_number = 2;
  id.subs.emplace(
      0, entry(0, "Highest sub-index supported", DataType::Unsigned8, AccessType::Ro, "1"));
  id.subs.emplace(1, entry(1, "Vendor-ID", DataType::Unsigned32, AccessType::Ro, "0x00000001"));
  d.objects.emplace(0x1018, id);
  Object v = var(0x2000, "Speed", DataType::Integer16, AccessType::Rw, "0");
  v.subs.at(0).parameter_value = "-100";
  v.subs.at(0).denotation = "Left wheel speed";
  v.subs.at(0).low_limit = "-1000";
  v.subs.at(0).high_limit = "1000";
  v.subs.at(0).pdo_mapping = true;
  d.objects.emplace(0x2000, v);
  DeviceCommissioning c;
  c.node_id = 5;
  c.node_name = "Left drive";
  c.baudrate_kbps = 500;
  d.commissioning = c;
  d.other_sections.push_back({"VendorSection", {}});
  d.other_sections.back().keys.set("Key", "Value");
  return d;
}

ReadResult parse(std::string_view text) {
  return parse_device_description(text, {ReadMode::Tolerant, "written.dcf"});
}

std::vector<std::string> section_headers(const std::string& text) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  while ((pos = text.find('[', pos)) != std::string::npos) {
    if (pos == 0 || text[pos - 1] == '\n') {
      out.push_back(text.substr(pos + 1, text.find(']', pos) - pos - 1));
    }
    ++pos;
  }
  return out;
}

TEST(DeviceWriter, WritesSectionsInCanonicalOrder) {
  WriteOptions options;
  options.line_ending = LineEnding::Lf;
  const std::string text = write_device_description(model(), options);
  EXPECT_THAT(section_headers(text),
              ::testing::ElementsAre("FileInfo", "DeviceInfo", "DummyUsage", "Comments",
                                     "MandatoryObjects", "OptionalObjects", "ManufacturerObjects",
                                     "1000", "1001", "1018", "1018sub0", "1018sub1", "2000",
                                     "DeviceComissioning", "VendorSection"));
}

TEST(DeviceWriter, WritesCrlfByDefaultAndLfOnRequest) {
  const std::string crlf = write_device_description(model());
  std::size_t bare_lf = 0;
  for (std::size_t i = 0; i < crlf.size(); ++i) {
    if (crlf[i] == '\n' && (i == 0 || crlf[i - 1] != '\r')) ++bare_lf;
  }
  EXPECT_EQ(bare_lf, 0u);
  EXPECT_THAT(crlf, HasSubstr("[1000]\r\nParameterName=Device type\r\n"));
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  const std::string text = write_device_description(model(), lf);
  EXPECT_EQ(text.find('\r'), std::string::npos);
  EXPECT_THAT(text, HasSubstr("[1000]\nParameterName=Device type\n"));
}

TEST(DeviceWriter, WritesObjectKeysInCiA306Form) {
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  const std::string text = write_device_description(model(), lf);
  EXPECT_THAT(text, HasSubstr("[2000]\nParameterName=Speed\nObjectType=0x7\nDataType=0x0003\n"
                              "AccessType=rw\nDefaultValue=0\nPDOMapping=1\nLowLimit=-1000\n"
                              "HighLimit=1000\nParameterValue=-100\n"
                              "Denotation=Left wheel speed\n"));
  EXPECT_THAT(text, HasSubstr("[1018]\nParameterName=Identity object\nObjectType=0x9\n"
                              "SubNumber=0x2\n\n[1018sub0]\n"));
  EXPECT_THAT(text, HasSubstr("[Comments]\nLines=2\nLine1=first comment\n"
                              "Line2=second ; comment\n"));
}

TEST(DeviceWriter, DerivesTheObjectListsFromTheObjects) {
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  const std::string text = write_device_description(model(), lf);
  // CiA 306 §4.5: 1000h, 1001h, 1018h mandatory; 2000h-5FFFh manufacturer-specific.
  EXPECT_THAT(text, HasSubstr("[MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n"
                              "3=0x1018\n"));
  EXPECT_THAT(text, HasSubstr("[OptionalObjects]\nSupportedObjects=0\n"));
  EXPECT_THAT(text, HasSubstr("[ManufacturerObjects]\nSupportedObjects=1\n1=0x2000\n"));
}

TEST(DeviceWriter, EdsHasNoParameterValueDenotationOrCommissioning) {
  WriteOptions eds;
  eds.kind = FileKind::Eds;
  const std::string text = write_device_description(model(), eds);
  EXPECT_THAT(text, Not(HasSubstr("ParameterValue")));
  EXPECT_THAT(text, Not(HasSubstr("Denotation")));
  EXPECT_THAT(text, Not(HasSubstr("DeviceComissioning")));
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_FALSE(r.device->commissioning);
  EXPECT_FALSE(r.device->sub(0x2000, 0)->parameter_value);
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "0");
}

TEST(DeviceWriter, DcfHasCommissioningInTheStandardsSpelling) {
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  const std::string text = write_device_description(model(), lf);
  EXPECT_THAT(text, HasSubstr("[DeviceComissioning]\nNodeID=5\nNodeName=Left drive\n"
                              "Baudrate=500\nNetworkName=\n"));
}

TEST(DeviceWriter, CompactObjectsAreWrittenExpanded) {
  const std::string text =
      "[1016]\nParameterName=Consumer heartbeat time\nObjectType=0x8\nDataType=0x0007\n"
      "AccessType=rw\nCompactSubObj=2\n[1016Value]\nNrOfEntries=1\n2=0x00050064\n";
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  const std::string out = write_device_description(*r.device, lf);
  EXPECT_THAT(out, Not(HasSubstr("CompactSubObj")));
  EXPECT_THAT(out, HasSubstr("[1016]\nParameterName=Consumer heartbeat time\nObjectType=0x8\n"
                             "SubNumber=0x3\n"));
  EXPECT_THAT(out, HasSubstr("[1016sub0]\nParameterName=NrOfObjects\nObjectType=0x7\n"
                             "DataType=0x0005\nAccessType=ro\nDefaultValue=2\n"));
  EXPECT_THAT(out, HasSubstr("[1016sub2]\nParameterName=Consumer heartbeat time2\n"));
  EXPECT_THAT(out, HasSubstr("ParameterValue=0x00050064\n"));
  auto back = parse(out);
  ASSERT_TRUE(back.device);
  EXPECT_EQ(*back.device, canonical_form(*r.device, lf));
  EXPECT_FALSE(back.device->object(0x1016)->compact_sub_obj);
  EXPECT_EQ(back.device->object(0x1016)->sub_number, 3);
}

TEST(DeviceWriter, SubObjectSectionsAreNamedWithHexSubIndex) {
  DeviceDescription d;
  Object a;
  a.index = 0x2100;
  a.name = "Array";
  a.object_type = ObjectType::Array;
  a.subs.emplace(0, entry(0, "n", DataType::Unsigned8, AccessType::Ro, "10"));
  a.subs.emplace(10, entry(10, "tenth", DataType::Unsigned8, AccessType::Rw));
  d.objects.emplace(0x2100, a);
  const std::string text = write_device_description(d);
  EXPECT_THAT(text, HasSubstr("[2100subA]"));
  EXPECT_THAT(text, HasSubstr("SubNumber=0x2"));  // the number of sub-objects, not the highest
}

TEST(DeviceWriter, StampSetsModificationAndFillsMissingCreation) {
  DeviceDescription d;
  d.file_info.set("FileName", "x.eds");
  WriteOptions options;
  options.line_ending = LineEnding::Lf;
  // 1700000000 is 2023-11-14 22:13:20 UTC (GNU date -u -d @1700000000).
  options.stamp = WriteOptions::Stamp{1700000000, "cfgmgr"};
  const std::string text = write_device_description(d, options);
  EXPECT_THAT(text, HasSubstr("[FileInfo]\nFileName=x.eds\nCreatedBy=cfgmgr\n"
                              "CreationTime=10:13PM\nCreationDate=11-14-2023\n"
                              "ModificationTime=10:13PM\nModificationDate=11-14-2023\n"
                              "ModifiedBy=cfgmgr\n"));
}

TEST(DeviceWriter, StampKeepsCreationAndReplacesModification) {
  DeviceDescription d = model();
  d.file_info.set("ModificationTime", "01:00AM");
  WriteOptions options;
  options.line_ending = LineEnding::Lf;
  // 951825600 is 2000-02-29 12:00:00 UTC (GNU date): noon is 12:00PM.
  options.stamp = WriteOptions::Stamp{951825600, "me"};
  auto r = parse(write_device_description(d, options));
  ASSERT_TRUE(r.device);
  const KeyValues& fi = r.device->file_info;
  EXPECT_EQ(*fi.find("CreatedBy"), "writer test");
  EXPECT_EQ(*fi.find("CreationTime"), "09:00AM");
  EXPECT_EQ(*fi.find("CreationDate"), "01-02-2024");
  EXPECT_EQ(*fi.find("ModificationTime"), "12:00PM");
  EXPECT_EQ(*fi.find("ModificationDate"), "02-29-2000");
  EXPECT_EQ(*fi.find("ModifiedBy"), "me");
}

TEST(DeviceWriter, StampAtMidnightAndBefore1970) {
  DeviceDescription d;
  WriteOptions options;
  options.line_ending = LineEnding::Lf;
  options.stamp = WriteOptions::Stamp{0, "x"};  // 1970-01-01 00:00 UTC
  EXPECT_THAT(write_device_description(d, options),
              HasSubstr("ModificationTime=12:00AM\nModificationDate=01-01-1970\n"));
  options.stamp = WriteOptions::Stamp{-86400, "x"};  // 1969-12-31 00:00 UTC (GNU date)
  EXPECT_THAT(write_device_description(d, options), HasSubstr("ModificationDate=12-31-1969\n"));
}

TEST(DeviceWriter, WithoutStampFileInfoIsWrittenAsItIs) {
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  EXPECT_THAT(write_device_description(model(), lf),
              HasSubstr("[FileInfo]\nFileName=unit.dcf\nCreatedBy=writer test\n"
                        "CreationTime=09:00AM\nCreationDate=01-02-2024\n\n[DeviceInfo]"));
}

TEST(DeviceWriter, OutputIsDeterministicAndStableOverARoundTrip) {
  const DeviceDescription d = model();
  const std::string first = write_device_description(d);
  EXPECT_EQ(write_device_description(d), first);
  auto r = parse(first);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(write_device_description(*r.device), first);
}

TEST(DeviceWriter, ReadingTheOutputGivesTheCanonicalForm) {
  for (FileKind kind : {FileKind::Dcf, FileKind::Eds}) {
    for (LineEnding ending : {LineEnding::Crlf, LineEnding::Lf}) {
      WriteOptions options;
      options.kind = kind;
      options.line_ending = ending;
      auto r = parse(write_device_description(model(), options));
      ASSERT_TRUE(r.device);
      EXPECT_FALSE(r.diagnostics.has_errors()) << r.diagnostics.format();
      EXPECT_EQ(*r.device, canonical_form(model(), options));
    }
  }
  // The model above is already canonical for a DCF.
  EXPECT_EQ(canonical_form(model()), model());
}

TEST(DeviceWriter, TextsWithLineBreaksAreWrittenOnOneLine) {
  DeviceDescription d = model();
  d.objects.at(0x2000).name = "two\nlines";
  d.comments.push_back("a\r\nb");
  d.device_info.set("ProductName", "x\ny");
  auto r = parse(write_device_description(d));
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->object(0x2000)->name, "two lines");
  EXPECT_EQ(r.device->comments.back(), "a  b");
  EXPECT_EQ(*r.device->device_info.find("ProductName"), "x y");
  EXPECT_EQ(*r.device, canonical_form(d));
}

TEST(DeviceWriter, LeavesOutKeysAndSectionsThatCannotBeReadBack) {
  DeviceDescription d = model();
  d.device_info.entries.push_back({"", "no key"});
  d.device_info.entries.push_back({"a=b", "equals in key"});
  d.device_info.entries.push_back({";x", "comment"});
  d.other_sections.push_back({"1000", {}});      // would be read as object 1000h
  d.other_sections.push_back({"FileInfo", {}});  // would be read as [FileInfo]
  d.other_sections.push_back({"bad]name", {}});
  d.other_sections.back().keys.set("k", "v");
  const std::string text = write_device_description(d);
  EXPECT_THAT(text, Not(HasSubstr("no key")));
  EXPECT_THAT(text, Not(HasSubstr("a=b=")));
  EXPECT_THAT(text, Not(HasSubstr("bad]name")));
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(*r.device, canonical_form(d));
  EXPECT_EQ(r.device->other_sections.size(), 1u);
}

TEST(DeviceWriter, VarObjectIsWrittenFromSubIndexZeroWithTheObjectsName) {
  DeviceDescription d;
  Object v = var(0x2000, "Object name", DataType::Unsigned8, AccessType::Rw, "1");
  v.subs.at(0).name = "other name";
  v.subs.emplace(1, entry(1, "not for a VAR", DataType::Unsigned8, AccessType::Rw));
  d.objects.emplace(0x2000, v);
  auto r = parse(write_device_description(d));
  ASSERT_TRUE(r.device);
  const Object* o = r.device->object(0x2000);
  ASSERT_EQ(o->subs.size(), 1u);
  EXPECT_EQ(o->sub(0)->name, "Object name");
  EXPECT_EQ(*r.device, canonical_form(d));
}

TEST(DeviceWriter, OutputOfACompleteModelIsCleanEvenForTheStrictReader) {
  for (FileKind kind : {FileKind::Dcf, FileKind::Eds}) {
    WriteOptions options;
    options.kind = kind;
    auto r = parse_device_description(write_device_description(model(), options),
                                      {ReadMode::Strict, "written"});
    EXPECT_TRUE(r.ok());
    EXPECT_TRUE(r.diagnostics.empty()) << r.diagnostics.format();
  }
}

// A model whose text is several of the writer's 64 KiB pieces: 2000h-25FFh, VARs with values.
DeviceDescription large_model() {
  DeviceDescription d = model();
  for (std::uint16_t i = 0; i < 0x600; ++i) {
    Object v = var(static_cast<std::uint16_t>(0x2100 + i),
                   "Manufacturer parameter number " + std::to_string(i), DataType::Unsigned32,
                   AccessType::Rw, "0x00000010");
    v.subs.at(0).parameter_value = "0x00000020";
    d.objects.emplace(v.index, std::move(v));
  }
  return d;
}

TEST(DeviceWriter, StreamedTextIsTheWholeTextInPieces) {
  const DeviceDescription d = large_model();
  const std::string whole = write_device_description(d);
  ASSERT_GT(whole.size(), std::size_t{3} * 64 * 1024);
  std::string streamed;
  std::size_t pieces = 0;
  EXPECT_TRUE(write_device_description(d, {}, [&](std::string_view piece) {
    ++pieces;
    EXPECT_LE(piece.size(), std::size_t{65} * 1024);  // about 64 KiB: never the whole text
    streamed += piece;
    return true;
  }));
  EXPECT_EQ(streamed, whole);
  EXPECT_GT(pieces, std::size_t{3});
}

TEST(DeviceWriter, ASinkThatSaysStopEndsTheWriter) {
  std::size_t pieces = 0;
  EXPECT_FALSE(write_device_description(large_model(), {}, [&](std::string_view) {
    ++pieces;
    return false;  // e.g. the disk is full
  }));
  EXPECT_EQ(pieces, 1U);
}

TEST(DeviceWriter, StampOnChangeLeavesAnUnchangedTextAsItIs) {
  const DeviceDescription d = large_model();
  const std::string old_text = write_device_description(d);
  WriteOptions options;
  options.stamp = WriteOptions::Stamp{1700000000, "cfgmgr"};
  options.stamp_only_if_changed_from = old_text;
  EXPECT_EQ(write_device_description(d, options), old_text);
}

TEST(DeviceWriter, StampOnChangeStampsADifferenceInTheLastPiece) {
  const DeviceDescription d = large_model();
  std::string old_text = write_device_description(d);
  WriteOptions options;
  options.stamp = WriteOptions::Stamp{1700000000, "cfgmgr"};
  const std::string stamped = write_device_description(d, options);
  ASSERT_THAT(stamped, HasSubstr("ModifiedBy=cfgmgr"));
  // The model's text differs from the old file only near its end (its last value), or only by
  // the old file being longer: both are a change, so the output is stamped.
  old_text[old_text.size() - 8] = 'X';
  options.stamp_only_if_changed_from = old_text;
  EXPECT_EQ(write_device_description(d, options), stamped);
  const std::string longer = write_device_description(d) + "\r\n";
  options.stamp_only_if_changed_from = longer;
  EXPECT_EQ(write_device_description(d, options), stamped);
}

// Values set in code, not read: written as the reader would have stored them (the rules of
// cfg/device_file.hpp's canonical_form), and the same as writing canonical_form() of the model.
TEST(DeviceWriter, ValuesSetInCodeAreWrittenAsTheReaderStoresThem) {
  DeviceDescription d = model();
  auto add = [&d](std::uint16_t index, DataType type, std::string value) {
    d.objects.emplace(index, var(index, "Value", type, AccessType::Rw, std::move(value)));
  };
  add(0x2001, DataType::Unsigned16, "0180h");       // CiA 301 document style: read as 0x hex
  add(0x2002, DataType::Unsigned8, "5 ; five");     // an inline comment after a number is cut
  add(0x2003, DataType::OctetString, "0x0A0B");     // the vendor form: the digits are kept
  add(0x2004, DataType::Domain, "0XABCD");          // the same, upper-case prefix
  add(0x2005, DataType::VisibleString, "a ; b");    // a string keeps what looks like a comment
  add(0x2006, DataType::Unsigned8, "");             // empty fixed-size value: not given
  add(0x2007, DataType::VisibleString, "");         // empty string: given, empty
  add(0x2008, DataType::Unsigned32, " 0x10 ");      // blanks around it go
  add(0x2009, DataType::Unsigned32, "0x10\r\n");    // as does a line break
  add(0x200A, DataType::Unsigned32, "0x00000191");  // already canonical
  WriteOptions lf;
  lf.line_ending = LineEnding::Lf;
  const std::string text = write_device_description(d, lf);
  auto value_of = [&text](std::uint16_t index) {
    const std::string section = "[" + hex_digits(index, 4) + "]\n";
    const std::size_t at = text.find(section);
    if (at == std::string::npos) return std::string("(no section)");
    const std::size_t end = text.find("\n\n", at);
    const std::string body = text.substr(at, end - at);
    const std::size_t key = body.find("DefaultValue=");
    if (key == std::string::npos) return std::string("(no DefaultValue)");
    const std::size_t eol = body.find('\n', key);
    return body.substr(key + 13, eol - key - 13);
  };
  EXPECT_EQ(value_of(0x2001), "0x0180");
  EXPECT_EQ(value_of(0x2002), "5");
  EXPECT_EQ(value_of(0x2003), "0A0B");
  EXPECT_EQ(value_of(0x2004), "ABCD");
  EXPECT_EQ(value_of(0x2005), "a ; b");
  EXPECT_EQ(value_of(0x2006), "(no DefaultValue)");
  EXPECT_EQ(value_of(0x2007), "");
  EXPECT_EQ(value_of(0x2008), "0x10");
  EXPECT_EQ(value_of(0x2009), "0x10");
  EXPECT_EQ(value_of(0x200A), "0x00000191");
  EXPECT_EQ(write_device_description(canonical_form(d, lf), lf), text);
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(*r.device, canonical_form(d, lf));
}

// A DOMAIN value can be far longer than the writer's 64 KiB pieces (vendor tools export
// firmware-sized DOMAIN values on one line): it is written whole.
TEST(DeviceWriter, AValueLongerThanAPieceIsWrittenWhole) {
  DeviceDescription d = model();
  std::string digits;
  for (int i = 0; i < 100000; ++i) digits += "A5";
  Object blob = var(0x2010, "Blob", DataType::Domain, AccessType::Rw, digits);
  d.objects.emplace(0x2010, blob);
  const std::string text = write_device_description(d);
  EXPECT_THAT(text, HasSubstr("DefaultValue=" + digits + "\r\nPDOMapping=0\r\n"));
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(*r.device, canonical_form(d));
}

}  // namespace
}  // namespace cfg
