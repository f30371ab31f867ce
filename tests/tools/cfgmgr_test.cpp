// cfgmgr end to end: `check` and `fmt` on samples/ and tests/data/check/ (files written for these
// tests; each says in its first lines what is wrong with it and where).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "prerequisite.hpp"
#include "test_paths.hpp"
#include "tool_test_support.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::data_path;
using tool_test::Json;
using tool_test::run;
using tool_test::ScratchDir;

std::vector<std::string> sample_files() {
  std::vector<std::string> files;
  const fs::path samples(CANOPEN_SAMPLES_DIR);
  if (!fs::exists(samples)) return files;
  for (const auto& e : fs::recursive_directory_iterator(samples)) {
    const auto ext = e.path().extension();
    if (ext == ".eds" || ext == ".dcf") files.push_back(e.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(Cfgmgr, HelpListsCommandsAndExitCodes) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"--help"}, dir.path());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("check"));
  EXPECT_THAT(r.out, HasSubstr("fmt"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  auto check_help = run("cfgmgr", {"check", "--help"}, dir.path());
  EXPECT_EQ(check_help.exit_code, 0);
  EXPECT_THAT(check_help.out, HasSubstr("Examples:"));
}

TEST(Cfgmgr, UsageErrorsExitWith2) {
  ScratchDir dir;
  EXPECT_EQ(run("cfgmgr", {}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("cfgmgr", {"no-such-command"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("cfgmgr", {"check"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("cfgmgr", {"fmt"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("cfgmgr", {"fmt", data_path("concise/node5.dcf"), "--eds", "--dcf"}, dir.path())
                .exit_code,
            2);
}

TEST(Cfgmgr, CheckAcceptsEverySample) {
  auto files = sample_files();
  if (files.empty()) PREREQUISITE_MISSING("no samples in ", CANOPEN_SAMPLES_DIR);
  ScratchDir dir;
  auto r = run(
      "cfgmgr",
      [&] {
        std::vector<std::string> args{"check"};
        args.insert(args.end(), files.begin(), files.end());
        return args;
      }(),
      dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, Not(HasSubstr("error:")));
  // One summary line per file on stdout.
  EXPECT_EQ(static_cast<std::size_t>(std::count(r.out.begin(), r.out.end(), '\n')), files.size());
}

TEST(Cfgmgr, CheckWarningIsNotAFailureUnlessStrict) {
  ScratchDir dir;
  const std::string file = data_path("check/bad_access_type.eds");
  auto tolerant = run("cfgmgr", {"check", file}, dir.path());
  EXPECT_EQ(tolerant.exit_code, 0) << tolerant.err;
  // Line 75 of the file: AccessType=bogus.
  EXPECT_THAT(tolerant.err, HasSubstr("bad_access_type.eds:75: warning: [2000] AccessType"));
  auto strict = run("cfgmgr", {"check", "--strict", file}, dir.path());
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_THAT(strict.err, HasSubstr("bad_access_type.eds:75: error: [2000] AccessType"));
}

TEST(Cfgmgr, CheckToleratesAPlaceholderDynamicChannelsSectionTheDeviceDoesNotUse) {
  // CiA DSP 302 §8.4: with DynamicChannelsSupported=0 the device uses no segment, so the
  // placeholder a vendor tool wrote (Type1=0x0000 at line 83, Range1=0x0000-0x0000 at 85)
  // configures nothing: the file loads (exit 0) with warnings; --strict makes them errors.
  ScratchDir dir;
  const std::string file = data_path("check/dynamic_placeholder.eds");
  auto tolerant = run("cfgmgr", {"check", file}, dir.path());
  EXPECT_EQ(tolerant.exit_code, 0) << tolerant.err;
  EXPECT_THAT(tolerant.err, HasSubstr("dynamic_placeholder.eds:83: warning: [DynamicChannels] "));
  EXPECT_THAT(tolerant.err, HasSubstr("dynamic_placeholder.eds:85: warning: [DynamicChannels] "));
  EXPECT_THAT(tolerant.err, Not(HasSubstr("error")));
  auto strict = run("cfgmgr", {"check", "--strict", file}, dir.path());
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_THAT(strict.err, HasSubstr("dynamic_placeholder.eds:83: error: [DynamicChannels] "));
  EXPECT_THAT(strict.err, HasSubstr("dynamic_placeholder.eds:85: error: [DynamicChannels] "));
}

TEST(Cfgmgr, CheckComparesWithTheCiA301Schema) {
  ScratchDir dir;
  // schema_mismatch.eds declares 1017h UNSIGNED32; CiA 301 defines UNSIGNED16.
  const std::string file = data_path("check/schema_mismatch.eds");
  auto r = run("cfgmgr", {"check", file}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("schema_mismatch.eds:71: warning: 1017h"));
  EXPECT_THAT(r.err, HasSubstr("UNSIGNED16"));
  EXPECT_EQ(run("cfgmgr", {"check", "--strict", file}, dir.path()).exit_code, 1);
  auto without = run("cfgmgr", {"check", "--no-schema", "--strict", file}, dir.path());
  EXPECT_EQ(without.exit_code, 0) << without.err;
  EXPECT_EQ(without.err, "");
}

TEST(Cfgmgr, CheckReportsErrorsAndKeepsGoing) {
  ScratchDir dir;
  auto r =
      run("cfgmgr", {"check", data_path("check/not_a_device.eds"), data_path("concise/node5.dcf")},
          dir.path());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("not_a_device.eds: error:"));
  EXPECT_THAT(r.out, HasSubstr("node5.dcf: 0 errors"));
}

TEST(Cfgmgr, CheckMissingFileIsAnIoError) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"check", dir / "absent.eds", data_path("concise/node5.dcf")}, dir.path());
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("absent.eds"));
}

TEST(Cfgmgr, CheckJsonHasOneReportPerFile) {
  ScratchDir dir;
  auto r = run("cfgmgr",
               {"check", "--json", data_path("check/bad_access_type.eds"),
                data_path("check/not_a_device.eds")},
               dir.path());
  EXPECT_EQ(r.exit_code, 1);
  tool_test::JsonParser parser(r.out);
  auto json = parser.parse();
  ASSERT_TRUE(json.has_value()) << parser.error() << "\n" << r.out;
  EXPECT_FALSE(json->get("ok")->boolean);
  const auto& files = json->get("files")->array;
  ASSERT_EQ(files.size(), 2u);
  EXPECT_TRUE(files[0].get("ok")->boolean);
  EXPECT_EQ(files[0].get("errors")->number, 0);
  EXPECT_GE(files[0].get("warnings")->number, 1);
  EXPECT_EQ(files[0].get("objects")->number, 4);  // 1000h, 1001h, 1018h, 2000h
  const auto& diagnostic = files[0].get("diagnostics")->array.at(0);
  EXPECT_EQ(diagnostic.get("line")->number, 75);
  EXPECT_EQ(diagnostic.get("severity")->string, "warning");
  EXPECT_FALSE(files[1].get("ok")->boolean);
  EXPECT_GE(files[1].get("errors")->number, 1);
}

TEST(Cfgmgr, FmtWritesCanonicalCrlfThatReadsBack) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"fmt", data_path("concise/node5.dcf"), "-o", dir / "a.dcf"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string first = tool_test::slurp(dir / "a.dcf");
  EXPECT_THAT(first, HasSubstr("\r\n"));  // CiA 306 files are CRLF by convention
  EXPECT_THAT(first, HasSubstr("ParameterValue=1000"));
  EXPECT_EQ(run("cfgmgr", {"check", "--strict", dir / "a.dcf"}, dir.path()).exit_code, 0);
  // Canonical form is a fixed point.
  auto again = run("cfgmgr", {"fmt", dir / "a.dcf"}, dir.path());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(again.out, first);
}

TEST(Cfgmgr, FmtLfAndEds) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"fmt", data_path("concise/node5.dcf"), "--eds", "--lf"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, Not(HasSubstr("\r")));
  EXPECT_THAT(r.out, Not(HasSubstr("ParameterValue")));  // an EDS carries no configuration
  EXPECT_THAT(r.out, Not(HasSubstr("[DeviceComissioning]")));
  EXPECT_THAT(r.out, HasSubstr("[1017]"));
}

