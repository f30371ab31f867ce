// The real-world corpus tier (../shared/corpus, see its README.md and MANIFEST.tsv): every
// EDS/DCF loads in tolerant mode or is rejected with a diagnostic naming the file, and the quirks
// the manifest lists are read as the spot checks below say. Expected values were read by hand
// from the files (line numbers with grep -n). Skipped when the corpus is absent.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "prerequisite.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kCorpus = CANOPEN_CORPUS_DIR;

#define REQUIRE_CORPUS()                                                          \
  if (!fs::is_directory(kCorpus)) {                                               \
    PREREQUISITE_MISSING("corpus not found at ", kCorpus, " (../shared/corpus)"); \
  }

std::vector<fs::path> device_files() {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(kCorpus)) {
    if (!e.is_regular_file()) continue;
    const std::string name = e.path().filename().string();
    auto ends_with = [&](std::string_view s) {
      return name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0;
    };
    if (ends_with(".eds") || ends_with(".dcf") || ends_with(".dcf.in")) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

ReadResult load(const std::string& relative, ReadMode mode = ReadMode::Tolerant) {
  ReadOptions options;
  options.mode = mode;
  return read_device_file((kCorpus / relative).string(), options);
}

const Diagnostic* find_diag(const ReadResult& r, int line, std::vector<std::string> parts) {
  for (const Diagnostic& d : r.diagnostics.items()) {
    if (d.line != line) continue;
    if (std::all_of(parts.begin(), parts.end(),
                    [&](const std::string& p) { return d.message.find(p) != std::string::npos; })) {
      return &d;
    }
  }
  return nullptr;
}

TEST(Corpus, EveryDeviceFileLoadsInTolerantModeOrIsRejectedWithADiagnostic) {
  REQUIRE_CORPUS();
  const auto files = device_files();
  ASSERT_GE(files.size(), 40u);
  for (const fs::path& path : files) {
    SCOPED_TRACE(path.string());
    auto r = read_device_file(path.string());
    if (path.filename() == "test_empty.eds") {
      // The 0-byte file: nothing to understand. Rejected, with the file named.
      EXPECT_FALSE(r.device);
      ASSERT_EQ(r.diagnostics.size(), 1u);
      EXPECT_EQ(r.diagnostics.items()[0].severity, Severity::Error);
      EXPECT_THAT(r.diagnostics.items()[0].format(),
                  HasSubstr(path.string() + ": error: the file is empty"));
      continue;
    }
    ASSERT_TRUE(r.device) << r.diagnostics.format();
    EXPECT_FALSE(r.diagnostics.has_errors()) << r.diagnostics.format();
    EXPECT_FALSE(r.device->objects.empty());
    for (const Diagnostic& d : r.diagnostics.items()) EXPECT_EQ(d.file, path.string());
  }
}

TEST(Corpus, EveryDeviceFileRoundTripsThroughTheWriter) {
  REQUIRE_CORPUS();
  for (const fs::path& path : device_files()) {
    auto r = read_device_file(path.string());
    if (!r.device) continue;
    for (FileKind kind : {FileKind::Dcf, FileKind::Eds}) {
      for (LineEnding ending : {LineEnding::Crlf, LineEnding::Lf}) {
        SCOPED_TRACE(path.string() + (kind == FileKind::Eds ? " as EDS" : " as DCF") +
                     (ending == LineEnding::Lf ? " LF" : " CRLF"));
        WriteOptions options;
        options.kind = kind;
        options.line_ending = ending;
        const std::string written = write_device_description(*r.device, options);
        auto back = parse_device_description(written);
        ASSERT_TRUE(back.device) << back.diagnostics.format();
        EXPECT_EQ(*back.device, canonical_form(*r.device, options));
        EXPECT_EQ(write_device_description(*back.device, options), written);
      }
    }
  }
}

TEST(Corpus, StrictModeFindsDeviationsInHandWrittenProfiles) {
  REQUIRE_CORPUS();
  auto r = load("cia-profiles-kacanopen/CiA_profiles_301.eds", ReadMode::Strict);
  ASSERT_TRUE(r.device);  // strict mode still gives the model
  EXPECT_FALSE(r.ok());
  // Line 3: "ObjectType=0x07 # VAR".
  const Diagnostic* d = find_diag(r, 3, {"[1000] ObjectType", "\"# VAR\"", "comment"});
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->severity, Severity::Error);
}

