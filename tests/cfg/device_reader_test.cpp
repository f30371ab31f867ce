// The CiA 306 EDS/DCF reader, from small texts written here. CiA 306 is not in spec/; the rules
// come from public knowledge of the standard (names say so where that knowledge is thin) and the
// choices documented at the top of libcfg/src/device_reader.cpp.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/write_acceptance.hpp"
#include "concise_test_support.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

std::string hex4(std::uint16_t v) {
  return hex_digits(v, 4);
}

// A complete, clean EDS (no deviation, also in strict mode) with 1000h, 1001h, 1018h, plus
// `more` sections; `optional`/`manufacturer` are added to the object lists.
std::string eds(std::string_view more = "", std::initializer_list<std::uint16_t> optional = {},
                std::initializer_list<std::uint16_t> manufacturer = {}) {
  std::string s =
      "[FileInfo]\n"
      "FileName=test.eds\n"
      "FileVersion=1\n"
      "FileRevision=0\n"
      "EDSVersion=4.0\n"
      "Description=unit test device\n"
      "CreationTime=09:00AM\n"
      "CreationDate=01-02-2024\n"
      "CreatedBy=tests\n"
      "\n"
      "[DeviceInfo]\n"
      "VendorName=Test\n"
      "VendorNumber=0x00000001\n"
      "ProductName=Unit\n"
      "ProductNumber=0x00000002\n"
      "RevisionNumber=0x00010000\n"
      "BaudRate_125=1\n"
      "SimpleBootUpSlave=1\n"
      "Granularity=8\n"
      "NrOfRXPDO=0\n"
      "NrOfTXPDO=0\n"
      "LSS_Supported=0\n"
      "\n"
      "[MandatoryObjects]\n"
      "SupportedObjects=3\n"
      "1=0x1000\n"
      "2=0x1001\n"
      "3=0x1018\n";
  auto list = [&](const char* name, std::initializer_list<std::uint16_t> indices) {
    if (indices.size() == 0) return;
    s += std::string("\n[") + name + "]\nSupportedObjects=" + std::to_string(indices.size()) + "\n";
    int n = 1;
    for (auto i : indices) s += std::to_string(n++) + "=0x" + hex4(i) + "\n";
  };
  list("OptionalObjects", optional);
  list("ManufacturerObjects", manufacturer);
  s += "\n[1000]\n"
       "ParameterName=Device type\n"
       "ObjectType=0x7\n"
       "DataType=0x0007\n"
       "AccessType=ro\n"
       "DefaultValue=0x00000191\n"
       "PDOMapping=0\n"
       "\n"
       "[1001]\n"
       "ParameterName=Error register\n"
       "ObjectType=0x7\n"
       "DataType=0x0005\n"
       "AccessType=ro\n"
       "DefaultValue=0\n"
       "PDOMapping=1\n"
       "\n"
       "[1018]\n"
       "ParameterName=Identity object\n"
       "ObjectType=0x9\n"
       "SubNumber=2\n"
       "\n"
       "[1018sub0]\n"
       "ParameterName=Highest sub-index supported\n"
       "ObjectType=0x7\n"
       "DataType=0x0005\n"
       "AccessType=ro\n"
       "DefaultValue=1\n"
       "PDOMapping=0\n"
       "\n"
       "[1018sub1]\n"
       "ParameterName=Vendor-ID\n"
       "ObjectType=0x7\n"
       "DataType=0x0007\n"
       "AccessType=ro\n"
       "DefaultValue=0x00000001\n"
       "PDOMapping=0\n";
  if (!more.empty()) s += "\n" + std::string(more);
  return s;
}

// A manufacturer VAR 2000h with the given DataType and extra keys.
std::string var2000(std::string_view data_type, std::string_view keys) {
  return eds("[2000]\nParameterName=Test value\nObjectType=0x7\nDataType=" +
                 std::string(data_type) + "\nAccessType=rw\nPDOMapping=0\n" + std::string(keys),
             {}, {0x2000});
}

ReadResult parse(std::string_view text, ReadMode mode = ReadMode::Tolerant) {
  ReadOptions options;
  options.mode = mode;
  options.file_name = "test.eds";
  return parse_device_description(text, options);
}

// 1-based line of the `nth` (1-based) occurrence of `needle`; -1 if there is none.
int line_of(std::string_view text, std::string_view needle, int nth = 1) {
  std::size_t at = text.find(needle);
  for (int i = 1; i < nth && at != std::string_view::npos; ++i) at = text.find(needle, at + 1);
  if (at == std::string_view::npos) return -1;
  int line = 1;
  for (std::size_t i = 0; i < at; ++i) line += text[i] == '\n' ? 1 : 0;
  return line;
}

// The diagnostic at `line` (0: any line) whose message contains every part.
const Diagnostic* find_diag(const ReadResult& r, int line,
                            std::initializer_list<std::string_view> parts) {
  for (const Diagnostic& d : r.diagnostics.items()) {
    if (line != 0 && d.line != line) continue;
    bool all = true;
    for (auto p : parts) all = all && d.message.find(p) != std::string::npos;
    if (all) return &d;
  }
  return nullptr;
}

::testing::AssertionResult has_diag(const ReadResult& r, int line, Severity severity,
                                    std::initializer_list<std::string_view> parts) {
  const Diagnostic* d = find_diag(r, line, parts);
  if (d != nullptr && d->severity == severity) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "no " << to_string(severity) << " at line " << line << " containing the parts; got:\n"
         << r.diagnostics.format();
}