TEST(Cfgmgr, FmtInPlaceReplacesTheFile) {
  ScratchDir dir;
  fs::copy_file(data_path("concise/node5.dcf"), dir / "n.dcf");
  auto r = run("cfgmgr", {"fmt", "n.dcf", "-o", "n.dcf", "--lf"}, dir.path(), dir.path().string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(tool_test::slurp(dir / "n.dcf"), Not(HasSubstr("; Test DCF written")));
  for (const auto& name : dir.files()) EXPECT_THAT(name, Not(HasSubstr("tmp"))) << name;
}

// CiA 306 [FileInfo]: ModificationTime "hh:mm" + AM/PM, ModificationDate "mm-dd-yyyy". The time is
// taken from SOURCE_DATE_EPOCH; 1700000000 is 2023-11-14 22:13:20 UTC (date -u -d @1700000000).
TEST(Cfgmgr, FmtStampsFileInfoOnlyWhenItChangesTheFile) {
  ScratchDir dir;
  ::setenv("SOURCE_DATE_EPOCH", "1700000000", 1);
  auto r = run("cfgmgr", {"fmt", data_path("concise/node5.dcf"), "-o", dir / "a.dcf"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string first = tool_test::slurp(dir / "a.dcf");
  EXPECT_THAT(first, HasSubstr("ModifiedBy=cfgmgr\r\n"));
  EXPECT_THAT(first, HasSubstr("ModificationTime=10:13PM\r\n"));
  EXPECT_THAT(first, HasSubstr("ModificationDate=11-14-2023\r\n"));
  // Formatting the canonical file again changes nothing, not even the stamp.
  ::setenv("SOURCE_DATE_EPOCH", "1800000000", 1);
  auto again = run("cfgmgr", {"fmt", dir / "a.dcf"}, dir.path());
  ::unsetenv("SOURCE_DATE_EPOCH");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_EQ(again.out, first);
  // --no-stamp leaves [FileInfo] as the input has it.
  auto plain = run("cfgmgr", {"fmt", "--no-stamp", data_path("concise/node5.dcf")}, dir.path());
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_THAT(plain.out, Not(HasSubstr("ModifiedBy=cfgmgr")));
}

// fmt writes its output in pieces as it makes it: a write error on the way is reported (exit
// code 3), and an output file that is not complete never replaces the old one.
TEST(Cfgmgr, FmtReportsAWriteErrorAndLeavesNoTemporaryFile) {
  if (!fs::exists("/dev/full")) PREREQUISITE_MISSING("no /dev/full");
  ScratchDir dir;
  auto full = run("cfgmgr", {"fmt", data_path("concise/node5.dcf"), "-o", "/dev/full"}, dir.path());
  EXPECT_EQ(full.exit_code, 3);
  EXPECT_THAT(full.err, HasSubstr("/dev/full: error: write error"));
  // Into a directory that does not exist: nothing is created.
  auto absent =
      run("cfgmgr", {"fmt", data_path("concise/node5.dcf"), "-o", dir / "no/out.dcf"}, dir.path());
  EXPECT_EQ(absent.exit_code, 3);
  EXPECT_THAT(absent.err, HasSubstr("cannot create"));
  EXPECT_TRUE(fs::is_empty(dir.path()));
}

TEST(Cfgmgr, FmtDoesNotWriteAFileWithErrors) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"fmt", data_path("check/not_a_device.eds"), "-o", dir / "out.eds"},
               dir.path());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("not_a_device.eds: error:"));
  EXPECT_FALSE(fs::exists(dir / "out.eds"));
  EXPECT_EQ(run("cfgmgr", {"fmt", dir / "absent.eds"}, dir.path()).exit_code, 3);
  // The file is opened once; what goes wrong there decides the exit code (no check beforehand).
  fs::create_directories(dir / "a_directory");
  auto directory = run("cfgmgr", {"fmt", dir / "a_directory"}, dir.path());
  EXPECT_EQ(directory.exit_code, 3);
  EXPECT_THAT(directory.err, HasSubstr("a_directory: error: is a directory"));
  auto check = run("cfgmgr", {"check", dir / "a_directory"}, dir.path());
  EXPECT_EQ(check.exit_code, 3);
  EXPECT_THAT(check.err, HasSubstr("a_directory: error: is a directory"));
}

