// Standard object definitions (schemas/) and the check of device files against them.
// Expected definitions come from CiA 302-2 v4.1.0 §6 (spec/000_*.txt), CiA DSP 302 v3.2.1 §6/§10
// (spec/001_*.txt) and, for CiA 301 (not in spec/), its public descriptions.
#include "cfg/schema.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;

const DeviceDescription& cia301() {
  static const DeviceDescription schema = [] {
    auto r = load_schema(kCia301Schema, CANOPEN_SCHEMA_DIR);
    EXPECT_TRUE(r.ok()) << r.error().message;
    return r.ok() ? r.value() : DeviceDescription{};
  }();
  return schema;
}

const DeviceDescription& cia302() {
  static const DeviceDescription schema = [] {
    auto r = load_schema(kCia302ManagerSchema, CANOPEN_SCHEMA_DIR);
    EXPECT_TRUE(r.ok()) << r.error().message;
    return r.ok() ? r.value() : DeviceDescription{};
  }();
  return schema;
}

// A small EDS with the objects under test; the rest of the file is boilerplate.
// `list` is the object list the indices go in ("Optional" -> [OptionalObjects]).
DeviceDescription device(const std::string& list, std::vector<std::uint16_t> indices,
                         const std::string& objects) {
  std::string text =
      "[FileInfo]\nFileName=test.eds\nEDSVersion=4.0\n"
      "[DeviceInfo]\nVendorName=test\n[" +
      list + "Objects]\nSupportedObjects=" + std::to_string(indices.size()) + "\n";
  for (std::size_t i = 0; i < indices.size(); ++i) {
    char entry[32];
    std::snprintf(entry, sizeof entry, "%zu=0x%04X\n", i + 1, static_cast<unsigned>(indices[i]));
    text += entry;
  }
  text += objects;
  ReadResult r = parse_device_description(text, {ReadMode::Tolerant, "test.eds"});
  EXPECT_TRUE(r.device.has_value()) << r.diagnostics.format();
  EXPECT_FALSE(r.diagnostics.has_errors()) << r.diagnostics.format();
  return r.device.value_or(DeviceDescription{});
}

std::string var(const std::string& section, const std::string& type, const std::string& access) {
  return "[" + section + "]\nParameterName=x\nObjectType=0x7\nDataType=" + type +
         "\nAccessType=" + access + "\nPDOMapping=0\n";
}

Diagnostics check(const DeviceDescription& d, const DeviceDescription& schema) {
  Diagnostics out;
  check_against_schema(d, schema, "test.eds", out);
  return out;
}

TEST(Schema, Cia301SchemaLoadsStrictClean) {
  auto r = load_schema(kCia301Schema, CANOPEN_SCHEMA_DIR);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->objects.empty());
}

TEST(Schema, Cia302ManagerSchemaLoadsStrictClean) {
  auto r = load_schema(kCia302ManagerSchema, CANOPEN_SCHEMA_DIR);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->objects.empty());
}

// Sets an environment variable for one test (each test runs in its own process under ctest).
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() { ::unsetenv(name_); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
};

// The build tree has the installed layout (<bindir>/../share/canopen/schemas), which leads to
// the source tree's schemas/.
TEST(SchemaDir, FoundBesideTheProgramInTheBuildTree) {
  ::unsetenv("CANOPEN_SCHEMA_DIR");
  auto dir = find_schema_dir();
  ASSERT_TRUE(dir.ok()) << dir.error().message;
  EXPECT_TRUE(std::filesystem::equivalent(*dir, CANOPEN_SCHEMA_DIR)) << *dir;
  EXPECT_TRUE(load_schema(kCia301Schema).ok());
  EXPECT_TRUE(load_schemas().ok());
}