TEST(Corpus, LargestDcfHasAllItsObjectsAndSubObjects) {
  REQUIRE_CORPUS();
  // oresat/c3.dcf: 182 object sections and 1570 sub-object sections (grep -c), no duplicates.
  auto r = load("oresat/c3.dcf");
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->objects.size(), 182u);
  std::size_t subs = 0;
  for (const auto& [index, obj] : r.device->objects) {
    if (!obj.is_var()) subs += obj.subs.size();
  }
  EXPECT_EQ(subs, 1570u);
  // Lines 8735-8744: [1800sub1] DefaultValue=0xC0000180+$NODEID, "ParameterValue=" empty.
  const SubObject* s = r.device->sub(0x1800, 1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->name, "COB-ID used by TPDO");
  EXPECT_EQ(s->default_value, "0xC0000180+$NODEID");
  EXPECT_FALSE(s->parameter_value);
  EXPECT_FALSE(s->denotation);
  EXPECT_EQ(s->line, 8735);
}

TEST(Corpus, KingPigeonNodeIdFormWithSpacesAndUpperCaseAccessType) {
  REQUIRE_CORPUS();
  // m150c.dcf (CRLF): [1800sub1] "AccessType=RW", "DefaultValue=$NodeID + 0x180" (line 358).
  auto r = load("canopen-binding-kingpigeon/m150c.dcf");
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x1800, 1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->default_value, "$NodeID + 0x180");
  EXPECT_EQ(s->access, AccessType::Rw);
  EXPECT_EQ(r.device->object(0x1800)->line, 339);  // grep -n "^\[1800\]"
}

TEST(Corpus, LelyCompactSubObjWithValueSectionIsExpanded) {
  REQUIRE_CORPUS();
  // coapp-fiber-master.dcf: [1016] CompactSubObj=1, DataType=0x0007, AccessType=rw;
  // [1016Value] NrOfEntries=1, 1=0x007F0400.
  auto r = load("lely-core/coapp-fiber-master.dcf");
  ASSERT_TRUE(r.device);
  const Object* o = r.device->object(0x1016);
  ASSERT_NE(o, nullptr);
  EXPECT_EQ(o->object_type, ObjectType::Array);
  EXPECT_EQ(o->compact_sub_obj, 1);
  ASSERT_EQ(o->subs.size(), 2u);
  EXPECT_EQ(o->sub(0)->default_value, "1");
  EXPECT_EQ(o->sub(0)->basic_type(), DataType::Unsigned8);
  EXPECT_EQ(o->sub(1)->name, "Consumer heartbeat time1");
  EXPECT_EQ(o->sub(1)->basic_type(), DataType::Unsigned32);
  EXPECT_EQ(o->sub(1)->access, AccessType::Rw);
  EXPECT_EQ(o->sub(1)->parameter_value, "0x007F0400");
  // [1014] "DefaultValue=$NODEID+0x80" stays symbolic; objects without ObjectType are VARs.
  EXPECT_EQ(r.device->sub(0x1014, 0)->default_value, "$NODEID+0x80");
  EXPECT_EQ(r.device->object(0x1014)->object_type, ObjectType::Var);
}

TEST(Corpus, DcfgenMasterCompactPdoMappingRecordsAndUploadFile) {
  REQUIRE_CORPUS();
  // pilz.dcf: 1F22 sub 3 "UploadFile=prbt_joint_1.bin"; compact 1600h RECORD.
  auto r = load("ros_canopen-motion_controller_driver/pilz.dcf");
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x1F22, 3);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->upload_file, "prbt_joint_1.bin");
  ASSERT_TRUE(r.device->object(0x1600));
  EXPECT_TRUE(r.device->object(0x1600)->compact_sub_obj);
  EXPECT_EQ(r.device->object(0x1600)->sub(0)->name, "NrOfObjects");
  ASSERT_TRUE(r.device->commissioning);
}

