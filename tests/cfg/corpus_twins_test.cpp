// Hand-written twins of the corpus spot checks (tests/cfg/corpus_test.cpp): each quirk a real
// vendor file shows, in a small text written here, so that the behaviour is tested in a fresh
// clone without ../shared. The comment of each test names the corpus test and file it mirrors;
// no text is copied from the corpus. Quirks whose twin already exists elsewhere are listed at the
// end of this file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <string_view>

#include "cfg/device_file.hpp"
#include "device_text_support.hpp"

namespace cfg {
namespace {

using test_support::line_of;

using ::testing::ElementsAre;

// [FileInfo], [DeviceInfo], [MandatoryObjects] and the mandatory objects; `extra` goes after them.
std::string device_file(std::string_view extra, std::string_view eds_version = "4.0") {
  return "[FileInfo]\nFileName=twin.eds\nFileVersion=1\nFileRevision=0\nEDSVersion=" +
         std::string(eds_version) +
         "\nDescription=corpus twin\nCreatedBy=tests\n\n"
         "[DeviceInfo]\nVendorName=Twin\nVendorNumber=0x00000001\nProductName=Twin\n"
         "ProductNumber=0x00000002\nRevisionNumber=0x00010000\nBaudRate_250=1\n"
         "SimpleBootUpSlave=1\nGranularity=8\nNrOfRXPDO=0\nNrOfTXPDO=0\nLSS_Supported=0\n\n"
         "[MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n\n"
         "[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
         "DefaultValue=0x00000000\nPDOMapping=0\n\n"
         "[1001]\nParameterName=Error register\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\n"
         "DefaultValue=0\nPDOMapping=0\n\n"
         "[1018]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=1\n\n"
         "[1018sub0]\nParameterName=Highest sub-index supported\nObjectType=0x7\n"
         "DataType=0x0005\nAccessType=ro\nDefaultValue=0\nPDOMapping=0\n\n" +
         std::string(extra);
}

ReadResult parse(std::string_view text, ReadMode mode = ReadMode::Tolerant) {
  return test_support::parse_text(text, mode, "twin.eds");
}

bool has_diag(const ReadResult& r, int line, std::initializer_list<std::string_view> parts) {
  return std::any_of(
      r.diagnostics.items().begin(), r.diagnostics.items().end(), [&](const Diagnostic& d) {
        return d.line == line && std::all_of(parts.begin(), parts.end(), [&](std::string_view p) {
                 return d.message.find(p) != std::string::npos;
               });
      });
}

// Twin of Corpus.KingPigeonNodeIdFormWithSpacesAndUpperCaseAccessType (m150c.dcf): CRLF lines,
// "$NodeID + 0x180" with blanks and mixed case, "AccessType=RW".
TEST(CorpusTwin, NodeIdFormWithBlanksAndUpperCaseAccessTypeInACrlfFile) {
  std::string text = device_file(
      "[1800]\nParameterName=TPDO1 communication\nObjectType=0x9\nSubNumber=2\n\n"
      "[1800sub0]\nParameterName=Highest sub-index\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=ro\nDefaultValue=1\nPDOMapping=0\n\n"
      "[1800sub1]\nParameterName=COB-ID\nObjectType=0x7\nDataType=0x0007\nAccessType=RW\n"
      "DefaultValue=$NodeID + 0x180\nPDOMapping=0\n");
  std::string crlf;
  for (char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  auto r = parse(crlf);
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x1800, 1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->default_value, "$NodeID + 0x180");
  EXPECT_EQ(s->access, AccessType::Rw);
  EXPECT_EQ(r.device->object(0x1800)->line, line_of(text, "[1800]"));
}

// Twin of Corpus.DcfgenMasterCompactPdoMappingRecordsAndUploadFile (pilz.dcf): lely's dcfgen
// writes PDO mapping RECORDs with CompactSubObj, and 1F22h sub-objects with UploadFile.
TEST(CorpusTwin, CompactPdoMappingRecordAndUploadFile) {
  const std::string text = device_file(
      "[1600]\nParameterName=RPDO1 mapping\nObjectType=0x9\nDataType=0x0007\nAccessType=rw\n"
      "PDOMapping=0\nCompactSubObj=2\n\n"
      "[1F22]\nParameterName=Concise DCF\nObjectType=0x8\nSubNumber=4\n\n"
      "[1F22sub0]\nParameterName=Highest sub-index\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=const\nDefaultValue=3\nPDOMapping=0\n\n"
      "[1F22sub3]\nParameterName=Node 3\nObjectType=0x7\nDataType=0x000F\nAccessType=rw\n"
      "PDOMapping=0\nUploadFile=joint_3.bin\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x1F22, 3)->upload_file, "joint_3.bin");
  const Object* mapping = r.device->object(0x1600);
  ASSERT_NE(mapping, nullptr);
  EXPECT_EQ(mapping->object_type, ObjectType::Record);
  EXPECT_EQ(mapping->compact_sub_obj, 2);
  ASSERT_EQ(mapping->subs.size(), 3u);
  EXPECT_EQ(mapping->sub(0)->name, "NrOfObjects");
  EXPECT_EQ(mapping->sub(2)->name, "RPDO1 mapping2");
  EXPECT_EQ(mapping->sub(2)->basic_type(), DataType::Unsigned32);
  // CiA 306 defines CompactSubObj for ARRAYs: only strict mode says so.
  auto strict = parse(text, ReadMode::Strict);
  EXPECT_TRUE(has_diag(strict, line_of(text, "CompactSubObj=2"), {"CompactSubObj on a RECORD"}));
}

// Twin of Corpus.CiaProfileHashCommentsAndHSuffixHex (CiA_profiles_301.eds): 'h'-suffix hex in
// digit groups, a text that only looks like one, and a comment after a section header.
TEST(CorpusTwin, HSuffixDigitGroupsAndCommentAfterASectionHeader) {
  const std::string text = device_file(
      "[1006]\nParameterName=Cycle period\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
      "DefaultValue=0000 0000h\nPDOMapping=0\n\n"
      "[1005]\nParameterName=COB-ID SYNC\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
      "DefaultValue=0000 0080h or 8000 0080h\nPDOMapping=0\n\n"
      "[1003]\nParameterName=Pre-defined error field\nObjectType=0x8\nSubNumber=2\n\n"
      "[1003sub0]\nParameterName=Number of errors\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=rw\nDefaultValue=0\nPDOMapping=0\n\n"
      "[1003sub01] # repeat up to 1003subFE\nParameterName=Standard error field\n"
      "ObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\nPDOMapping=0\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x1006, 0)->default_value, "0x00000000");
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=0000 0000h"), {"'h'-suffix hex"}));
  EXPECT_EQ(r.device->sub(0x1005, 0)->default_value, "0000 0080h or 8000 0080h");
  EXPECT_TRUE(has_diag(r, line_of(text, "DefaultValue=0000 0080h or"),
                       {"[1005] DefaultValue", "not a valid UNSIGNED32"}));
  EXPECT_TRUE(has_diag(r, line_of(text, "[1003sub01]"), {"text after the section name"}));
  EXPECT_NE(r.device->sub(0x1003, 1), nullptr);
}

// Twin of Corpus.SupportedObjectsThatDisagreeWithTheListsAreReported (test_zipped_format.eds):
// a [DeviceInfo] text written as "" keeps its quotes (CiA 306 has no quoting).
TEST(CorpusTwin, QuotedEmptyDeviceInfoTextIsKeptAsWritten) {
  std::string text = device_file("");
  text.replace(text.find("VendorName=Twin"), 15, "VendorName=\"\"");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(*r.device->device_info.find("VendorName"), "\"\"");
}

// Twin of Corpus.SensorCompactSubObj255UsesSubIndicesUpToFE (sensor.eds): CompactSubObj=255
// would need the reserved sub-index FFh; 254 entries are made, with a warning.
TEST(CorpusTwin, CompactSubObj255MakesSubIndicesUpToFE) {
  const std::string text = device_file(
      "[1003]\nParameterName=Error field\nObjectType=0x8\nDataType=0x0007\nAccessType=ro\n"
      "PDOMapping=0\nCompactSubObj=255\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const Object* o = r.device->object(0x1003);
  ASSERT_NE(o, nullptr);
  EXPECT_EQ(o->subs.size(), 255u);  // sub-index 0 and 1..FEh
  EXPECT_NE(o->sub(0xFE), nullptr);
  EXPECT_EQ(o->sub(0xFF), nullptr);
  EXPECT_TRUE(has_diag(r, line_of(text, "CompactSubObj=255"), {"CompactSubObj 255"}));
}

// Twin of Corpus.AutoconfTemplateKeepsItsPlaceholders (co-nmt-master.dcf.in): a file name with
// an autoconf placeholder is text, kept as written.
TEST(CorpusTwin, FileNameWithAPlaceholderIsKeptAsWritten) {
  const std::string text = device_file(
      "[1F20]\nParameterName=Store DCF\nObjectType=0x8\nSubNumber=2\n\n"
      "[1F20sub0]\nParameterName=Highest sub-index\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=const\nDefaultValue=1\nPDOMapping=0\n\n"
      "[1F20sub1]\nParameterName=Node 1\nObjectType=0x7\nDataType=0x000F\nAccessType=rw\n"
      "PDOMapping=0\nUploadFile=@top_srcdir@/node1.dcf\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x1F20, 1)->upload_file, "@top_srcdir@/node1.dcf");
}

// Twin of Corpus.LeadingBlankLineAndBannerComments (IO_legacy_v1.eds, emecdrv5_rev09.eds): a
// blank first line and a banner of ';' comments before [FileInfo].
TEST(CorpusTwin, LeadingBlankLineAndBannerComments) {
  const std::string text =
      "\n;*****************************\n; Twin device, EDS\n;*****************************\n\n" +
      device_file("");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_TRUE(r.diagnostics.empty()) << r.diagnostics.format();
  EXPECT_EQ(*r.device->file_info.find("FileName"), "twin.eds");
  EXPECT_NE(r.device->object(0x1000), nullptr);
}

// Twin of Corpus.BogusEdsVersionsAreKeptAsText (IoX1_16DI_8DO.eds, ZeroErrDriver.eds).
TEST(CorpusTwin, EdsVersionThatIsNoVersionIsKeptAsText) {
  for (std::string_view version : {"404", "1.5"}) {
    auto r = parse(device_file("", version));
    ASSERT_TRUE(r.device);
    EXPECT_EQ(*r.device->file_info.find("EDSVersion"), version);
  }
}

// Twin of Corpus.LargestDcfHasAllItsObjectsAndSubObjects (oresat/c3.dcf): a COB-ID formula with
// the node-ID last and an empty ParameterValue (not given, CANopenEditor's way).
TEST(CorpusTwin, FormulaWithNodeIdLastAndEmptyParameterValue) {
  const std::string text = device_file(
      "[1800]\nParameterName=TPDO1 communication\nObjectType=0x9\nSubNumber=2\n\n"
      "[1800sub0]\nParameterName=Highest sub-index\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=ro\nDefaultValue=1\nPDOMapping=0\n\n"
      "[1800sub1]\nParameterName=COB-ID used by TPDO\nObjectType=0x7\nDataType=0x0007\n"
      "AccessType=rw\nDefaultValue=0xC0000180+$NODEID\nPDOMapping=0\nParameterValue=\n"
      "Denotation=\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x1800, 1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->default_value, "0xC0000180+$NODEID");
  EXPECT_FALSE(s->parameter_value);
  EXPECT_FALSE(s->denotation);
  EXPECT_EQ(s->line, line_of(text, "[1800sub1]"));
}

// Twin of Corpus.PythonCanopenSampleNamesSectionsSubSpellingAndNodeIdForms (sample.eds):
// decimal addends on either side of $NODEID, a lower-case object section, "Sub" spelling.
TEST(CorpusTwin, DecimalNodeIdFormulasLowerCaseSectionAndSubSpelling) {
  const std::string text = device_file(
      "[1401]\nParameterName=RPDO2 communication\nObjectType=0x9\nSubNumber=2\n\n"
      "[1401sub0]\nParameterName=Highest sub-index\nObjectType=0x7\nDataType=0x0005\n"
      "AccessType=ro\nDefaultValue=1\nPDOMapping=0\n\n"
      "[1401Sub1]\nParameterName=COB-ID\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
      "DefaultValue=$NODEID+768\nPDOMapping=0\n\n"
      "[1a00]\nParameterName=TPDO1 mapping\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\n"
      "DefaultValue=1280+$NODEID\nPDOMapping=0\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x1401, 1)->default_value, "$NODEID+768");
  EXPECT_EQ(r.device->sub(0x1A00, 0)->default_value, "1280+$NODEID");
  for (const Diagnostic& d : r.diagnostics.items()) {
    EXPECT_NE(d.severity, Severity::Error) << d.format();
  }
}

// Twin of Corpus.MoreQuirksOfTheManifest (odrive master.dcf, demoDevice.eds, e35.eds,
// emsiso.eds, sample.eds, full_features.dcf): trailing blank of a name, a string with a tab and
// UTF-8, INTEGER64/REAL64 extremes without diagnostics, rww, [Comments] Lines=0, extra
// [FileInfo] keys, NodeID in hex, [xxxxDenotation], [xxxxObjectLinks] order.
TEST(CorpusTwin, MoreQuirksOfRealFiles) {
  std::string text = device_file(
      "[Comments]\nLines=0\n\n"
      "[2000]\nParameterName=motor_1: \nObjectType=0x7\nDataType=0x0009\nAccessType=rw\n"
      "DefaultValue=tab '\t' and euro '\xE2\x82\xAC', kept\nPDOMapping=0\n\n"
      "[2001]\nParameterName=I64\nObjectType=0x7\nDataType=0x0015\nAccessType=rw\n"
      "DefaultValue=-1234567890123456789\nPDOMapping=0\n\n"
      "[2002]\nParameterName=R64\nObjectType=0x7\nDataType=0x0011\nAccessType=rww\n"
      "DefaultValue=456.789\nPDOMapping=1\n\n"
      "[2003]\nParameterName=Sets\nObjectType=0x8\nDataType=0x0005\nAccessType=rw\n"
      "PDOMapping=0\nCompactSubObj=2\n\n"
      "[2003Denotation]\nNrOfEntries=2\n1=Config A\n2=Config B\n\n"
      "[2003ObjectLinks]\nObjectLinks=2\n2=0x1000\n1=0x2001\n\n"
      "[DeviceComissioning]\nNodeID=0x10\nNodeName=Some name\nBaudrate=500\n");
  text.replace(text.find("CreatedBy=tests\n"), 16,
               "CreatedBy=tests\nCreationTime=13:37PM\nLastEDS=x.dcf\n");
  auto r = parse(text);
  ASSERT_TRUE(r.device);
  const DeviceDescription& d = *r.device;
  EXPECT_EQ(d.sub(0x2000, 0)->name, "motor_1:");
  EXPECT_EQ(d.sub(0x2000, 0)->default_value, "tab '\t' and euro '\xE2\x82\xAC', kept");
  EXPECT_EQ(d.sub(0x2001, 0)->default_value, "-1234567890123456789");
  EXPECT_EQ(d.sub(0x2002, 0)->default_value, "456.789");
  EXPECT_EQ(d.sub(0x2002, 0)->access, AccessType::Rww);
  for (const char* key : {"[2001]", "[2002]"}) {
    const int first = line_of(text, key);
    for (const Diagnostic& diagnostic : r.diagnostics.items()) {
      EXPECT_FALSE(diagnostic.line >= first && diagnostic.line < first + 7) << diagnostic.format();
    }
  }
  EXPECT_TRUE(d.comments.empty());
  EXPECT_EQ(*d.file_info.find("CreationTime"), "13:37PM");
  EXPECT_EQ(*d.file_info.find("LastEDS"), "x.dcf");
  EXPECT_EQ(d.node_id(), 0x10);
  EXPECT_EQ(d.commissioning->node_name, "Some name");
  EXPECT_EQ(d.commissioning->baudrate_kbps, 500);
  EXPECT_EQ(d.sub(0x2003, 2)->denotation, "Config B");
  // CiA 306 §4.6.4: the links in the order of their entry numbers.
  EXPECT_THAT(d.object(0x2003)->object_links, ElementsAre(0x2001, 0x1000));
}

// Corpus spot checks whose twins were already here before this file (tests/cfg/...):
// - StrictModeFindsDeviationsInHandWrittenProfiles: device_reader_test
//   NumberFollowedByCommentIsAnErrorInStrictMode, HashInlineCommentsOnAttributeKeysAsIn...
// - LelyCompactSubObjWithValueSectionIsExpanded: CompactSubObjTakesNamesValuesAndDenotations...
// - DuplicateSectionsOfCia401AreReportedWithTheirLines: DuplicateSectionIsMergedAndTheLater...
// - FileWithoutFinalNewlineKeepsItsLastKey: ReadsAFileWithoutFinalLineEnd
// - LowerCaseSubbIsSubIndexB: SubSectionSpellingsSubAndHexSubIndexInAnyCase
// - SubIndexFFIsKeptWithAWarning: SubIndexFFIsReservedWarnedAndKept
// - FullFeaturesFixtureLinksDenotationsAndFiles: ReadsObjectLinks, ObjFlagsAreReadOn...
// - ModularDeviceSectionsAreKept: KeepsUnknownSectionsInFileOrder
// - QuotedStringValueIsKeptAsWritten: vendor_values_test LelyDcfSpellingsOfStringsOctetsAndTimes
// - CrlfAndLfCopiesOfOneFileGiveTheSameModel: AcceptsCrlfLfAndLoneCrLineEndsInOneFile
// - CommentedOutKeysAreNotRead: SemicolonLinesAreComments
// - NonAsciiUtf8TextIsKeptByteForByte: KeepsUtf8AndLatin1BytesOfTextsAsTheyAre
// - SupportedObjects disagreement: SupportedObjectsThatDisagreeWithTheListIsWarnedAndTheListWins

}  // namespace
}  // namespace cfg