TEST(SchemaDir, EnvironmentVariableOverridesTheInstalledPlace) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "schema_env";
  std::filesystem::create_directories(dir);
  for (auto name : kStandardSchemas) {
    const std::string file = std::string(name) + ".eds";
    std::filesystem::copy_file(std::filesystem::path(CANOPEN_SCHEMA_DIR) / file, dir / file,
                               std::filesystem::copy_options::overwrite_existing);
  }
  ScopedEnv env("CANOPEN_SCHEMA_DIR", dir.string());
  auto found = find_schema_dir();
  ASSERT_TRUE(found.ok()) << found.error().message;
  EXPECT_EQ(*found, dir.string());
  std::filesystem::remove_all(dir);
}

TEST(SchemaDir, EnvironmentVariableWithoutSchemasIsAnErrorNotAFallback) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / "schema_none";
  std::filesystem::create_directories(dir);
  ScopedEnv env("CANOPEN_SCHEMA_DIR", dir.string());
  auto found = find_schema_dir();
  ASSERT_FALSE(found.ok());
  EXPECT_THAT(found.error().message, AllOf(HasSubstr(dir.string()), HasSubstr("CANOPEN_SCHEMA_DIR"),
                                           HasSubstr("cia301_communication.eds")));
  auto loaded = load_schema(kCia301Schema);
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.error().message, found.error().message);
  std::filesystem::remove_all(dir);
}

TEST(Schema, MissingSchemaIsAnError) {
  auto r = load_schema("no_such_schema", CANOPEN_SCHEMA_DIR);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("no_such_schema"));
}

TEST(Schema, Cia302ManagerObjectsAreAsTheSpecDefinesThem) {
  const auto& s = cia302();
  // CiA 302-2 §6.1 Table 6: 102Ah VAR UNSIGNED16.
  ASSERT_NE(s.object(0x102A), nullptr);
  EXPECT_EQ(s.object(0x102A)->object_type, ObjectType::Var);
  EXPECT_EQ(s.sub(0x102A, 0)->data_type, 0x0006);
  // §6.2 Table 17: 1F80h VAR UNSIGNED32.
  EXPECT_EQ(s.sub(0x1F80, 0)->data_type, 0x0007);
  // §6.3 Tables 26/27: 1F81h ARRAY of UNSIGNED32 rw, sub-index 0 const 7Fh.
  EXPECT_EQ(s.object(0x1F81)->object_type, ObjectType::Array);
  EXPECT_EQ(s.sub(0x1F81, 1)->data_type, 0x0007);
  EXPECT_EQ(s.sub(0x1F81, 1)->access, AccessType::Rw);
  EXPECT_EQ(s.sub(0x1F81, 0)->access, AccessType::Const);
  EXPECT_EQ(*s.sub(0x1F81, 0)->default_value, "0x7F");
  // §6.4 Table 30: 1F82h sub-index 80h (all nodes) is wo.
  EXPECT_EQ(s.sub(0x1F82, 0x80)->access, AccessType::Wo);
  EXPECT_EQ(s.sub(0x1F82, 1)->data_type, 0x0005);
  // DSP 302 §6.2 / §10: 1F22h ARRAY of DOMAIN; §6.4: 1F25h UNSIGNED32 with sub-index 80h.
  EXPECT_EQ(s.sub(0x1F22, 1)->data_type, 0x000F);
  EXPECT_EQ(s.sub(0x1F25, 0x80)->data_type, 0x0007);
  // §6.13 / §6.14: 1F90h has 6 UNSIGNED16 entries, 1F91h 3.
  EXPECT_EQ(s.object(0x1F90)->subs.size(), 7U);
  EXPECT_EQ(s.sub(0x1F91, 3)->data_type, 0x0006);
  for (std::uint16_t index = 0x1F20; index <= 0x1F27; ++index) {
    EXPECT_NE(s.object(index), nullptr) << std::hex << index;
  }
  for (std::uint16_t index = 0x1F80; index <= 0x1F8A; ++index) {
    EXPECT_NE(s.object(index), nullptr) << std::hex << index;
  }
}