::testing::AssertionResult clean(const ReadResult& r) {
  if (r.device && r.diagnostics.empty()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << (r.device ? "" : "no model; ") << r.diagnostics.format();
}

// ---------------------------------------------------------------------------------------------
// Lines, sections, keys

TEST(DeviceReader, ReadsACleanFileWithoutDiagnosticsEvenInStrictMode) {
  const std::string text = eds();
  auto r = parse(text, ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  EXPECT_TRUE(r.ok());
  const DeviceDescription& d = *r.device;
  ASSERT_EQ(d.objects.size(), 3u);
  EXPECT_EQ(*d.file_info.find("CreatedBy"), "tests");
  EXPECT_EQ(*d.device_info.find("VendorName"), "Test");
  const Object* o = d.object(0x1018);
  ASSERT_NE(o, nullptr);
  EXPECT_EQ(o->object_type, ObjectType::Record);
  EXPECT_EQ(o->sub_number, 2);
  EXPECT_EQ(o->line, line_of(text, "[1018]"));
  ASSERT_NE(o->sub(1), nullptr);
  EXPECT_EQ(o->sub(1)->name, "Vendor-ID");
  EXPECT_EQ(o->sub(1)->default_value, "0x00000001");
  EXPECT_EQ(o->sub(1)->line, line_of(text, "[1018sub1]"));
}

TEST(DeviceReader, VarObjectCarriesItsAttributesInSubIndexZero) {
  auto r = parse(eds());
  ASSERT_TRUE(r.device);
  const Object* o = r.device->object(0x1001);
  ASSERT_NE(o, nullptr);
  EXPECT_EQ(o->name, "Error register");
  EXPECT_TRUE(o->is_var());
  ASSERT_EQ(o->subs.size(), 1u);
  const SubObject& s = o->subs.at(0);
  EXPECT_EQ(s.sub_index, 0);
  EXPECT_EQ(s.name, "Error register");
  EXPECT_EQ(s.data_type, 0x0005);
  EXPECT_EQ(s.basic_type(), DataType::Unsigned8);
  EXPECT_EQ(s.access, AccessType::Ro);
  EXPECT_TRUE(s.pdo_mapping);
  EXPECT_EQ(s.default_value, "0");
}

TEST(DeviceReader, SectionAndKeyNamesAreCaseInsensitive) {
  std::string text =
      eds("[2000]\nPARAMETERNAME=Upper\nobjecttype=0x9\nsubnumber=1\n"
          "[2000SUB0]\nparametername=lower\nDATATYPE=0x0005\naccesstype=ro\n",
          {}, {0x2000});
  // Known sections in any case too.
  text.replace(text.find("[FileInfo]"), 10, "[fileinfo]");
  text.replace(text.find("[MandatoryObjects]"), 18, "[MANDATORYOBJECTS]");
  auto r = parse(text);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(*r.device->file_info.find("FileName"), "test.eds");
  const Object* o = r.device->object(0x2000);
  ASSERT_NE(o, nullptr);
  EXPECT_EQ(o->name, "Upper");
  EXPECT_EQ(o->object_type, ObjectType::Record);
  ASSERT_NE(o->sub(0), nullptr);
  EXPECT_EQ(o->sub(0)->name, "lower");
}

TEST(DeviceReader, LowerCaseHexInObjectSectionNames) {
  auto r = parse(eds("[2a0f]\nParameterName=x\nDataType=0x0005\nAccessType=rw\n", {}, {0x2A0F}));
  ASSERT_TRUE(clean(r));
  EXPECT_NE(r.device->object(0x2A0F), nullptr);
}

TEST(DeviceReader, SubSectionSpellingsSubAndHexSubIndexInAnyCase) {
  // "subb" is "sub" + hex "b" = sub-index 0Bh, as in emsiso.eds; "Sub" as in python-canopen.
  auto r =
      parse(eds("[2000]\nParameterName=a\nObjectType=0x8\nSubNumber=4\n"
                "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\n"
                "[2000Sub1]\nParameterName=one\nDataType=0x0005\nAccessType=rw\n"
                "[2000subb]\nParameterName=eleven\nDataType=0x0005\nAccessType=rw\n"
                "[2000SUB0A]\nParameterName=ten\nDataType=0x0005\nAccessType=rw\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const Object* o = r.device->object(0x2000);
  ASSERT_EQ(o->subs.size(), 4u);
  EXPECT_EQ(o->sub(1)->name, "one");
  EXPECT_EQ(o->sub(0x0B)->name, "eleven");
  EXPECT_EQ(o->sub(0x0A)->name, "ten");
}

TEST(DeviceReader, AcceptsCrlfLfAndLoneCrLineEndsInOneFile) {
  std::string text =
      eds("[2000]\r\nParameterName=crlf\r\nDataType=0x0005\rAccessType=rw\nDefaultValue=300\r\n",
          {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x2000, 0);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->name, "crlf");  // no '\r' left in the text
  EXPECT_EQ(s->access, AccessType::Rw);
  // Line numbers count every line end: [2000] is line L, DefaultValue is L+4.
  const int l = line_of(text, "[2000]");
  EXPECT_TRUE(has_diag(r, l + 4, Severity::Warning, {"[2000] DefaultValue \"300\"", "UNSIGNED8"}));
}

TEST(DeviceReader, ReadsAFileWithoutFinalLineEnd) {
  std::string text =
      eds("[2000]\nParameterName=last\nDataType=0x0005\nAccessType=rw\n"
          "DefaultValue=7",
          {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "7");
}

TEST(DeviceReader, KeepsUtf8AndLatin1BytesOfTextsAsTheyAre) {
  auto r =
      parse(eds("[2000]\nParameterName=Temp\xC3\xA9rature \xB0"
                "C\nDataType=0x0009\nAccessType=ro\nDefaultValue=Gr\xFC\xDF"
                "e\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(s->name,
            "Temp\xC3\xA9rature \xB0"
            "C");
  EXPECT_EQ(s->default_value,
            "Gr\xFC\xDF"
            "e");
}

TEST(DeviceReader, SkipsAUtf8ByteOrderMarkWhichStrictModeReports) {
  const std::string text = "\xEF\xBB\xBF" + eds();
  auto tolerant = parse(text);
  EXPECT_TRUE(clean(tolerant));
  EXPECT_EQ(*tolerant.device->file_info.find("FileName"), "test.eds");
  auto strict = parse(text, ReadMode::Strict);
  EXPECT_TRUE(has_diag(strict, 1, Severity::Error, {"byte order mark"}));
}

TEST(DeviceReader, RejectsAnEmptyFileWithAnError) {
  for (std::string_view text : {std::string_view(""), std::string_view(" \r\n\n\t\n")}) {
    auto r = parse(text);
    EXPECT_FALSE(r.device);
    ASSERT_EQ(r.diagnostics.size(), 1u);
    EXPECT_EQ(r.diagnostics.items()[0].severity, Severity::Error);
    EXPECT_THAT(r.diagnostics.items()[0].format(), HasSubstr("test.eds: error: the file is empty"));
  }
}

TEST(DeviceReader, RejectsTextWithoutAnySectionAsNotAnEdsWithOneError) {
  auto r = parse("master:\n  node_id: 1\nfoo=bar\n");
  EXPECT_FALSE(r.device);
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_THAT(r.diagnostics.items()[0].message, HasSubstr("no [section] header"));
}

TEST(DeviceReader, AllowsBlanksAroundTheEqualsSign) {
  auto r =
      parse(eds("[2000]\nParameterName = Spaced name \nDataType\t=\t0x0005\n"
                "AccessType =rw\nDefaultValue= 5\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(s->name, "Spaced name");
  EXPECT_EQ(s->default_value, "5");
}

TEST(DeviceReader, IndentedKeysAreKeysNotContinuationLines) {
  // inih would append an indented line to the previous value (multi-line values).
  auto r =
      parse(eds("[2000]\n  ParameterName=Indented\n\tDataType=0x0005\n    AccessType=rw\n"
                "   DefaultValue=12\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(s->name, "Indented");
  EXPECT_EQ(s->data_type, 0x0005);
  EXPECT_EQ(s->default_value, "12");
}

TEST(DeviceReader, ReadsA20000CharacterValueAndTheLinesAfterIt) {
  // Debian's inih cuts lines at 200 bytes and parses the rest as a new line.
  std::string long_value(20000, 'x');
  for (std::size_t i = 0; i < long_value.size(); i += 97) long_value[i] = '=';
  long_value[5000] = '[';
  auto r = parse(eds("[2000]\nParameterName=Long\nDataType=0x0009\nAccessType=ro\nDefaultValue=" +
                         long_value + "\nPDOMapping=1\n",
                     {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(s->default_value, long_value);
  EXPECT_TRUE(s->pdo_mapping);
}

TEST(DeviceReader, WarnsAboutKeysBeforeTheFirstSectionAndIgnoresThem) {
  const std::string text = "; header comment\nStray=1\n" + eds();
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_TRUE(has_diag(r, 2, Severity::Warning, {"Stray", "before the first section"}));
}

TEST(DeviceReader, WarnsAboutLinesThatAreNoKeyNoSectionNoComment) {
  auto r = parse(
      eds("[2000]\nParameterName=x\nDataType=0x0005\nAccessType=rw\njust words\n", {}, {0x2000}));
  ASSERT_TRUE(r.device);
  EXPECT_TRUE(has_diag(r, 0, Severity::Warning, {"[2000] line is neither", "\"just words\""}));
}

TEST(DeviceReader, TextAfterTheSectionNameIsIgnoredWithAWarning) {
  // CiA_profiles_301.eds writes "[1003sub01] # repeat until 1003subFE".
  const std::string text =
      eds("[2000] # a comment\nParameterName=x\nDataType=0x0005\n"
          "AccessType=rw\n",
          {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_NE(r.device->object(0x2000), nullptr);
  EXPECT_TRUE(has_diag(r, line_of(text, "[2000]"), Severity::Warning,
                       {"[2000]", "text after the section name"}));
}

TEST(DeviceReader, SectionHeaderWithoutClosingBracketIsReadWithAWarning) {
  const std::string text =
      eds("[2000\nParameterName=x\nDataType=0x0005\nAccessType=rw\n", {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_NE(r.device->object(0x2000), nullptr);
  EXPECT_TRUE(has_diag(r, line_of(text, "[2000"), Severity::Warning, {"no closing ']'"}));
}

// ---------------------------------------------------------------------------------------------
// Comments

TEST(DeviceReader, SemicolonLinesAreComments) {
  auto r =
      parse(eds("[2000]\nParameterName=x\n;DefaultValue=99\nDataType=0x0005\n  ; indented\n"
                "AccessType=rw\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  EXPECT_FALSE(r.device->sub(0x2000, 0)->default_value);  // the commented-out key is not read
}

TEST(DeviceReader, HashCommentLinesAreAcceptedButNotCiA306) {
  const std::string text =
      eds("[2000]\nParameterName=x\n# Category: Optional\nDataType=0x0005\nAccessType=rw\n", {},
          {0x2000});
  EXPECT_TRUE(clean(parse(text)));
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "# Category"), Severity::Error,
                       {"'#' comment"}));
}

TEST(DeviceReader, StringValueKeepsSemicolonAndHashAfterBlanks) {
  auto r =
      parse(eds("[2000]\nParameterName=Name ; with # marks\nDataType=0x0009\nAccessType=ro\n"
                "DefaultValue=text ; more # and more\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(s->name, "Name ; with # marks");
  EXPECT_EQ(s->default_value, "text ; more # and more");
}

TEST(DeviceReader, NumberFollowedByCommentIsCutWithAWarningInTolerantMode) {
  const std::string text = var2000("0x0007", "DefaultValue=0x10 ; sixteen\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "0x10");
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=0x10"), Severity::Warning,
                       {"[2000] DefaultValue", "\"; sixteen\"", "comment"}));
}

TEST(DeviceReader, NumberFollowedByCommentIsAnErrorInStrictMode) {
  const std::string text = var2000("0x0007", "DefaultValue=0x10 ; sixteen\n");
  auto r = parse(text, ReadMode::Strict);
  ASSERT_TRUE(r.device);  // strict mode still gives the model
  EXPECT_FALSE(r.ok());
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=0x10"), Severity::Error,
                       {"[2000] DefaultValue", "comment"}));
}

TEST(DeviceReader, HashInlineCommentsOnAttributeKeysAsInCiaProfileFiles) {
  // CiA_profiles_301.eds: "ObjectType=0x07 # VAR", "DataType=0x0007 # UNSIGNED32",
  // "AccessType=rw # rw;", "PDOMapping=0 # No".
  const std::string text = eds(
      "[2000]\nParameterName=Profile entry\nObjectType=0x07 # VAR\nDataType=0x0007 # UNSIGNED32\n"
      "AccessType=rw # rw;\nPDOMapping=1 # Optional\n",
      {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(r.device->object(0x2000)->object_type, ObjectType::Var);
  EXPECT_EQ(s->data_type, 0x0007);
  EXPECT_EQ(s->access, AccessType::Rw);
  EXPECT_TRUE(s->pdo_mapping);
  EXPECT_TRUE(has_diag(r, line_of(text, "ObjectType=0x07"), Severity::Warning,
                       {"[2000] ObjectType", "\"# VAR\""}));
  // Tolerant: the first in full, the other three summed up in one warning; strict: each one.
  EXPECT_EQ(r.diagnostics.count(Severity::Warning), 2u);
  EXPECT_TRUE(has_diag(r, 0, Severity::Warning, {"3 more values have a comment after them"}));
  EXPECT_EQ(parse(text, ReadMode::Strict).diagnostics.count(Severity::Error), 4u);
}

// ---------------------------------------------------------------------------------------------
// Duplicates

TEST(DeviceReader, DuplicateSectionIsMergedAndTheLaterKeyWins) {
  const std::string text =
      eds("[2000]\nParameterName=first\nDataType=0x0005\nAccessType=rw\nDefaultValue=1\n"
          "[2000]\nParameterName=second\nPDOMapping=1\n",
          {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(r.device->object(0x2000)->name, "second");
  EXPECT_EQ(s->default_value, "1");  // from the first occurrence
  EXPECT_TRUE(s->pdo_mapping);       // from the second
  const int first = line_of(text, "[2000]");
  const int second = line_of(text, "[2000]", 2);
  EXPECT_TRUE(has_diag(
      r, second, Severity::Warning,
      {"[2000] appears a second time", "first at line " + std::to_string(first), "later value"}));
}

TEST(DeviceReader, DuplicateKeyTakesTheLaterValueAndNamesTheFirstLine) {
  const std::string text = var2000("0x0005", "DefaultValue=11\nDefaultValue=12\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "12");
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=12"), Severity::Warning,
                       {"[2000] DefaultValue is given a second time",
                        "first at line " + std::to_string(line_of(text, "DefaultValue=11"))}));
}

TEST(DeviceReader, DuplicateKeyInKeyValueSectionKeepsItsPlaceWithTheLaterValue) {
  std::string text = eds();
  text.insert(text.find("CreatedBy=tests"), "FileVersion=7\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const auto& entries = r.device->file_info.entries;
  ASSERT_GE(entries.size(), 2u);
  EXPECT_EQ(entries[1].first, "FileVersion");
  EXPECT_EQ(entries[1].second, "7");
  EXPECT_TRUE(has_diag(r, line_of(text, "FileVersion=7"), Severity::Warning,
                       {"[FileInfo] FileVersion is given a second time"}));
}

// ---------------------------------------------------------------------------------------------
// Object lists (CiA 306 §4.5)

TEST(DeviceReader, SupportedObjectsThatDisagreeWithTheListIsWarnedAndTheListWins) {
  std::string text = eds();
  text.replace(text.find("SupportedObjects=3"), 18, "SupportedObjects=2");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->objects.size(), 3u);
  EXPECT_TRUE(has_diag(r, line_of(text, "SupportedObjects=2"), Severity::Warning,
                       {"[MandatoryObjects] SupportedObjects 2 but 3 objects are listed"}));
}

TEST(DeviceReader, SupportedObjectsMayBeWrittenInHex) {
  std::string text = eds();
  text.replace(text.find("SupportedObjects=3"), 18, "SupportedObjects=0x03");
  EXPECT_TRUE(clean(parse(text, ReadMode::Strict)));
}

TEST(DeviceReader, ObjectListedWithoutASectionIsWarnedAndNotCreated) {
  const std::string text = eds("", {0x1017});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->object(0x1017), nullptr);
  EXPECT_TRUE(has_diag(r, line_of(text, "1=0x1017"), Severity::Warning,
                       {"[OptionalObjects] lists 1017h", "no [1017] section"}));
}

TEST(DeviceReader, SectionOfAnObjectNoListNamesIsKeptWithAWarning) {
  const std::string text =
      eds("[1017]\nParameterName=Producer heartbeat time\nDataType=0x0006\n"
          "AccessType=rw\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_NE(r.device->object(0x1017), nullptr);
  EXPECT_TRUE(
      has_diag(r, line_of(text, "[1017]"), Severity::Warning, {"[1017] is in no object list"}));
}

TEST(DeviceReader, FileWithoutObjectListsGetsOneWarning) {
  // node-canopen's tiny_sample.eds has no lists at all.
  auto r = parse(
      "[DeviceInfo]\nVendorName=x\n[1000]\nParameterName=a\nDataType=7\nAccessType=ro\n"
      "[1001]\nParameterName=b\nDataType=5\nAccessType=ro\n");
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->objects.size(), 2u);
  EXPECT_TRUE(has_diag(r, 0, Severity::Warning, {"no object lists"}));
  EXPECT_EQ(find_diag(r, 0, {"in no object list"}), nullptr);
}

TEST(DeviceReader, ObjectListedTwiceIsWarned) {
  std::string text = eds();
  text.replace(text.find("3=0x1018\n"), 9, "3=0x1018\n4=0x1001\n");
  text.replace(text.find("SupportedObjects=3"), 18, "SupportedObjects=4");
  auto r = parse(text);
  EXPECT_TRUE(has_diag(r, line_of(text, "4=0x1001"), Severity::Warning,
                       {"lists 1001h again", "first at line"}));
}

TEST(DeviceReader, ObjectInTheWrongListIsAnErrorOnlyInStrictMode) {
  // 2000h-5FFFh belong in [ManufacturerObjects] (CiA 306 §4.5).
  const std::string text =
      eds("[2000]\nParameterName=x\nDataType=0x0005\nAccessType=rw\n", {0x2000});
  EXPECT_TRUE(clean(parse(text)));
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "1=0x2000"), Severity::Error,
                       {"belongs in [ManufacturerObjects]"}));
}

TEST(DeviceReader, MissingMandatoryObjectIsWarned) {
  std::string text = eds();
  text.replace(text.find("[1001]"), 6, "[1002]");
  auto r = parse(text);
  EXPECT_TRUE(has_diag(r, 0, Severity::Warning, {"mandatory object 1001h is missing"}));
}

// ---------------------------------------------------------------------------------------------
// Object and sub-object keys (CiA 306 §4.6.3)

TEST(DeviceReader, MissingObjectTypeMeansVarWithoutADiagnostic_CiA306_4_6_3_2) {
  auto r = parse(eds("[2000]\nParameterName=x\nDataType=0x0005\nAccessType=rw\n", {}, {0x2000}),
                 ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->object(0x2000)->object_type, ObjectType::Var);
}

TEST(DeviceReader, DecimalDataTypeIsRead) {
  auto r = parse(var2000("7", "DefaultValue=0x12345678\n"));
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->sub(0x2000, 0)->basic_type(), DataType::Unsigned32);
}

TEST(DeviceReader, UnknownDataTypeIsWarnedAndItsValuesAreNotChecked) {
  const std::string text = var2000("0x0040", "DefaultValue=anything\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 0)->data_type, 0x0040);
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "anything");
  EXPECT_TRUE(has_diag(r, line_of(text, "DataType=0x0040"), Severity::Warning,
                       {"[2000] DataType 0x0040 is not a basic data type"}));
  EXPECT_EQ(r.diagnostics.size(), 1u);
}

TEST(DeviceReader, ValueOutOfTheRangeOfItsTypeIsWarned) {
  // UNSIGNED8 holds 0..255 (CiA 301 §7.1.4).
  const std::string text = var2000("0x0005", "DefaultValue=256\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "256");  // kept as written
  EXPECT_TRUE(
      has_diag(r, line_of(text, "DefaultValue=256"), Severity::Warning,
               {"[2000] DefaultValue \"256\" is not a valid UNSIGNED8", "DataType 0x0005"}));
}

TEST(DeviceReader, DefaultValueNotParseableForItsTypeIsWarnedInTolerantAndAnErrorInStrictMode) {
  const std::string text = var2000("0x0007", "DefaultValue=No\n");
  EXPECT_TRUE(has_diag(parse(text), line_of(text, "DefaultValue=No"), Severity::Warning,
                       {"[2000] DefaultValue \"No\" is not a valid UNSIGNED32"}));
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "DefaultValue=No"),
                       Severity::Error, {"[2000] DefaultValue"}));
}

// A DCF's ParameterValue is what a configuration manager downloads (CiA 302 §6): one that cannot
// be encoded for its type is an error in either mode.
TEST(DeviceReader, ParameterValueNotParseableForItsTypeIsAnErrorInBothModes) {
  const std::string text = var2000("0x0007", "ParameterValue=No\n");
  for (ReadMode mode : {ReadMode::Tolerant, ReadMode::Strict}) {
    auto r = parse(text, mode);
    EXPECT_TRUE(has_diag(r, line_of(text, "ParameterValue=No"), Severity::Error,
                         {"[2000] ParameterValue \"No\" is not a valid UNSIGNED32"}));
    EXPECT_FALSE(r.ok());
  }
}

TEST(DeviceReader, DiagnosticsFormatAsFileLineSeverityMessage) {
  const std::string text = var2000("0x0005", "DefaultValue=256\n");
  auto r = parse(text);
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_EQ(r.diagnostics.items()[0].format().rfind(
                "test.eds:" + std::to_string(line_of(text, "DefaultValue=256")) +
                    ": warning: [2000] DefaultValue \"256\"",
                0),
            0u);
}

TEST(DeviceReader, NodeIdFormulasStayAsWrittenAndAreChecked) {
  const std::string text = eds(
      "[2000]\nParameterName=a\nObjectType=0x8\nSubNumber=4\n"
      "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=3\n"
      "[2000sub1]\nParameterName=b\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x180\n"
      "[2000sub2]\nParameterName=c\nDataType=0x0007\nAccessType=rw\n"
      "DefaultValue=0x200 + $NodeId\n"
      "[2000sub3]\nParameterName=d\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+xyz\n",
      {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 1)->default_value, "$NODEID+0x180");
  EXPECT_EQ(r.device->sub(0x2000, 2)->default_value, "0x200 + $NodeId");
  EXPECT_EQ(r.diagnostics.size(), 1u) << r.diagnostics.format();
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=$NODEID+xyz"), Severity::Warning,
                       {"[2000sub3] DefaultValue \"$NODEID+xyz\""}));
}

TEST(DeviceReader, HSuffixHexIsReadWithAWarningAndStoredAs0xHex) {
  // CiA_profiles_301.eds writes CiA 301 document style: "0180h", "0000 0080h".
  const std::string text = var2000("0x0007", "DefaultValue=0000 0080h\nLowLimit=0180h\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "0x00000080");
  EXPECT_EQ(r.device->sub(0x2000, 0)->low_limit, "0x0180");
  EXPECT_TRUE(has_diag(r, line_of(text, "LowLimit=0180h"), Severity::Warning,
                       {"[2000] LowLimit \"0180h\"", "read as 0x0180"}));
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "LowLimit=0180h"),
                       Severity::Error, {"'h'-suffix"}));
}

TEST(DeviceReader, HSuffixOnAttributeKeysIsReadWithAWarning) {
  const std::string text =
      eds("[2000]\nParameterName=x\nObjectType=07h\nDataType=0005h\n"
          "AccessType=rw\n",
          {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2000, 0)->data_type, 0x0005);
  EXPECT_TRUE(has_diag(r, line_of(text, "DataType=0005h"), Severity::Warning,
                       {"[2000] DataType \"0005h\"", "read as 0x5"}));
}

TEST(DeviceReader, EmptyValueOfANumberTypeIsNotGivenAndOnlyStrictModeReportsIt) {
  // CANopenEditor writes "ParameterValue=" for every entry that has none.
  const std::string text = var2000("0x0007", "DefaultValue=5\nParameterValue=\nLowLimit=\n");
  auto r = parse(text);
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_FALSE(s->parameter_value);
  EXPECT_FALSE(s->low_limit);
  EXPECT_EQ(s->configured_value(), "5");
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "ParameterValue="),
                       Severity::Error, {"[2000] ParameterValue is empty"}));
}

TEST(DeviceReader, EmptyValueOfAStringTypeIsTheEmptyString) {
  auto r = parse(var2000("0x0009", "DefaultValue=\n"), ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->sub(0x2000, 0)->default_value, "");
}

TEST(DeviceReader, DefaultValueOutsideLowAndHighLimitIsWarned) {
  const std::string text = var2000("0x0003",
                                   "LowLimit=-10\nHighLimit=10\nDefaultValue=11\n"
                                   "ParameterValue=-11\n");
  auto r = parse(text);
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=11"), Severity::Warning,
                       {"[2000] DefaultValue \"11\" is above HighLimit \"10\""}));
  EXPECT_TRUE(has_diag(r, line_of(text, "ParameterValue=-11"), Severity::Warning,
                       {"[2000] ParameterValue \"-11\" is below LowLimit \"-10\""}));
  EXPECT_TRUE(clean(parse(var2000("0x0003", "LowLimit=-10\nHighLimit=10\nDefaultValue=10\n"))));
}

TEST(DeviceReader, LowLimitAboveHighLimitIsWarned) {
  auto r = parse(var2000("0x0007", "LowLimit=0x20\nHighLimit=0x10\n"));
  EXPECT_TRUE(has_diag(r, 0, Severity::Warning, {"LowLimit \"0x20\" is above HighLimit \"0x10\""}));
}

TEST(DeviceReader, MissingParameterNameIsWarned) {
  const std::string text = eds("[2000]\nDataType=0x0005\nAccessType=rw\n", {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->object(0x2000)->name, "");
  EXPECT_TRUE(
      has_diag(r, line_of(text, "[2000]"), Severity::Warning, {"[2000] ParameterName is missing"}));
}

TEST(DeviceReader, MissingAccessTypeIsWarnedAndReadAsReadOnly) {
  const std::string text = eds("[2000]\nParameterName=x\nDataType=0x0005\n", {}, {0x2000});
  auto r = parse(text);
  EXPECT_EQ(r.device->sub(0x2000, 0)->access, AccessType::Ro);
  EXPECT_TRUE(has_diag(r, line_of(text, "[2000]"), Severity::Warning,
                       {"[2000] AccessType is missing; read as ro"}));
}

TEST(DeviceReader, MissingDataTypeOfAVarIsWarned) {
  const std::string text = eds("[2000]\nParameterName=x\nAccessType=rw\n", {}, {0x2000});
  EXPECT_TRUE(has_diag(parse(text), line_of(text, "[2000]"), Severity::Warning,
                       {"[2000] DataType is missing"}));
}

TEST(DeviceReader, DomainObjectWithoutDataTypeIsADomain) {
  // As lely reads it: the DataType of a DOMAIN object defaults to DOMAIN (000Fh).
  auto r =
      parse(eds("[2000]\nParameterName=Program\nObjectType=0x2\nAccessType=wo\n"
                "DownloadFile=program.bin\n",
                {}, {0x2000}));
  ASSERT_TRUE(clean(r));
  const SubObject* s = r.device->sub(0x2000, 0);
  EXPECT_EQ(r.device->object(0x2000)->object_type, ObjectType::Domain);
  EXPECT_EQ(s->basic_type(), DataType::Domain);
  EXPECT_EQ(s->download_file, "program.bin");
}

TEST(DeviceReader, AccessTypeIsCaseInsensitiveButStrictModeWantsLowerCase) {
  std::string text = var2000("0x0005", "");
  text.replace(text.find("AccessType=rw"), 13, "AccessType=RW");
  auto r = parse(text);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->sub(0x2000, 0)->access, AccessType::Rw);
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "AccessType=RW"),
                       Severity::Error, {"lower case"}));
}