// The version comes from the top-level CMakeLists.txt's project(... VERSION x.y.z), read here
// independently of the tools' own compile definition.
std::string project_version() {
  const std::string text =
      tool_test::slurp(fs::path(CANOPEN_SAMPLES_DIR).parent_path() / "CMakeLists.txt");
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(R"(project\([^)]*VERSION\s+([0-9.]+))"))) return "";
  return m[1];
}

TEST(Cfgmgr, VersionPrintsNameAndProjectVersion) {
  ScratchDir dir;
  const std::string version = project_version();
  ASSERT_FALSE(version.empty());
  auto r = run("cfgmgr", {"--version"}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "cfgmgr " + version + "\n");
}

TEST(Cfgmgr, CheckSchemaDirThatCannotBeLoadedIsAnIoError) {
  ScratchDir dir;
  const std::string file = data_path("concise/node5.dcf");
  auto missing = run("cfgmgr", {"check", "--schema-dir", dir / "absent", file}, dir.path());
  EXPECT_EQ(missing.exit_code, 3);
  EXPECT_THAT(missing.err, HasSubstr("--schema-dir " + (dir / "absent")));
  EXPECT_EQ(missing.out, "");  // nothing was checked
  // A directory without the schema files.
  fs::create_directories(dir / "empty");
  auto empty = run("cfgmgr", {"check", "--schema-dir", dir / "empty", file}, dir.path());
  EXPECT_EQ(empty.exit_code, 3);
  EXPECT_THAT(empty.err, HasSubstr(dir / "empty"));
  EXPECT_THAT(empty.err, HasSubstr("cia301_communication"));
  // A file where the directory should be: found out by loading, not by a check beforehand.
  auto not_a_directory = run("cfgmgr", {"check", "--schema-dir", file, file}, dir.path());
  EXPECT_EQ(not_a_directory.exit_code, 3);
  EXPECT_THAT(not_a_directory.err, HasSubstr("--schema-dir " + file));
  EXPECT_EQ(not_a_directory.out, "");
  // The directory the project ships loads.
  auto shipped = run("cfgmgr", {"check", "--schema-dir", CANOPEN_SCHEMA_DIR, file}, dir.path());
  EXPECT_EQ(shipped.exit_code, 0) << shipped.err;
}