TEST(Schema, SdoManagerObjectsAreAsDsp302_7_2_3DefinesThem) {
  const auto& s = cia302();
  // DSP 302 §7.2.3: 1F00h Request SDO and 1F01h Release SDO, VAR UNSIGNED32 wo.
  for (std::uint16_t index : {std::uint16_t{0x1F00}, std::uint16_t{0x1F01}}) {
    ASSERT_NE(s.object(index), nullptr) << std::hex << index;
    EXPECT_EQ(s.object(index)->object_type, ObjectType::Var);
    EXPECT_EQ(s.sub(index, 0)->data_type, 0x0007);
    EXPECT_EQ(s.sub(index, 0)->access, AccessType::Wo);
  }
  // 1F02h SDO manager COB-IDs: ARRAY of UNSIGNED32 rw.
  ASSERT_NE(s.object(0x1F02), nullptr);
  EXPECT_EQ(s.object(0x1F02)->object_type, ObjectType::Array);
  EXPECT_EQ(s.sub(0x1F02, 1)->data_type, 0x0007);
  EXPECT_EQ(s.sub(0x1F02, 1)->access, AccessType::Rw);
  // 1F03h-1F06h SDO connections parts 1-4: ARRAY of UNSIGNED32 ro, 254 entries each.
  for (std::uint16_t index = 0x1F03; index <= 0x1F06; ++index) {
    ASSERT_NE(s.object(index), nullptr) << std::hex << index;
    EXPECT_EQ(s.object(index)->object_type, ObjectType::Array);
    EXPECT_EQ(s.sub(index, 1)->data_type, 0x0007);
    EXPECT_EQ(s.sub(index, 1)->access, AccessType::Ro);
    EXPECT_EQ(*s.sub(index, 0)->default_value, "0xFE");
  }
  // SRD objects: 1F10h Dynamic SDO connection state VAR UNSIGNED32 rw; 1F11h Slave failed VAR
  // UNSIGNED16 wo.
  EXPECT_EQ(s.sub(0x1F10, 0)->data_type, 0x0007);
  EXPECT_EQ(s.sub(0x1F10, 0)->access, AccessType::Rw);
  EXPECT_EQ(s.sub(0x1F11, 0)->data_type, 0x0006);
  EXPECT_EQ(s.sub(0x1F11, 0)->access, AccessType::Wo);
  // §7.2.3 defines nothing at 1F07h-1F0Fh.
  for (std::uint16_t index = 0x1F07; index <= 0x1F0F; ++index) {
    EXPECT_EQ(s.object(index), nullptr) << std::hex << index;
  }
}

TEST(Schema, ReportsAReadableRequestSdoAndAnUnsigned32SlaveFailed) {
  // DSP 302 §7.2.3: 1F00h is wo, 1F11h UNSIGNED16.
  const auto d = device("Optional", {0x1F00, 0x1F11},
                        var("1F00", "0x0007", "rw") + var("1F11", "0x0007", "wo"));
  const Diagnostics diags = check(d, cia302());
  ASSERT_EQ(diags.size(), 2U) << diags.format();
  EXPECT_THAT(diags.format(), AllOf(HasSubstr("1F00h"), HasSubstr("1F11h")));
}

TEST(Schema, Cia301DefinesHeartbeatAndIdentity) {
  const auto& s = cia301();
  // CiA 301: 1017h producer heartbeat time VAR UNSIGNED16 rw; 1016h ARRAY UNSIGNED32.
  EXPECT_EQ(s.sub(0x1017, 0)->data_type, 0x0006);
  EXPECT_EQ(s.sub(0x1017, 0)->access, AccessType::Rw);
  EXPECT_EQ(s.sub(0x1016, 1)->data_type, 0x0007);
  // 1018h identity RECORD of four UNSIGNED32 ro entries.
  EXPECT_EQ(s.object(0x1018)->object_type, ObjectType::Record);
  for (std::uint8_t i = 1; i <= 4; ++i) EXPECT_EQ(s.sub(0x1018, i)->access, AccessType::Ro);
}