TEST(DeviceReader, UnknownAccessTypeIsWarnedAndReadAsReadOnly) {
  std::string text = var2000("0x0005", "");
  text.replace(text.find("AccessType=rw"), 13, "AccessType=readwrite");
  auto r = parse(text);
  EXPECT_EQ(r.device->sub(0x2000, 0)->access, AccessType::Ro);
  EXPECT_TRUE(has_diag(r, line_of(text, "AccessType=readwrite"), Severity::Warning,
                       {"[2000] AccessType \"readwrite\" is not one of"}));
}

TEST(DeviceReader, ObjFlagsAreReadOnObjectsAndSubObjects) {
  auto r =
      parse(eds("[2000]\nParameterName=v\nDataType=0x0005\nAccessType=rw\nObjFlags=0x1\n"
                "[2001]\nParameterName=r\nObjectType=0x9\nSubNumber=1\nObjFlags=2\n"
                "[2001sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nObjFlags=3\n",
                {}, {0x2000, 0x2001}));
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->object(0x2000)->obj_flags, 1u);
  EXPECT_EQ(r.device->object(0x2001)->obj_flags, 2u);
  EXPECT_EQ(r.device->sub(0x2001, 0)->obj_flags, 3u);
}

TEST(DeviceReader, SubIndexFFIsReservedWarnedAndKept) {
  const std::string text =
      eds("[2000]\nParameterName=a\nObjectType=0x8\nSubNumber=2\n"
          "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\n"
          "[2000subFF]\nParameterName=last\nDataType=0x0005\nAccessType=rw\n",
          {}, {0x2000});
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  ASSERT_NE(r.device->sub(0x2000, 0xFF), nullptr);
  EXPECT_TRUE(
      has_diag(r, line_of(text, "[2000subFF]"), Severity::Warning, {"sub-index FFh is reserved"}));
}