// CiA 306 §4.7 [DeviceComissioning]: a DCF is the configuration of one node and names it.
// no_node_id.dcf has no [DeviceComissioning] (tests/data/concise/README.md); section_only.dcf
// is node5.dcf with the section but without its NodeID line.
TEST(Cfgmgr, CheckWarnsWhenADcfHasNoNodeIdCiA306) {
  ScratchDir dir;
  const std::string file = data_path("concise/no_node_id.dcf");
  {
    std::string text = tool_test::slurp(data_path("concise/node5.dcf"));
    const auto at = text.find("NodeID=5");
    ASSERT_NE(at, std::string::npos);
    text.erase(at, text.find('\n', at) + 1 - at);
    std::ofstream(dir / "section_only.dcf", std::ios::binary) << text;
  }
  auto section_only = run("cfgmgr", {"check", dir / "section_only.dcf"}, dir.path());
  EXPECT_EQ(section_only.exit_code, 0) << section_only.err;
  EXPECT_THAT(section_only.err,
              HasSubstr("section_only.dcf: warning: a DCF should give the node-ID in "
                        "[DeviceComissioning] NodeID (CiA 306)"));
  EXPECT_THAT(tool_test::slurp(dir / "section_only.dcf"), HasSubstr("[DeviceComissioning]"));

  const std::string message =
      "no_node_id.dcf: warning: a DCF should give the node-ID in [DeviceComissioning] NodeID "
      "(CiA 306)";
  auto r = run("cfgmgr", {"check", file}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr(message));
  auto strict = run("cfgmgr", {"check", "--strict", file}, dir.path());
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_THAT(strict.err, HasSubstr("no_node_id.dcf: error: a DCF should give the node-ID"));
  // A DCF with NodeID=5, and an EDS (which has no commissioning), are not warned about.
  auto node5 = run("cfgmgr", {"check", data_path("concise/node5.dcf")}, dir.path());
  EXPECT_THAT(node5.err, Not(HasSubstr("should give the node-ID")));
  auto eds = run("cfgmgr", {"check", data_path("check/schema_mismatch.eds")}, dir.path());
  EXPECT_THAT(eds.err, Not(HasSubstr("should give the node-ID")));
}