TEST(Corpus, DuplicateSectionsOfCia401AreReportedWithTheirLines) {
  REQUIRE_CORPUS();
  // cia_401.eds: [1A03sub01] at line 569 and again at line 593; the second has
  // "ParameterName=" empty and "PDOMapping=1 # " (the later values win).
  auto r = load("cia-profiles-kacanopen/cia_401.eds");
  ASSERT_TRUE(r.device);
  const Diagnostic* d =
      find_diag(r, 593, {"[1A03sub01] appears a second time", "first at line 569"});
  ASSERT_NE(d, nullptr) << r.diagnostics.format();
  EXPECT_EQ(d->severity, Severity::Warning);
  const SubObject* s = r.device->sub(0x1A03, 1);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->name, "");
  EXPECT_TRUE(s->pdo_mapping);
  EXPECT_EQ(s->data_type, 0x0021);
  EXPECT_NE(find_diag(r, 3630, {"[642A] appears a second time", "first at line 2964"}), nullptr);
}

TEST(Corpus, CiaProfileHashCommentsAndHSuffixHex) {
  REQUIRE_CORPUS();
  auto r = load("cia-profiles-kacanopen/CiA_profiles_301.eds");
  ASSERT_TRUE(r.device);
  // Lines 1-8: [1000] "ObjectType=0x07 # VAR", "DataType=0x0007 # UNSIGNED32", "# Category:".
  EXPECT_EQ(r.device->object(0x1000)->object_type, ObjectType::Var);
  EXPECT_EQ(r.device->sub(0x1000, 0)->data_type, 0x0007);
  // [100C] "DefaultValue=0000h" (line 133) is read as 0x0000 with a warning.
  EXPECT_EQ(r.device->sub(0x100C, 0)->default_value, "0x0000");
  EXPECT_NE(find_diag(r, 133, {"[100C] DefaultValue \"0000h\"", "read as 0x0000"}), nullptr);
  // [1006] "DefaultValue=0000 0000h" (line 88): digit groups.
  EXPECT_EQ(r.device->sub(0x1006, 0)->default_value, "0x00000000");
  // [1005] "DefaultValue=0000 0080h or 8000 0080h" (line 79) is no UNSIGNED32: kept, warned.
  EXPECT_EQ(r.device->sub(0x1005, 0)->default_value, "0000 0080h or 8000 0080h");
  EXPECT_NE(find_diag(r, 79, {"[1005] DefaultValue", "not a valid UNSIGNED32"}), nullptr);
  // "[1003sub01] # repeat until 1003subFE" (line 41): the text after ']' is ignored.
  EXPECT_NE(find_diag(r, 41, {"[1003sub01]", "text after the section name"}), nullptr);
  EXPECT_NE(r.device->sub(0x1003, 1), nullptr);
}

TEST(Corpus, SupportedObjectsThatDisagreeWithTheListsAreReported) {
  REQUIRE_CORPUS();
  // test_zipped_format.eds line 52: SupportedObjects=3 with six entries (lines 53-58).
  auto r = load("gocanopen/test_zipped_format.eds");
  ASSERT_TRUE(r.device);
  EXPECT_NE(find_diag(r, 52, {"[MandatoryObjects] SupportedObjects 3 but 6"}), nullptr);
  for (int index : {0x1000, 0x1001, 0x1008, 0x1009, 0x100A, 0x1018}) {
    EXPECT_NE(r.device->object(static_cast<std::uint16_t>(index)), nullptr) << index;
  }
  // Line 15 "VendorName=\"\"": kept as written, quotes and all.
  EXPECT_EQ(*r.device->device_info.find("VendorName"), "\"\"");
  // e35.eds: [ManufacturerObjects] SupportedObjects=105 with 104 entries.
  auto e35 = load("python-canopen/e35.eds");
  ASSERT_TRUE(e35.device);
  EXPECT_NE(find_diag(e35, 116, {"SupportedObjects 105 but 104"}), nullptr);
}