TEST(DeviceReader, SubIndexAboveFFIsIgnoredWithAWarning) {
  const std::string text =
      eds("[2000]\nParameterName=a\nObjectType=0x8\nSubNumber=1\n"
          "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\n"
          "[2000sub100]\nParameterName=too far\nDataType=0x0005\nAccessType=rw\n",
          {}, {0x2000});
  auto r = parse(text);
  EXPECT_EQ(r.device->object(0x2000)->subs.size(), 1u);
  EXPECT_TRUE(has_diag(r, line_of(text, "[2000sub100]"), Severity::Warning,
                       {"larger than FFh; section ignored"}));
}

TEST(DeviceReader, SubNumberThatDisagreesWithTheSubSectionsIsWarned) {
  const std::string text =
      eds("[2000]\nParameterName=a\nObjectType=0x8\nSubNumber=3\n"
          "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\n"
          "[2000sub1]\nParameterName=e\nDataType=0x0005\nAccessType=rw\n",
          {}, {0x2000});
  auto r = parse(text);
  EXPECT_EQ(r.device->object(0x2000)->sub_number, 3);
  EXPECT_TRUE(has_diag(r, line_of(text, "SubNumber=3"), Severity::Warning,
                       {"[2000] SubNumber 3 but the file has 2 sub-object sections"}));
}