TEST(Schema, ReportsHeartbeatDeclaredUnsigned32) {
  const auto d = device("Optional", {0x1017}, var("1017", "0x0007", "rw"));
  const Diagnostics diags = check(d, cia301());
  ASSERT_EQ(diags.size(), 1U) << diags.format();
  const Diagnostic& w = diags.items()[0];
  EXPECT_EQ(w.severity, Severity::Warning);
  EXPECT_EQ(w.file, "test.eds");
  EXPECT_GT(w.line, 0);
  EXPECT_THAT(w.message,
              AllOf(HasSubstr("1017h"), HasSubstr("UNSIGNED32"), HasSubstr("UNSIGNED16")));
}

TEST(Schema, ReportsWritableIdentityEntry) {
  const auto d = device("Mandatory", {0x1018},
                        "[1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=2\n" +
                            var("1018sub0", "0x0005", "ro") + var("1018sub1", "0x0007", "rw"));
  const Diagnostics diags = check(d, cia301());
  ASSERT_EQ(diags.size(), 1U) << diags.format();
  EXPECT_THAT(diags.items()[0].message,
              AllOf(HasSubstr("1018h sub-index 01h"), HasSubstr("rw"), HasSubstr("ro")));
}

TEST(Schema, ReportsArrayWhereTheStandardHasARecord) {
  const auto d = device("Mandatory", {0x1018},
                        "[1018]\nParameterName=Identity\nObjectType=0x8\nSubNumber=2\n" +
                            var("1018sub0", "0x0005", "ro") + var("1018sub1", "0x0007", "ro"));
  const Diagnostics diags = check(d, cia301());
  ASSERT_EQ(diags.size(), 1U) << diags.format();
  EXPECT_THAT(diags.items()[0].message,
              AllOf(HasSubstr("1018h"), HasSubstr("ARRAY"), HasSubstr("RECORD")));
}

TEST(Schema, AcceptsAccessTheStandardAllowsToRestrict) {
  // CiA 302-2 §6.1 Table 7: 102Ah "rw; const, if rw is not supported"; §6.6 Table 35: 1F84h
  // entries "rw; wo, if rw is not supported". A ro 1017h (static heartbeat) is narrower too.
  const auto d = device("Optional", {0x102A, 0x1F84, 0x1017},
                        var("102A", "0x0006", "const") +
                            "[1F84]\nParameterName=x\nObjectType=0x8\nSubNumber=2\n" +
                            var("1F84sub0", "0x0005", "ro") + var("1F84sub1", "0x0007", "wo") +
                            var("1017", "0x0006", "ro"));
  EXPECT_TRUE(check(d, cia302()).empty()) << check(d, cia302()).format();
  EXPECT_TRUE(check(d, cia301()).empty()) << check(d, cia301()).format();
}

TEST(Schema, ChecksEveryPdoAgainstItsRangesDefinition) {
  // CiA 301: 1A03h is a TPDO mapping like 1A00h; its entries are UNSIGNED32.
  const auto d = device("Optional", {0x1A03},
                        "[1A03]\nParameterName=TPDO4 mapping\nObjectType=0x9\nSubNumber=2\n" +
                            var("1A03sub0", "0x0005", "rw") + var("1A03sub1", "0x0006", "rw"));
  const Diagnostics diags = check(d, cia301());
  ASSERT_EQ(diags.size(), 1U) << diags.format();
  EXPECT_THAT(diags.items()[0].message, AllOf(HasSubstr("1A03h sub-index 01h"),
                                              HasSubstr("UNSIGNED16"), HasSubstr("UNSIGNED32")));
}