TEST(Corpus, FileWithoutFinalNewlineKeepsItsLastKey) {
  REQUIRE_CORPUS();
  // test_zipped_format.eds ends in "[2101]...PDOMapping=0" without a line end.
  auto r = load("gocanopen/test_zipped_format.eds");
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x2101, 0);
  ASSERT_NE(s, nullptr);
  EXPECT_FALSE(s->pdo_mapping);
  EXPECT_EQ(s->access, AccessType::Rw);
}

TEST(Corpus, PythonCanopenSampleNamesSectionsSubSpellingAndNodeIdForms) {
  REQUIRE_CORPUS();
  auto r = load("python-canopen/sample.eds");
  ASSERT_TRUE(r.device);
  // [3004] CompactSubObj=3 with [3004Name] 1..3 = "Sensor Status 1".."3".
  const Object* o = r.device->object(0x3004);
  ASSERT_NE(o, nullptr);
  ASSERT_EQ(o->subs.size(), 4u);
  EXPECT_EQ(o->sub(2)->name, "Sensor Status 2");
  EXPECT_EQ(o->sub(2)->basic_type(), DataType::Unsigned16);
  // "[1a00]" lower-case section and "[3010Sub0]".
  EXPECT_NE(r.device->object(0x1A00), nullptr);
  EXPECT_NE(r.device->sub(0x3010, 0), nullptr);
  // "$NODEID+768" (line 248) and "1280+$NODEID" (line 314) stay symbolic.
  EXPECT_EQ(r.device->sub(0x1401, 1)->default_value, "$NODEID+768");
  EXPECT_EQ(r.device->sub(0x1403, 1)->default_value, "1280+$NODEID");
  ASSERT_TRUE(r.device->commissioning);
}

TEST(Corpus, SensorCompactSubObj255UsesSubIndicesUpToFE) {
  REQUIRE_CORPUS();
  // sensor.eds [1003] CompactSubObj=255 (line 126): FFh is reserved, 254 entries are made.
  auto r = load("python-canopen/sensor.eds");
  ASSERT_TRUE(r.device);
  const Object* o = r.device->object(0x1003);
  ASSERT_NE(o, nullptr);
  EXPECT_EQ(o->subs.size(), 255u);
  EXPECT_EQ(o->sub(0xFF), nullptr);
  EXPECT_NE(find_diag(r, 126, {"CompactSubObj 255"}), nullptr);
}

TEST(Corpus, LowerCaseSubbIsSubIndexB) {
  REQUIRE_CORPUS();
  // emsiso.eds line 176 "[3101subb]": ParameterName=MotorWireTemp, decimal DataType=8 (REAL32).
  auto r = load("emsiso/emsiso.eds");
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x3101, 0x0B);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->name, "MotorWireTemp");
  EXPECT_EQ(s->basic_type(), DataType::Real32);
  EXPECT_EQ(s->line, 176);
}

TEST(Corpus, SubIndexFFIsKeptWithAWarning) {
  REQUIRE_CORPUS();
  // max_subnumber.eds: [2000subFF] at line 37, SubNumber=0xFF with two sub sections.
  auto r = load("eds-dcf-net/max_subnumber.eds");
  ASSERT_TRUE(r.device);
  EXPECT_NE(r.device->sub(0x2000, 0xFF), nullptr);
  EXPECT_NE(find_diag(r, 37, {"sub-index FFh is reserved"}), nullptr);
  EXPECT_NE(find_diag(r, 27, {"SubNumber 255 but the file has 2"}), nullptr);
}

TEST(Corpus, FullFeaturesFixtureLinksDenotationsAndFiles) {
  REQUIRE_CORPUS();
  auto r = load("eds-dcf-net/full_features.dcf");
  ASSERT_TRUE(r.device);
  // [1018sub1] ParameterValue=0x00000200, Denotation=VendorIdentifier.
  EXPECT_EQ(r.device->sub(0x1018, 1)->parameter_value, "0x00000200");
  EXPECT_EQ(r.device->sub(0x1018, 1)->denotation, "VendorIdentifier");
  // [2100Value] 1=10, 2=20, 3=30.
  EXPECT_EQ(r.device->sub(0x2100, 3)->parameter_value, "30");
  bool links = false, upload = false, download = false, flags = false;
  for (const auto& [index, obj] : r.device->objects) {
    links = links || !obj.object_links.empty();
    flags = flags || obj.obj_flags.has_value();
    for (const auto& [sub, s] : obj.subs) {
      upload = upload || s.upload_file.has_value();
      download = download || s.download_file.has_value();
    }
  }
  EXPECT_TRUE(links);
  EXPECT_TRUE(upload);
  EXPECT_TRUE(download);
  EXPECT_TRUE(flags);
}