TEST(DeviceReader, ArrayWithoutSubNumberIsWarned) {
  const std::string text =
      eds("[2000]\nParameterName=a\nObjectType=0x8\n"
          "[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\n",
          {}, {0x2000});
  EXPECT_TRUE(has_diag(parse(text), line_of(text, "[2000]"), Severity::Warning,
                       {"[2000] ARRAY has no SubNumber"}));
}

TEST(DeviceReader, SubSectionsOfAVarAreIgnoredWithAWarning) {
  const std::string text =
      eds("[2000]\nParameterName=v\nDataType=0x0005\nAccessType=rw\n"
          "[2000sub1]\nParameterName=stray\nDataType=0x0005\nAccessType=rw\n",
          {}, {0x2000});
  auto r = parse(text);
  EXPECT_EQ(r.device->object(0x2000)->subs.size(), 1u);
  EXPECT_EQ(r.device->sub(0x2000, 0)->name, "v");
  EXPECT_TRUE(has_diag(r, line_of(text, "[2000sub1]"), Severity::Warning,
                       {"[2000] is a VAR: its sub-object sections are ignored"}));
}

TEST(DeviceReader, SubSectionWithoutItsObjectSectionIsIgnoredWithAWarning) {
  const std::string text =
      eds("[2000sub1]\nParameterName=orphan\nDataType=0x0005\nAccessType=rw\n");
  auto r = parse(text);
  EXPECT_EQ(r.device->object(0x2000), nullptr);
  EXPECT_TRUE(has_diag(r, line_of(text, "[2000sub1]"), Severity::Warning,
                       {"no [2000] section; they are ignored"}));
}