TEST(Schema, ArrayElementOneStandsForEveryNode) {
  // CiA 302-2 §6.7: every 1F85h entry is UNSIGNED32; node 5 declared UNSIGNED16 is reported.
  const auto d = device("Optional", {0x1F85},
                        "[1F85]\nParameterName=x\nObjectType=0x8\nSubNumber=3\n" +
                            var("1F85sub0", "0x0005", "const") + var("1F85sub1", "0x0007", "rw") +
                            var("1F85sub5", "0x0006", "rw"));
  const Diagnostics diags = check(d, cia302());
  ASSERT_EQ(diags.size(), 1U) << diags.format();
  EXPECT_THAT(diags.items()[0].message, HasSubstr("1F85h sub-index 05h"));
}

TEST(Schema, ReportsARunOfLikeEntriesOnce) {
  // A per-node array declared with the wrong type would otherwise give 127 warnings.
  const auto d = device("Optional", {0x1F26},
                        "[1F26]\nParameterName=x\nObjectType=0x8\nSubNumber=4\n" +
                            var("1F26sub0", "0x0005", "ro") + var("1F26sub1", "0x0006", "rw") +
                            var("1F26sub2", "0x0006", "rw") + var("1F26sub3", "0x0006", "rw"));
  const Diagnostics diags = check(d, cia302());
  ASSERT_EQ(diags.size(), 1U) << diags.format();
  EXPECT_THAT(diags.items()[0].message,
              AllOf(HasSubstr("1F26h sub-indices 01h-03h"), HasSubstr("UNSIGNED16")));
}

TEST(Schema, IgnoresObjectsTheStandardDoesNotDefine) {
  const auto d = device("Manufacturer", {0x2000}, var("2000", "0x0007", "rw"));
  EXPECT_TRUE(check(d, cia301()).empty());
  EXPECT_TRUE(check(d, cia302()).empty());
}

TEST(Schema, LoadsAllStandardSchemasAsOne) {
  auto r = load_schemas(kStandardSchemas, CANOPEN_SCHEMA_DIR);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_NE(r->object(0x1017), nullptr);  // CiA 301
  EXPECT_NE(r->object(0x1F81), nullptr);  // CiA 302
  // Both files define 1018h; the union holds it once and checks a device once.
  const auto d = device("Optional", {0x1017}, var("1017", "0x0007", "rw"));
  EXPECT_EQ(check(d, *r).size(), 1U);
}

TEST(Schema, SchemasThatDisagreeOnAnObjectDoNotLoad) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) / "schema_test_disagree";
  std::filesystem::create_directories(dir);
  const std::filesystem::path original =
      std::filesystem::path(CANOPEN_SCHEMA_DIR) / "cia302_manager.eds";
  std::filesystem::copy_file(original, dir / "a.eds",
                             std::filesystem::copy_options::overwrite_existing);
  std::ifstream in(original, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // 1001h error register made UNSIGNED16 in the second file.
  const std::string from = "ParameterName=Error register\r\nObjectType=0x7\r\nDataType=0x0005";
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos);
  text.replace(at + from.size() - 1, 1, "6");
  std::ofstream(dir / "b.eds", std::ios::binary) << text;

  const std::array<std::string_view, 2> names{"a", "b"};
  auto r = load_schemas(names, dir.string());
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("1001h"));
  std::filesystem::remove_all(dir);
}

TEST(Schema, SamplesAgreeWithTheStandards) {
  auto loaded = load_schemas(kStandardSchemas, CANOPEN_SCHEMA_DIR);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const DeviceDescription& standards = loaded.value();
  const std::filesystem::path samples = CANOPEN_SAMPLES_DIR;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(samples)) {
    const auto ext = entry.path().extension();
    if (ext != ".eds" && ext != ".dcf") continue;
    SCOPED_TRACE(entry.path().string());
    ReadResult r = read_device_file(entry.path().string());
    ASSERT_TRUE(r.device.has_value()) << r.diagnostics.format();
    Diagnostics diags;
    check_against_schema(*r.device, standards, entry.path().string(), diags);
    EXPECT_TRUE(diags.empty()) << diags.format();
  }
}

}  // namespace
}  // namespace cfg