TEST(Corpus, ModularDeviceSectionsAreKept) {
  REQUIRE_CORPUS();
  auto r = load("eds-dcf-net/modular_device.dcf");
  ASSERT_TRUE(r.device);
  auto has = [&](std::string_view name) {
    return std::any_of(r.device->other_sections.begin(), r.device->other_sections.end(),
                       [&](const RawSection& s) { return s.name == name; });
  };
  EXPECT_TRUE(has("SupportedModules"));
  EXPECT_TRUE(has("M1ModuleInfo"));
}

TEST(Corpus, AutoconfTemplateKeepsItsPlaceholders) {
  REQUIRE_CORPUS();
  // co-nmt-master.dcf.in: 1F20 sub 2 "UploadFile=@srcdir@/co-nmt-slave.dcf".
  auto r = load("lely-core/co-nmt-master.dcf.in");
  ASSERT_TRUE(r.device);
  const SubObject* s = r.device->sub(0x1F20, 2);
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->upload_file, "@srcdir@/co-nmt-slave.dcf");
}

TEST(Corpus, QuotedStringValueIsKeptAsWritten) {
  REQUIRE_CORPUS();
  // co-sdev.dcf line 145 [2009] VISIBLE_STRING: ParameterValue="Hello, World!".
  auto r = load("lely-core/co-sdev.dcf");
  ASSERT_TRUE(r.device);
  EXPECT_EQ(r.device->sub(0x2009, 0)->parameter_value, "\"Hello, World!\"");
}

TEST(Corpus, CrlfAndLfCopiesOfOneFileGiveTheSameModel) {
  REQUIRE_CORPUS();
  auto lf = load("starnus-ros2_canopen-build/robot_control__cia402_slave.eds");
  auto crlf = load("starnus-ros2_canopen-build/robot_control__cia402_slave.CRLF-source.eds");
  ASSERT_TRUE(lf.device);
  ASSERT_TRUE(crlf.device);
  EXPECT_EQ(*lf.device, *crlf.device);
  EXPECT_EQ(lf.device->objects.size(), 189u);
}

TEST(Corpus, CommentedOutKeysAreNotRead) {
  REQUIRE_CORPUS();
  // DS301_profile.eds writes ";StorageLocation=..." under every object; no key is unknown.
  auto r = load("canopennode/DS301_profile.eds");
  ASSERT_TRUE(r.device);
  for (const Diagnostic& d : r.diagnostics.items()) {
    EXPECT_THAT(d.message, ::testing::Not(HasSubstr("StorageLocation")));
  }
}

TEST(Corpus, LeadingBlankLineAndBannerComments) {
  REQUIRE_CORPUS();
  // IO_legacy_v1.eds and emecdrv5_rev09.eds start with a blank line and ';' comments.
  for (const char* file : {"canopennode/IO_legacy_v1.eds", "emec/emecdrv5_rev09.eds"}) {
    auto r = load(file);
    ASSERT_TRUE(r.device) << file;
    EXPECT_FALSE(r.device->file_info.entries.empty()) << file;
    EXPECT_NE(r.device->object(0x1000), nullptr) << file;
  }
}

TEST(Corpus, NonAsciiUtf8TextIsKeptByteForByte) {
  REQUIRE_CORPUS();
  // demoDevice.eds has non-ASCII UTF-8 texts; every name is kept as the bytes of the file, so
  // the writer writes them back (round trip above) and nothing is mangled to '?'.
  auto r = load("canopennode/demoDevice.eds");
  ASSERT_TRUE(r.device);
  bool non_ascii = false;
  for (const auto& [index, obj] : r.device->objects) {
    for (const auto& [sub, s] : obj.subs) {
      for (char c : s.name) non_ascii = non_ascii || static_cast<unsigned char>(c) >= 0x80;
      for (char c : s.default_value.value_or("")) {
        non_ascii = non_ascii || static_cast<unsigned char>(c) >= 0x80;
      }
    }
  }
  EXPECT_TRUE(non_ascii);
}