TEST(DeviceReader, UnknownObjectKeysGetOneNoteEachInTolerantMode) {
  const std::string text =
      eds("[2000]\nParameterName=v\nDataType=0x0005\nAccessType=rw\n"
          "StorageLocation=RAM\n"
          "[2001]\nParameterName=w\nDataType=0x0005\nAccessType=rw\n"
          "StorageLocation=ROM\n",
          {}, {0x2000, 0x2001});
  auto r = parse(text);
  ASSERT_EQ(r.diagnostics.size(), 1u) << r.diagnostics.format();
  EXPECT_TRUE(has_diag(r, line_of(text, "StorageLocation=RAM"), Severity::Note,
                       {"key StorageLocation is not a CiA 306 object key", "2 times"}));
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "StorageLocation=RAM"),
                       Severity::Error, {"StorageLocation"}));
}

// ---------------------------------------------------------------------------------------------
// CompactSubObj (CiA 306 §4.6.3.3; names as lely-core builds them)

const char* kCompact =
    "[1016]\n"
    "ParameterName=Consumer heartbeat time\n"
    "ObjectType=0x8\n"
    "DataType=0x0007\n"
    "AccessType=rw\n"
    "DefaultValue=0\n"
    "PDOMapping=0\n"
    "CompactSubObj=3\n";