TEST(Cfgmgr, CheckSummaryUsesSingularForOne) {
  ScratchDir dir;
  const std::string file = data_path("concise/no_node_id.dcf");
  // no_node_id.dcf: 9 objects in its object lists, and only the missing NodeID to warn about.
  auto r = run("cfgmgr", {"check", file}, dir.path());
  EXPECT_EQ(r.out, file + ": 0 errors, 1 warning, 9 objects\n") << r.err;
  auto strict = run("cfgmgr", {"check", "--strict", file}, dir.path());
  EXPECT_EQ(strict.out, file + ": 1 error, 0 warnings, 9 objects\n") << strict.err;
}

TEST(Cfgmgr, CheckReadsStdin) {
  ScratchDir dir;
  // node5.dcf lists 3 mandatory, 5 optional and 1 manufacturer object.
  auto r = run("cfgmgr", {"check", "-"}, dir.path(), "", data_path("concise/node5.dcf"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "<stdin>: 0 errors, 0 warnings, 9 objects\n");
  // Diagnostics name <stdin>: a DCF read from stdin has no extension, so only the reader speaks.
  auto bad = run("cfgmgr", {"check", "-"}, dir.path(), "", data_path("check/not_a_device.eds"));
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_THAT(bad.err, HasSubstr("<stdin>: error:"));
  // stdin can be read once only.
  auto twice = run("cfgmgr", {"check", "-", "-"}, dir.path(), "", data_path("concise/node5.dcf"));
  EXPECT_EQ(twice.exit_code, 2);
  EXPECT_THAT(twice.err, HasSubstr("stdin"));
}

// Vendor tools export DOMAIN/OCTET_STRING values as one 0x-prefixed run of hex digits
// (tests/data/concise/vendor_hex_domain.dcf, written for the tests). Such a DCF passes check,
// also strict, and fmt writes the values in its own form (digit pairs without a prefix).
TEST(Cfgmgr, CheckAndFmtAcceptHexPrefixedDomainValues) {
  ScratchDir dir;
  const std::string file = data_path("concise/vendor_hex_domain.dcf");
  auto r = run("cfgmgr", {"check", "--strict", file}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, file + ": 0 errors, 0 warnings, 6 objects\n");
  auto fmt = run("cfgmgr", {"fmt", file, "-o", dir / "out.dcf"}, dir.path());
  ASSERT_EQ(fmt.exit_code, 0) << fmt.err;
  const std::string written = tool_test::slurp(dir / "out.dcf");
  EXPECT_THAT(written,
              HasSubstr("ParameterValue=0400003700002401010000320000240101000001000024\r\n"));
  EXPECT_THAT(written, HasSubstr("ParameterValue=c0ffee01\r\n"));
  EXPECT_THAT(written, Not(HasSubstr("=0x0400")));
  EXPECT_EQ(run("cfgmgr", {"check", "--strict", dir / "out.dcf"}, dir.path()).exit_code, 0);
}

}  // namespace