TEST(Corpus, BogusEdsVersionsAreKeptAsText) {
  REQUIRE_CORPUS();
  // systec IoX1_16DI_8DO.eds: EDSVersion=404; zeroerr: EDSVersion=1.5.
  auto r = load("systec/IoX1_16DI_8DO.eds");
  ASSERT_TRUE(r.device);
  EXPECT_EQ(*r.device->file_info.find("EDSVersion"), "404");
}

TEST(Corpus, MoreQuirksOfTheManifest) {
  REQUIRE_CORPUS();
  // odrive master.dcf line 2256 "ParameterName=motor_1: " (trailing blank) in [2000sub1].
  auto odrive = load("odrive-cia402-profile/master.dcf");
  ASSERT_TRUE(odrive.device);
  EXPECT_EQ(odrive.device->sub(0x2000, 1)->name, "motor_1:");
  // demoDevice.eds line 2810: a VISIBLE_STRING with a tab and UTF-8 inside, kept whole;
  // lines 2732/2741/2759: INTEGER64 -1234567890123456789, UNSIGNED64 hex, REAL64 456.789.
  auto demo = load("canopennode/demoDevice.eds");
  ASSERT_TRUE(demo.device);
  EXPECT_EQ(demo.device->sub(0x2121, 2)->default_value,
            "Example string with 1000 bytes capacity. It may contain UTF-8 characters, like "
            "'\xE2\x82\xAC', tabs '\t', newlines, etc.");
  EXPECT_EQ(demo.device->sub(0x2120, 1)->default_value, "-1234567890123456789");
  EXPECT_EQ(demo.device->sub(0x2120, 4)->default_value, "456.789");
  for (int line : {2732, 2741, 2759}) {
    for (const Diagnostic& d : demo.diagnostics.items()) EXPECT_NE(d.line, line) << d.format();
  }
  // e35.eds line 3479: "AccessType=rww" in [2700sub1].
  auto e35 = load("python-canopen/e35.eds");
  ASSERT_TRUE(e35.device);
  EXPECT_EQ(e35.device->sub(0x2700, 1)->access, AccessType::Rww);
  // emsiso.eds: "[Comments] Lines=0"; extra [FileInfo] keys and the time "13:37PM" kept.
  auto emsiso = load("emsiso/emsiso.eds");
  ASSERT_TRUE(emsiso.device);
  EXPECT_TRUE(emsiso.device->comments.empty());
  EXPECT_EQ(*emsiso.device->file_info.find("LastEDS"), "dcf_used.dcf");
  EXPECT_EQ(*emsiso.device->file_info.find("CreationTime"), "13:37PM");
  // sample.eds lines 32-36: [DeviceComissioning] NodeID=0x10, NodeName=Some name, Baudrate=500.
  auto sample = load("python-canopen/sample.eds");
  ASSERT_TRUE(sample.device);
  EXPECT_EQ(sample.device->node_id(), 0x10);
  EXPECT_EQ(sample.device->commissioning->node_name, "Some name");
  EXPECT_EQ(sample.device->commissioning->baudrate_kbps, 500);
  // full_features.dcf: [2100Denotation] 1=Config A..3=Config C; [2000ObjectLinks] 0x2100, 0x1000.
  auto full = load("eds-dcf-net/full_features.dcf");
  ASSERT_TRUE(full.device);
  EXPECT_EQ(full.device->sub(0x2100, 2)->denotation, "Config B");
  EXPECT_THAT(full.device->object(0x2000)->object_links, ::testing::ElementsAre(0x2100, 0x1000));
  // ZeroErrDriver.eds line 306: "$NodeID+0x80" in [1014].
  auto zeroerr = load("zeroerr/ZeroErrDriver.eds");
  ASSERT_TRUE(zeroerr.device);
  EXPECT_EQ(zeroerr.device->sub(0x1014, 0)->default_value, "$NodeID+0x80");
}

}  // namespace
}  // namespace cfg