TEST(DeviceReader, CompactSubObjExpandsToNrOfObjectsAndNumberedEntries) {
  auto r = parse(eds(kCompact, {0x1016}), ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  const Object* o = r.device->object(0x1016);
  EXPECT_EQ(o->compact_sub_obj, 3);
  ASSERT_EQ(o->subs.size(), 4u);
  const SubObject& n = o->subs.at(0);
  EXPECT_EQ(n.name, "NrOfObjects");
  EXPECT_EQ(n.basic_type(), DataType::Unsigned8);
  EXPECT_EQ(n.access, AccessType::Ro);
  EXPECT_EQ(n.default_value, "3");
  for (std::uint8_t i = 1; i <= 3; ++i) {
    const SubObject& s = o->subs.at(i);
    EXPECT_EQ(s.name, "Consumer heartbeat time" + std::to_string(i));
    EXPECT_EQ(s.basic_type(), DataType::Unsigned32);
    EXPECT_EQ(s.access, AccessType::Rw);
    EXPECT_EQ(s.default_value, "0");
  }
}

TEST(DeviceReader, CompactSubObjTakesNamesValuesAndDenotationsFromTheirSections) {
  const std::string text = eds(std::string(kCompact) +
                                   "[1016Name]\nNrOfEntries=2\n1=Heartbeat of node 2\n"
                                   "3=Heartbeat of node 4\n"
                                   "[1016Value]\nNrOfEntries=2\n1=0x000203E8\n2=$NODEID+0x10\n"
                                   "[1016Denotation]\nNrOfEntries=1\n2=Drive left\n",
                               {0x1016});
  auto r = parse(text);
  ASSERT_TRUE(clean(r));
  const Object* o = r.device->object(0x1016);
  EXPECT_EQ(o->sub(1)->name, "Heartbeat of node 2");
  EXPECT_EQ(o->sub(2)->name, "Consumer heartbeat time2");
  EXPECT_EQ(o->sub(3)->name, "Heartbeat of node 4");
  EXPECT_EQ(o->sub(1)->parameter_value, "0x000203E8");
  EXPECT_EQ(o->sub(2)->parameter_value, "$NODEID+0x10");
  EXPECT_FALSE(o->sub(3)->parameter_value);
  EXPECT_EQ(o->sub(2)->denotation, "Drive left");
}

TEST(DeviceReader, CompactValueIsCheckedAgainstTheTypeAndNrOfEntriesAgainstTheEntries) {
  const std::string text =
      eds(std::string(kCompact) + "[1016Value]\nNrOfEntries=2\n1=0x1FFFFFFFF\n", {0x1016});
  auto r = parse(text);
  EXPECT_TRUE(has_diag(r, line_of(text, "1=0x1FFFFFFFF"), Severity::Warning,
                       {"[1016Value] 1 \"0x1FFFFFFFF\" is not a valid UNSIGNED32"}));
  EXPECT_TRUE(has_diag(r, line_of(text, "NrOfEntries=2"), Severity::Warning,
                       {"[1016Value] NrOfEntries 2 but 1 entries"}));
}

TEST(DeviceReader, CompactValueForAMissingSubIndexIsWarned) {
  const std::string text =
      eds(std::string(kCompact) + "[1016Value]\nNrOfEntries=1\n9=5\n", {0x1016});
  EXPECT_TRUE(has_diag(parse(text), line_of(text, "9=5"), Severity::Warning,
                       {"[1016Value] sets sub-index 9", "does not have"}));
}

TEST(DeviceReader, ExplicitSubSectionReplacesTheExpandedCompactEntry) {
  const std::string text = eds(std::string(kCompact) +
                                   "[1016sub2]\nParameterName=special\nDataType=0x0007\n"
                                   "AccessType=ro\n",
                               {0x1016});
  auto r = parse(text);
  const Object* o = r.device->object(0x1016);
  ASSERT_EQ(o->subs.size(), 4u);
  EXPECT_EQ(o->sub(2)->name, "special");
  EXPECT_EQ(o->sub(2)->access, AccessType::Ro);
  EXPECT_TRUE(
      has_diag(r, line_of(text, "[1016sub2]"), Severity::Warning,
               {"[1016] uses CompactSubObj", "sub-index 02h", "replaces the expanded entry"}));
}

TEST(DeviceReader, CompactSubObjExpansionIsBudgetedAgainstTheFileSize) {
  // 300 objects of 254 sub-objects from ~20 KB of text: more than 65536 + size/8.
  std::string text = "[DeviceInfo]\nVendorName=x\n";
  for (int i = 0; i < 300; ++i) {
    text += "[" + hex4(static_cast<std::uint16_t>(0x2000 + i)) +
            "]\nParameterName=a\nObjectType=8\nDataType=5\nAccessType=ro\nCompactSubObj=254\n";
  }
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  std::size_t subs = 0;
  for (const auto& [index, obj] : r.device->objects) subs += obj.subs.size();
  EXPECT_LE(subs, 65536u + text.size() / 8 + 300u);
  EXPECT_GT(subs, 60000u);  // the budget is spent first
  EXPECT_TRUE(r.diagnostics.has_errors());
  EXPECT_TRUE(has_diag(r, 0, Severity::Error, {"CompactSubObj 254", "not expanded"}));
}

TEST(DeviceReader, ValueSectionOfAVarIsIgnoredWithAWarning) {
  const std::string text =
      eds("[2000]\nParameterName=v\nDataType=0x0005\nAccessType=rw\n"
          "[2000Value]\nNrOfEntries=1\n1=3\n",
          {}, {0x2000});
  EXPECT_TRUE(has_diag(parse(text), line_of(text, "[2000Value]"), Severity::Warning,
                       {"[2000Value] is for [2000], which is a VAR"}));
}

// ---------------------------------------------------------------------------------------------
// File-level sections

TEST(DeviceReader, ReadsDeviceComissioningInTheStandardsSpelling) {
  auto r = parse(eds("[DeviceComissioning]\nNodeID=0x05\nNodeName=Left drive\nBaudrate=500\n"
                     "NetNumber=1\nNetworkName=Line 1\nCANopenManager=1\n"
                     "LSS_SerialNumber=0x1234\nVendorKey=kept\n"),
                 ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  ASSERT_TRUE(r.device->commissioning);
  const DeviceCommissioning& c = *r.device->commissioning;
  EXPECT_EQ(r.device->node_id(), 5);
  EXPECT_EQ(c.node_name, "Left drive");
  EXPECT_EQ(c.baudrate_kbps, 500);
  EXPECT_EQ(c.net_number, 1u);
  EXPECT_EQ(c.network_name, "Line 1");
  EXPECT_EQ(c.canopen_manager, true);
  EXPECT_EQ(c.lss_serial_number, 0x1234u);
  EXPECT_EQ(*c.other.find("VendorKey"), "kept");
}

TEST(DeviceReader, AcceptsDeviceCommissioningSpelledCorrectlyExceptInStrictMode) {
  const std::string text = eds("[DeviceCommissioning]\nNodeID=3\n");
  auto r = parse(text);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(r.device->node_id(), 3);
  EXPECT_TRUE(has_diag(parse(text, ReadMode::Strict), line_of(text, "[DeviceCommissioning]"),
                       Severity::Error, {"[DeviceComissioning]"}));
}

TEST(DeviceReader, NodeIdOutside1To127IsWarnedAndNotUsed) {
  const std::string text = eds("[DeviceComissioning]\nNodeID=128\n");
  auto r = parse(text);
  EXPECT_FALSE(r.device->node_id());
  EXPECT_TRUE(
      has_diag(r, line_of(text, "NodeID=128"), Severity::Warning, {"NodeID 128 is not a node-ID"}));
}

TEST(DeviceReader, ReadsCommentsLinesInOrder) {
  auto r = parse(eds("[Comments]\nLines=2\nLine2=second ; not a comment\nLine1=first\n"),
                 ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  EXPECT_THAT(r.device->comments, ::testing::ElementsAre("first", "second ; not a comment"));
}

TEST(DeviceReader, CommentsLinesCountThatDisagreesIsWarned) {
  const std::string text = eds("[Comments]\nLines=3\nLine1=only\n");
  auto r = parse(text);
  EXPECT_EQ(r.device->comments.size(), 1u);
  EXPECT_TRUE(
      has_diag(r, line_of(text, "Lines=3"), Severity::Warning, {"[Comments] Lines 3 but 1 lines"}));
}

TEST(DeviceReader, ReadsDummyUsage) {
  auto r = parse(eds("[DummyUsage]\nDummy0001=0\nDummy0005=1\n"), ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  EXPECT_EQ(*r.device->dummy_usage.find("Dummy0005"), "1");
}

TEST(DeviceReader, ReadsObjectLinks) {
  auto r = parse(eds("[2000]\nParameterName=v\nDataType=0x0005\nAccessType=rw\n"
                     "[2000ObjectLinks]\nObjectLinks=2\n2=0x6001\n1=0x6000\n",
                     {}, {0x2000}),
                 ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  EXPECT_THAT(r.device->object(0x2000)->object_links, ::testing::ElementsAre(0x6000, 0x6001));
}

TEST(DeviceReader, KeepsUnknownSectionsInFileOrder) {
  // Modular devices (CiA 306 §5) and tools add sections the model does not interpret.
  auto r = parse(eds("[SupportedModules]\nNrOfEntries=1\n1=0x1\n[M1ModuleInfo]\nProductName=IO\n"
                     "[Tools]\nItems=0\n"),
                 ReadMode::Strict);
  ASSERT_TRUE(clean(r));
  const auto& o = r.device->other_sections;
  ASSERT_EQ(o.size(), 3u);
  EXPECT_EQ(o[0].name, "SupportedModules");
  EXPECT_EQ(*o[0].keys.find("1"), "0x1");
  EXPECT_EQ(o[1].name, "M1ModuleInfo");
  EXPECT_EQ(o[2].name, "Tools");
}

TEST(DeviceReader, MissingDeviceInfoIsWarnedAndMissingFileInfoIsStrictOnly) {
  auto r = parse("[1000]\nParameterName=a\nDataType=7\nAccessType=ro\n", ReadMode::Strict);
  EXPECT_TRUE(has_diag(r, 0, Severity::Error, {"no [FileInfo]"}));
  EXPECT_TRUE(has_diag(r, 0, Severity::Error, {"no [DeviceInfo]"}));
  auto t = parse("[1000]\nParameterName=a\nDataType=7\nAccessType=ro\n");
  EXPECT_EQ(find_diag(t, 0, {"no [FileInfo]"}), nullptr);
  EXPECT_TRUE(has_diag(t, 0, Severity::Warning, {"no [DeviceInfo]"}));
}

// ---------------------------------------------------------------------------------------------
// API

TEST(DeviceReader, ReadDeviceFileReportsAFileThatCannotBeOpened) {
  auto r = read_device_file("/nonexistent/dir/device.eds");
  EXPECT_FALSE(r.device);
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_THAT(r.diagnostics.items()[0].format(),
              HasSubstr("/nonexistent/dir/device.eds: error: cannot open the file"));
}

// Issue 33: a DCF saved at node 1 and edited to node 12 keeps node 1's pre-defined COB-IDs;
// the device at node 12 derives its own (CiA 301 §7.3.5): a warning at each ParameterValue.
TEST(DeviceReader, WarnsWhereANodeIdDerivedValueWasRecordedForAnotherNodeId) {
  const std::string path = std::string(CANOPEN_TEST_DATA_DIR) + "/network/nodes/saved_at_node1.dcf";
  const ReadResult r = read_device_file(path);
  ASSERT_TRUE(r.device.has_value()) << r.diagnostics.format();
  std::vector<std::string> found;
  for (const Diagnostic& d : r.diagnostics.items()) {
    if (d.severity == Severity::Warning && d.message.find("another node-ID") != std::string::npos) {
      found.push_back(std::to_string(d.line) + ": " + d.message.substr(0, d.message.find(':')));
    }
  }
  const auto line_of_value = [&](std::uint16_t index, std::uint8_t sub) {
    return r.device->sub(index, sub)->parameter_value_line;
  };
  EXPECT_EQ(found, (std::vector<std::string>{
                       std::to_string(line_of_value(0x1200, 1)) + ": 1200h sub 01h",
                       std::to_string(line_of_value(0x1200, 2)) + ": 1200h sub 02h",
                       std::to_string(line_of_value(0x1800, 1)) + ": 1800h sub 01h"}));
  EXPECT_THAT(r.diagnostics.format(),
              HasSubstr("ParameterValue 0x00000601 is DefaultValue $NODEID+0x600 for node-ID 1, "
                        "but NodeID is 12"));
  EXPECT_THAT(r.diagnostics.format(), HasSubstr("the device at node 12 derives 0x60C (CiA 301"));
}

// Which node-ID a file's $NODEID values were recorded at: the default SDO server's COB-IDs
// (1200h sub 1/2, fixed at 600h/580h + node-ID by CiA 301 §7.3.5) tell where the device was
// when its DCF was saved; a lone other value that is another node-ID's default (1014h = 0A4h,
// 80h + 36) is a deliberate setting: the device keeps it, and nothing warns.
TEST(DeviceReader, TheDefaultSdoServerTellsTheNodeIdAFileWasRecordedAt) {
  const std::string saved =
      std::string(CANOPEN_TEST_DATA_DIR) + "/network/nodes/saved_at_node1.dcf";
  const ReadResult r = read_device_file(saved);
  ASSERT_TRUE(r.device.has_value()) << r.diagnostics.format();
  EXPECT_EQ(recorded_node_id(*r.device), std::optional<std::uint8_t>(1));
  // Without 1200h's values, 1800h sub 1 = 181h alone is TPDO 1's COB-ID set on purpose.
  std::string text = test_support::read_text(saved);
  for (const char* line : {"ParameterValue=0x00000601\n", "ParameterValue=0x00000581\n"}) {
    const auto at = text.find(line);
    ASSERT_NE(at, std::string::npos);
    text.erase(at, std::string(line).size());
  }
  const ReadResult lone = parse(text);
  ASSERT_TRUE(lone.device.has_value()) << lone.diagnostics.format();
  EXPECT_EQ(recorded_node_id(*lone.device), std::optional<std::uint8_t>(12));
  EXPECT_THAT(lone.diagnostics.format(), Not(HasSubstr("another node-ID")));
  const auto entries = device_entries(*lone.device, 12);
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  EXPECT_EQ(find_entry(*entries, 0x1800, 1)->unsigned_value(), 0x181U);
  EXPECT_EQ(find_entry(*entries, 0x1200, 1)->unsigned_value(), 0x60CU);  // its default at 12
}

TEST(DeviceReader, AnEmcyCobIdMovedOnPurposeIsKept) {
  const ReadResult r =
      read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/emcy/nodes/python_node4.dcf");
  ASSERT_TRUE(r.device.has_value()) << r.diagnostics.format();
  EXPECT_EQ(recorded_node_id(*r.device), std::optional<std::uint8_t>(4));
  EXPECT_THAT(r.diagnostics.format(), Not(HasSubstr("another node-ID")));
  const auto entries = device_entries(*r.device, 4);
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  EXPECT_EQ(find_entry(*entries, 0x1014, 0)->unsigned_value(), 0xA4U);
}

TEST(DeviceReader, ReadDeviceFileUsesThePathInDiagnostics) {
  const std::string path = ::testing::TempDir() + "reader_test_file.eds";
  {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    const std::string text = var2000("0x0005", "DefaultValue=256\n");
    std::fwrite(text.data(), 1, text.size(), f);
    std::fclose(f);
  }
  auto r = read_device_file(path);
  std::remove(path.c_str());
  ASSERT_TRUE(r.device);
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_EQ(r.diagnostics.items()[0].file, path);
}

TEST(DeviceReader, CapsTheNumberOfDiagnosticsAndKeepsCountingErrors) {
  std::string text = eds("[2000]\n");
  for (int i = 0; i < 6000; ++i) text += "junk line\n";
  auto r = parse(text, ReadMode::Strict);
  ASSERT_TRUE(r.device);
  EXPECT_LE(r.diagnostics.size(), 5001u);
  EXPECT_TRUE(r.diagnostics.has_errors());
  EXPECT_THAT(r.diagnostics.items().back().message, HasSubstr("more diagnostics not shown"));
  EXPECT_EQ(r.diagnostics.items().back().severity, Severity::Error);
}

TEST(DeviceReader, DiagnosticsAreInLineOrderWithWholeFileMessagesLast) {
  auto r = parse("[1000]\nParameterName=a\nDataType=0x0005\nAccessType=xx\nDefaultValue=999\n");
  ASSERT_GE(r.diagnostics.size(), 3u);
  int previous = 1;
  for (const Diagnostic& d : r.diagnostics.items()) {
    const int line = d.line == 0 ? 1 << 30 : d.line;
    EXPECT_GE(line, previous);
    previous = line;
  }
}

}  // namespace
}  // namespace cfg
