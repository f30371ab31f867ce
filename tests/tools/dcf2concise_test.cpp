// dcf2concise end to end: the built binary on tests/data/concise/ (written for these tests),
// samples/network/ and the corpus. Expected entries come from the DCF text (values as written
// there) and the order from DSP 302 v3.2.1 §6.2; outputs are decoded back with libcfg.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "concise_test_support.hpp"
#include "prerequisite.hpp"
#include "test_paths.hpp"
#include "tool_test_support.hpp"

namespace {

namespace fs = std::filesystem;
using cfg::ObjectWrite;
using test_support::u16;
using test_support::u32;
using test_support::u8;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::data_path;
using tool_test::run;
using tool_test::ScratchDir;

std::vector<ObjectWrite> decode_file(const std::string& path) {
  auto entries = cfg::decode_concise_dcf(test_support::read_bytes(path));
  EXPECT_TRUE(entries.ok()) << path << ": " << entries.error().message;
  return entries.ok() ? *entries : std::vector<ObjectWrite>{};
}

std::vector<ObjectWrite> decode_string(const std::string& bytes) {
  std::vector<std::uint8_t> data(bytes.begin(), bytes.end());
  auto entries = cfg::decode_concise_dcf(data);
  EXPECT_TRUE(entries.ok()) << entries.error().message;
  return entries.ok() ? *entries : std::vector<ObjectWrite>{};
}

// node5.dcf (NodeID=5): 1017h ParameterValue=1000; RPDO1 with 1400h sub 2 = 1, COB-ID default
// $NODEID+0x200, mapping 2 entries; 1F50h sub 1 DownloadFile=node5_program.bin
// ("CANopen\0\xFF"). Not: 1000h/1001h/1018h (ro), 1010h (store command), 2000h (no value).
const ObjectWrite kProgram{0x1F50, 1, {'C', 'A', 'N', 'o', 'p', 'e', 'n', 0x00, 0xFF}};
std::vector<ObjectWrite> node5_writes(std::uint32_t cob_id = 0x205) {
  return {u16(0x1017, 0, 1000),
          u32(0x1400, 1, 0x80000000 | cob_id),
          u8(0x1400, 2, 1),
          u8(0x1600, 0, 0),
          u32(0x1600, 1, 0x20000008),
          u32(0x1600, 2, 0x60400010),
          u8(0x1600, 0, 2),
          u32(0x1400, 1, cob_id),
          kProgram};
}

// A copy of tests/data/concise/ in the scratch directory, for runs that write beside the input.
void copy_concise_data(const ScratchDir& dir) {
  for (const auto& e : fs::directory_iterator(data_path("concise"))) {
    fs::copy_file(e.path(), dir.path() / e.path().filename());
  }
}

TEST(Dcf2Concise, HelpDocumentsExitCodesAndExamples) {
  ScratchDir dir;
  auto r = run("dcf2concise", {"--help"}, dir.path());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  EXPECT_THAT(r.out, HasSubstr("2  usage error"));
  EXPECT_THAT(r.out, HasSubstr("Examples:"));
  EXPECT_THAT(r.out, HasSubstr("--decode"));
}

TEST(Dcf2Concise, UsageErrorsExitWith2) {
  ScratchDir dir;
  const std::string dcf = data_path("concise/node5.dcf");
  EXPECT_EQ(run("dcf2concise", {}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("dcf2concise", {dcf, "--node-id", "128"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("dcf2concise", {dcf, "--node-id", "0"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("dcf2concise", {dcf, "--changed-only", "--with-defaults"}, dir.path()).exit_code,
            2);
  EXPECT_EQ(run("dcf2concise", {"--decode", dcf, "--node-id", "3"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("dcf2concise", {dcf, "--dcf", dcf}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("dcf2concise", {dcf, "--json", "-o", "-"}, dir.path()).exit_code, 2);
  EXPECT_EQ(run("dcf2concise", {dcf, "--no-such-option"}, dir.path()).exit_code, 2);
  // stdin in, so stdout out by default: no room for --json.
  EXPECT_EQ(run("dcf2concise", {"-", "--json"}, dir.path(), "", dcf).exit_code, 2);
  // The default output (input with .bin) must not be the input itself.
  fs::copy_file(dcf, dir / "weird.bin");
  EXPECT_EQ(run("dcf2concise", {"weird.bin"}, dir.path(), dir.path().string()).exit_code, 2);
  EXPECT_EQ(tool_test::slurp(dir / "weird.bin"), tool_test::slurp(dcf));
  fs::remove(dir / "weird.bin");
  EXPECT_THAT(dir.files(), ::testing::IsEmpty());
}

TEST(Dcf2Concise, MissingInputIsAnIoError) {
  ScratchDir dir;
  auto r = run("dcf2concise", {dir / "absent.dcf", "-o", dir / "out.bin"}, dir.path());
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("absent.dcf"));
  EXPECT_FALSE(fs::exists(dir / "out.bin"));
}

// Each file is opened once and the error that arises says which kind it is (README: exit 3 when
// a file cannot be read or written, 1 when the input is wrong); no check runs beforehand.
TEST(Dcf2Concise, UnreadableFilesAreIoErrorsInEveryMode) {
  ScratchDir dir;
  fs::create_directories(dir / "a_directory");
  auto directory = run("dcf2concise", {dir / "a_directory", "-o", dir / "out.bin"}, dir.path());
  EXPECT_EQ(directory.exit_code, 3);
  EXPECT_THAT(directory.err, HasSubstr("a_directory: error: is a directory"));
  EXPECT_FALSE(fs::exists(dir / "out.bin"));
  // --decode: the stream, and the device file that names its entries.
  auto stream = run("dcf2concise", {"--decode", dir / "absent.bin"}, dir.path());
  EXPECT_EQ(stream.exit_code, 3);
  EXPECT_THAT(stream.err, HasSubstr("absent.bin: error: cannot open"));
  auto stream_dir = run("dcf2concise", {"--decode", dir / "a_directory"}, dir.path());
  EXPECT_EQ(stream_dir.exit_code, 3);
  EXPECT_THAT(stream_dir.err, HasSubstr("a_directory: error: read error"));
  auto device =
      run("dcf2concise",
          {"--decode", data_path("concise/heartbeat_1000.bin"), "--dcf", dir / "absent.eds"},
          dir.path());
  EXPECT_EQ(device.exit_code, 3);
  EXPECT_THAT(device.err, HasSubstr("absent.eds: error: cannot open"));
  // A device file that is there but wrong is an input error.
  auto wrong = run("dcf2concise",
                   {"--decode", data_path("concise/heartbeat_1000.bin"), "--dcf",
                    data_path("check/not_a_device.eds")},
                   dir.path());
  EXPECT_EQ(wrong.exit_code, 1);
}

TEST(Dcf2Concise, UnwritableOutputIsAnIoError) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", dir / "no/such/dir/out.bin"},
               dir.path());
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("out.bin"));
}

TEST(Dcf2Concise, ConvertsADcfInPdoSafeOrder) {
  ScratchDir dir;
  // Run from the scratch directory: DownloadFile must be found beside the DCF, not in the cwd.
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", dir / "node5.bin"}, dir.path(),
               dir.path().string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(decode_file(dir / "node5.bin"), node5_writes());
}

// Output to something that is not a regular file is written into, never replaced (a user who
// says `-o /dev/null` must still have /dev/null afterwards).
TEST(Dcf2Concise, OutputToADeviceWritesIntoItAndKeepsIt) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", "/dev/null"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

TEST(Dcf2Concise, OutputThroughASymlinkReplacesTheTargetAndKeepsTheLink) {
  ScratchDir dir;
  { std::ofstream(dir / "real.bin") << "old"; }
  fs::create_symlink(dir / "real.bin", dir / "link.bin");
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", dir / "link.bin"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(dir / "link.bin"));
  EXPECT_EQ(decode_file(dir / "real.bin"), node5_writes());
}

TEST(Dcf2Concise, OutputKeepsThePermissionsOfAnExistingFile) {
  ScratchDir dir;
  { std::ofstream(dir / "out.bin") << "old"; }
  fs::permissions(dir / "out.bin",
                  fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", dir / "out.bin"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(fs::status(dir / "out.bin").permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  EXPECT_EQ(decode_file(dir / "out.bin"), node5_writes());
}

TEST(Dcf2Concise, DefaultOutputIsTheInputWithExtensionBin) {
  ScratchDir dir;
  copy_concise_data(dir);
  auto r = run("dcf2concise", {"node5.dcf"}, dir.path(), dir.path().string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(decode_file(dir / "node5.bin"), node5_writes());
}

TEST(Dcf2Concise, DashWritesTheStreamToStdout) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", "-"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(decode_string(r.out), node5_writes());
}

TEST(Dcf2Concise, NodeIdOptionOverridesCommissioning) {
  ScratchDir dir;
  auto r =
      run("dcf2concise", {data_path("concise/node5.dcf"), "-o", "-", "--node-id", "9"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(decode_string(r.out), node5_writes(0x209));  // CiA 301: RPDO1 = 200h + node-ID
}

TEST(Dcf2Concise, ChangedOnlyKeepsValuesThatDifferFromDefaults) {
  ScratchDir dir;
  auto r =
      run("dcf2concise", {data_path("concise/node5.dcf"), "-o", "-", "--changed-only"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // 1600h sub 1 equals its DefaultValue and is left out; sub 0 (2, default 1) stays.
  EXPECT_THAT(decode_string(r.out),
              ElementsAre(u16(0x1017, 0, 1000), u32(0x1400, 1, 0x80000205), u8(0x1400, 2, 1),
                          u8(0x1600, 0, 0), u32(0x1600, 2, 0x60400010), u8(0x1600, 0, 2),
                          u32(0x1400, 1, 0x205), kProgram));
}

TEST(Dcf2Concise, WithDefaultsAddsWritableDefaults) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", "-", "--with-defaults"},
               dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto expected = node5_writes();
  expected.push_back(u8(0x2000, 0, 0));  // rww, DefaultValue=0
  EXPECT_EQ(decode_string(r.out), expected);
}

TEST(Dcf2Concise, ValueErrorIsReportedWithFileAndLineAndNoOutputIsLeft) {
  ScratchDir dir;
  copy_concise_data(dir);
  { std::ofstream(dir / "out.bin") << "old"; }
  auto r = run("dcf2concise", {"bad_value.dcf", "-o", "out.bin"}, dir.path(), dir.path().string());
  EXPECT_EQ(r.exit_code, 1);
  // Line 92 of bad_value.dcf is [1017]'s ParameterValue=70000, which does not fit UNSIGNED16
  // (0..65535): one error, at the key's line.
  EXPECT_THAT(r.err, HasSubstr("bad_value.dcf:92: error: [1017] ParameterValue \"70000\""));
  EXPECT_THAT(r.err, HasSubstr("out of range for UNSIGNED16"));
  EXPECT_EQ(tool_test::slurp(dir / "out.bin"), "old");  // untouched
  for (const auto& name : dir.files()) EXPECT_THAT(name, Not(HasSubstr("tmp"))) << name;
  EXPECT_FALSE(fs::exists(dir / "bad_value.bin"));
}

TEST(Dcf2Concise, MissingNodeIdIsAnError) {
  ScratchDir dir;
  auto r =
      run("dcf2concise", {data_path("concise/no_node_id.dcf"), "-o", dir / "out.bin"}, dir.path());
  EXPECT_EQ(r.exit_code, 1);
  // Line 130 is [1400sub1]'s DefaultValue=$NODEID+0x200 (the section starts at 125): the
  // message names the key's own line.
  EXPECT_THAT(r.err, HasSubstr("no_node_id.dcf:130: error: [1400sub1] DefaultValue"));
  EXPECT_THAT(r.err, HasSubstr("no node-ID"));
  EXPECT_THAT(r.err, HasSubstr("give one with --node-id N"));
  EXPECT_FALSE(fs::exists(dir / "out.bin"));
  // With a node-ID it converts.
  auto with_id =
      run("dcf2concise", {data_path("concise/no_node_id.dcf"), "-o", "-", "--node-id", "5"},
          dir.path());
  EXPECT_EQ(with_id.exit_code, 0) << with_id.err;
  EXPECT_EQ(decode_string(with_id.out), node5_writes());
}

TEST(Dcf2Concise, MissingDownloadFileIsAnError) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/missing_file.dcf"), "-o", dir / "out.bin"},
               dir.path());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("missing_file.dcf:192: error: [1F50sub1] DownloadFile"));
  EXPECT_FALSE(fs::exists(dir / "out.bin"));
}

TEST(Dcf2Concise, StrictMakesDeviationsErrors) {
  ScratchDir dir;
  copy_concise_data(dir);
  std::string text = tool_test::slurp(dir / "node5.dcf");
  // [2000] "AccessType=rww" -> "AccessType=RWW": CiA 306 writes access types in lower case.
  const auto at = text.find("AccessType=rww");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 14, "AccessType=RWW");
  std::ofstream(dir / "upper.dcf", std::ios::binary) << text;
  auto tolerant = run("dcf2concise", {"upper.dcf", "-o", "t.bin"}, dir.path(), dir.path().string());
  EXPECT_EQ(tolerant.exit_code, 0) << tolerant.err;
  auto strict =
      run("dcf2concise", {"upper.dcf", "-o", "s.bin", "--strict"}, dir.path(), dir.path().string());
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_TRUE(std::regex_search(strict.err, std::regex(R"(upper\.dcf:\d+: error: )")))
      << strict.err;
  EXPECT_FALSE(fs::exists(dir / "s.bin"));
}

TEST(Dcf2Concise, JsonSummaryHasEntriesAndDiagnostics) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/node5.dcf"), "-o", dir / "n.bin", "--json"},
               dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  tool_test::JsonParser parser(r.out);
  auto json = parser.parse();
  ASSERT_TRUE(json.has_value()) << parser.error() << "\n" << r.out;
  ASSERT_TRUE(json->is(tool_test::Json::Kind::Object));
  EXPECT_TRUE(json->get("ok")->boolean);
  EXPECT_EQ(json->get("output")->string, dir / "n.bin");
  EXPECT_EQ(json->get("size")->number, static_cast<double>(fs::file_size(dir / "n.bin")));
  const auto& entries = json->get("entries")->array;
  ASSERT_EQ(entries.size(), 9u);
  EXPECT_EQ(entries[0].get("index")->number, 0x1017);
  EXPECT_EQ(entries[0].get("index_hex")->string, "1017");
  EXPECT_EQ(entries[0].get("sub_index")->number, 0);
  EXPECT_EQ(entries[0].get("size")->number, 2);
  EXPECT_EQ(entries[0].get("data")->string, "e803");  // 1000, little-endian
  EXPECT_TRUE(json->get("diagnostics")->is(tool_test::Json::Kind::Array));
}

TEST(Dcf2Concise, JsonOnErrorSaysWhy) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/bad_value.dcf"), "-o", dir / "n.bin", "--json"},
               dir.path());
  EXPECT_EQ(r.exit_code, 1);
  tool_test::JsonParser parser(r.out);
  auto json = parser.parse();
  ASSERT_TRUE(json.has_value()) << parser.error() << "\n" << r.out;
  EXPECT_FALSE(json->get("ok")->boolean);
  EXPECT_TRUE(json->get("output")->is(tool_test::Json::Kind::Null));
  bool found = false;
  for (const auto& d : json->get("diagnostics")->array) {
    if (d.get("severity")->string == "error" && d.get("line")->number == 92) found = true;
  }
  EXPECT_TRUE(found) << r.out;
}

TEST(Dcf2Concise, DecodePrintsNamesAndValuesInWords) {
  ScratchDir dir;
  ASSERT_EQ(run("dcf2concise", {data_path("concise/node5.dcf"), "-o", dir / "n.bin"}, dir.path())
                .exit_code,
            0);
  auto r = run("dcf2concise", {"--decode", dir / "n.bin", "--dcf", data_path("concise/node5.dcf")},
               dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> lines;
  std::istringstream in(r.out);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 9u) << r.out;
  EXPECT_TRUE(std::regex_match(
      lines[0], std::regex(R"(1017sub0  Producer heartbeat time += 1000 \(0x03E8\))")))
      << lines[0];
  EXPECT_THAT(lines[1], HasSubstr("1400sub1  RPDO1 communication parameter: COB-ID used by RPDO"));
  // A COB-ID reads as hex alone: bit 31 set, CAN-ID 205h (CiA 301 §7.5.2.35).
  EXPECT_TRUE(lines[1].ends_with("  = 0x80000205")) << lines[1];
  EXPECT_THAT(lines[8], HasSubstr("1F50sub1"));
}

TEST(Dcf2Concise, DecodeWithoutDeviceFileShowsBytes) {
  ScratchDir dir;
  auto r = run("dcf2concise", {"--decode", "-"}, dir.path(), "",
               data_path("concise/heartbeat_1000.bin"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "1017sub0    2 bytes  = 1000 (0x03E8)\n");
}

TEST(Dcf2Concise, DecodeJsonHasTypedValues) {
  ScratchDir dir;
  auto r = run("dcf2concise",
               {"--decode", data_path("concise/heartbeat_1000.bin"), "--dcf",
                data_path("concise/node5.dcf"), "--json"},
               dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  tool_test::JsonParser parser(r.out);
  auto json = parser.parse();
  ASSERT_TRUE(json.has_value()) << parser.error() << "\n" << r.out;
  EXPECT_TRUE(json->get("ok")->boolean);
  EXPECT_EQ(json->get("announced")->number, 1);
  const auto& entries = json->get("entries")->array;
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].get("name")->string, "Producer heartbeat time");
  EXPECT_EQ(entries[0].get("type")->string, "UNSIGNED16");
  EXPECT_EQ(entries[0].get("value")->string, "0x3E8");  // format_value: canonical DCF text
  EXPECT_EQ(entries[0].get("data")->string, "e803");
}

TEST(Dcf2Concise, DecodeRejectsTruncatedStreamWithOffset) {
  ScratchDir dir;
  auto r = run("dcf2concise", {"--decode", data_path("concise/truncated.bin")}, dir.path());
  EXPECT_EQ(r.exit_code, 1);
  // truncated.bin: heartbeat_1000.bin without its last byte (12 bytes).
  EXPECT_THAT(r.err, HasSubstr("truncated.bin: error: concise DCF truncated: the stream ends at "
                               "byte offset 12"));
}

TEST(Dcf2Concise, DecodeWarnsAboutEntriesTheDeviceDoesNotHave) {
  ScratchDir dir;
  const std::vector<ObjectWrite> entries{u16(0x1017, 0, 1000), u8(0x3000, 1, 7)};
  auto bytes = cfg::encode_concise_dcf(entries);
  std::ofstream(dir / "x.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  const std::string device = data_path("concise/node5.dcf");
  auto r = run("dcf2concise", {"--decode", dir / "x.bin", "--dcf", device}, dir.path());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("warning: entry 2 (3000sub1): not in node5.dcf"));
  auto strict =
      run("dcf2concise", {"--decode", dir / "x.bin", "--dcf", device, "--strict"}, dir.path());
  EXPECT_EQ(strict.exit_code, 1);
}

// samples/network/*.dcf (written for this project): each converts, and each entry decodes as
// the data type its DCF gives it.
TEST(Dcf2Concise, ConvertsEverySampleNetworkDcf) {
  const fs::path network = fs::path(CANOPEN_SAMPLES_DIR) / "network";
  if (!fs::exists(network)) PREREQUISITE_MISSING("no samples/network at ", network);
  ScratchDir dir;
  int converted = 0;
  for (const auto& e : fs::directory_iterator(network)) {
    if (e.path().extension() != ".dcf") continue;
    const std::string out = dir / (e.path().stem().string() + ".bin");
    auto r = run("dcf2concise", {e.path().string(), "-o", out}, dir.path());
    ASSERT_EQ(r.exit_code, 0) << e.path() << "\n" << r.err;
    EXPECT_FALSE(decode_file(out).empty()) << e.path();
    auto decoded =
        run("dcf2concise", {"--decode", out, "--dcf", e.path().string(), "--strict"}, dir.path());
    EXPECT_EQ(decoded.exit_code, 0) << e.path() << "\n" << decoded.err;
    ++converted;
  }
  EXPECT_GE(converted, 3);
}

// Every concise DCF of the corpus decodes with the entry count MANIFEST.tsv records; where it
// records none (dcfgen's output sets added later), with the count the stream's first
// UNSIGNED32 declares (DSP 302 §6.1: number of entries, then index, sub-index, size, data).
TEST(Dcf2Concise, DecodesCorpusStreams) {
  const fs::path corpus(CANOPEN_CORPUS_DIR);
  if (!fs::exists(corpus / "MANIFEST.tsv")) PREREQUISITE_MISSING("corpus not found: ", corpus);
  ScratchDir dir;
  std::istringstream manifest(tool_test::slurp(corpus / "MANIFEST.tsv"));
  for (std::string line; std::getline(manifest, line);) {
    const std::string file = line.substr(0, line.find('\t'));
    if (file.size() < 4 || file.substr(file.size() - 4) != ".bin") continue;
    const auto key = line.find("concise-dcf entries=");
    std::size_t expected = 0;
    if (key != std::string::npos) {
      expected = std::stoul(line.substr(key + 20));
    } else {
      const std::string bytes = tool_test::slurp(corpus / file);
      ASSERT_GE(bytes.size(), 4U) << file;
      for (int i = 3; i >= 0; --i)
        expected = expected * 256U + static_cast<unsigned char>(bytes[i]);
    }
    auto r = run("dcf2concise", {"--decode", (corpus / file).string(), "--json"}, dir.path());
    ASSERT_EQ(r.exit_code, 0) << file << "\n" << r.err;
    tool_test::JsonParser parser(r.out);
    auto json = parser.parse();
    ASSERT_TRUE(json.has_value()) << file << ": " << parser.error();
    EXPECT_EQ(json->get("entries")->array.size(), expected) << file;
  }
}

// The version comes from the top-level CMakeLists.txt's project(... VERSION x.y.z), read here
// independently of the tool's own compile definition.
TEST(Dcf2Concise, VersionPrintsNameAndProjectVersion) {
  ScratchDir dir;
  const std::string text =
      tool_test::slurp(fs::path(CANOPEN_SAMPLES_DIR).parent_path() / "CMakeLists.txt");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(text, m, std::regex(R"(project\([^)]*VERSION\s+([0-9.]+))")));
  auto r = run("dcf2concise", {"--version"}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "dcf2concise " + m[1].str() + "\n");
}

// An EDS has no ParameterValue: the stream is only its entry count, UNSIGNED32 0 (DSP 302
// §6.2). A valid configuration, so rc 0 and a note, also under --strict.
TEST(Dcf2Concise, SaysThatAFileWithoutParameterValuesGivesAnEmptyStream) {
  const fs::path eds = fs::path(CANOPEN_SAMPLES_DIR) / "drive.eds";
  if (!fs::exists(eds)) PREREQUISITE_MISSING("no samples/drive.eds at ", eds);
  ScratchDir dir;
  auto r = run("dcf2concise", {eds.string(), "-o", dir / "drive.bin"}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("drive.eds: note: no ParameterValue to download: the concise DCF "
                               "is empty, a valid configuration"));
  EXPECT_THAT(r.err, HasSubstr("use --with-defaults to include DefaultValues"));
  EXPECT_EQ(tool_test::slurp(dir / "drive.bin"), std::string(4, '\0'));

  auto json = run("dcf2concise", {eds.string(), "-o", dir / "drive.bin", "--json"}, dir.path());
  EXPECT_EQ(json.exit_code, 0) << json.err;
  tool_test::JsonParser parser(json.out);
  auto parsed = parser.parse();
  ASSERT_TRUE(parsed.has_value()) << parser.error() << "\n" << json.out;
  EXPECT_EQ(parsed->get("size")->number, 4);
  const auto& diagnostics = parsed->get("diagnostics")->array;
  ASSERT_EQ(diagnostics.size(), 1u) << json.out;
  EXPECT_EQ(diagnostics[0].get("severity")->string, "note");
  EXPECT_THAT(diagnostics[0].get("message")->string, HasSubstr("no ParameterValue to download"));

  // With the DefaultValues there is something to download, and nothing to warn about (the
  // EDS's $NODEID defaults need a node-ID).
  auto defaults =
      run("dcf2concise",
          {eds.string(), "-o", dir / "drive.bin", "--with-defaults", "--node-id", "3"}, dir.path());
  EXPECT_EQ(defaults.exit_code, 0) << defaults.err;
  EXPECT_THAT(defaults.err, Not(HasSubstr("the concise DCF is empty")));
  EXPECT_GT(tool_test::slurp(dir / "drive.bin").size(), 4u);
}

TEST(Dcf2Concise, NotesThatNodeIdOverridesTheDcfs) {
  ScratchDir dir;
  const std::string dcf = data_path("concise/node5.dcf");  // [DeviceComissioning] NodeID=5
  auto r = run("dcf2concise", {dcf, "-o", dir / "n.bin", "--node-id", "7"}, dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err,
              HasSubstr("node5.dcf: note: --node-id 7 overrides NodeID 5 of [DeviceComissioning]"));
  EXPECT_EQ(decode_file(dir / "n.bin"), node5_writes(0x207));  // $NODEID+0x200 with node 7
  auto same = run("dcf2concise", {dcf, "-o", dir / "n.bin", "--node-id", "5"}, dir.path());
  EXPECT_EQ(same.exit_code, 0) << same.err;
  EXPECT_THAT(same.err, Not(HasSubstr("overrides")));
}

// One entry of one byte, written by hand (DSP 302 §6.2: UNSIGNED32 count, then UNSIGNED16 index,
// UNSIGNED8 sub-index, UNSIGNED32 size, data; little-endian): 1400h sub 2 = 1.
TEST(Dcf2Concise, DecodeSaysOneByteInTheSingular) {
  ScratchDir dir;
  const std::string stream(
      "\x01\x00\x00\x00"
      "\x00\x14\x02\x01\x00\x00\x00\x01",
      12);
  std::ofstream(dir / "one.bin", std::ios::binary) << stream;
  auto r = run("dcf2concise", {"--decode", dir / "one.bin"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "1400sub2    1 byte   = 1 (0x01)\n");
}

// A DCF without any ParameterValue under --strict: the empty configuration is valid (DSP 302
// §6.2), so it is written and said, not failed. no_params.dcf is written here: one
// writable VAR with a DefaultValue only, node-ID 5.
TEST(Dcf2Concise, StrictAcceptsAnEmptyConfiguration) {
  ScratchDir dir;
  std::ofstream(dir / "no_params.dcf", std::ios::binary)
      << "[FileInfo]\r\nFileName=no_params.dcf\r\n"
         "[DeviceInfo]\r\nVendorName=Test\r\nProductName=Test\r\n"
         "[MandatoryObjects]\r\nSupportedObjects=3\r\n1=0x1000\r\n2=0x1001\r\n3=0x1018\r\n"
         "[OptionalObjects]\r\nSupportedObjects=1\r\n1=0x1017\r\n"
         "[1000]\r\nParameterName=Device type\r\nObjectType=0x7\r\nDataType=0x0007\r\n"
         "AccessType=ro\r\nDefaultValue=0\r\nPDOMapping=0\r\n"
         "[1001]\r\nParameterName=Error register\r\nObjectType=0x7\r\nDataType=0x0005\r\n"
         "AccessType=ro\r\nDefaultValue=0\r\nPDOMapping=0\r\n"
         "[1017]\r\nParameterName=Producer heartbeat time\r\nObjectType=0x7\r\n"
         "DataType=0x0006\r\nAccessType=rw\r\nDefaultValue=0\r\nPDOMapping=0\r\n"
         "[1018]\r\nParameterName=Identity object\r\nObjectType=0x9\r\nSubNumber=2\r\n"
         "[1018sub0]\r\nParameterName=Highest sub-index supported\r\nObjectType=0x7\r\n"
         "DataType=0x0005\r\nAccessType=const\r\nDefaultValue=1\r\nPDOMapping=0\r\n"
         "[1018sub1]\r\nParameterName=Vendor-ID\r\nObjectType=0x7\r\nDataType=0x0007\r\n"
         "AccessType=ro\r\nDefaultValue=0\r\nPDOMapping=0\r\n"
         "[DeviceComissioning]\r\nNodeID=5\r\nBaudrate=500\r\n";
  auto r =
      run("dcf2concise", {"no_params.dcf", "--strict", "-o", "out.bin"}, dir.path(), dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("no_params.dcf: note: no ParameterValue to download: the concise "
                               "DCF is empty, a valid configuration"));
  EXPECT_THAT(r.err, Not(HasSubstr("error")));
  EXPECT_EQ(tool_test::slurp(dir / "out.bin"), std::string(4, '\0'));  // count 0, no entries
}

// COB-IDs and PDO mapping entries are bit fields: --decode shows them as hex alone, with or
// without a device file; an ordinary number keeps its decimal first. Entries: 1400h
// sub 1 = 80000202h (RPDO1 of node 2, not valid: CiA 301 §7.5.2.35), 1600h sub 1 = 60400010h
// (maps 6040h sub 0, 16 bits: CiA 301 §7.5.2.36), 1600h sub 0 = 1 (a count), 1005h = 80h (SYNC
// COB-ID, CiA 301 §7.5.2.5), 1017h = 1000 (a time in ms).
TEST(Dcf2Concise, DecodeShowsCobIdsAndMappingEntriesAsHex) {
  ScratchDir dir;
  const std::vector<ObjectWrite> entries{u32(0x1400, 1, 0x80000202), u32(0x1600, 1, 0x60400010),
                                         u8(0x1600, 0, 1), u32(0x1005, 0, 0x80),
                                         u16(0x1017, 0, 1000)};
  auto bytes = cfg::encode_concise_dcf(entries);
  std::ofstream(dir / "x.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  auto r = run("dcf2concise", {"--decode", dir / "x.bin"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out,
            "1400sub1    4 bytes  = 0x80000202\n"
            "1600sub1    4 bytes  = 0x60400010\n"
            "1600sub0    1 byte   = 1 (0x01)\n"
            "1005sub0    4 bytes  = 0x00000080\n"
            "1017sub0    2 bytes  = 1000 (0x03E8)\n");

  // With node5.dcf (RPDO1 parameters, mapping and heartbeat as UNSIGNED32/8/16).
  const std::vector<ObjectWrite> known{u32(0x1400, 1, 0x80000205), u32(0x1600, 2, 0x60400010),
                                       u16(0x1017, 0, 1000)};
  bytes = cfg::encode_concise_dcf(known);
  std::ofstream(dir / "k.bin", std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()),
             static_cast<std::streamsize>(bytes.size()));
  auto named =
      run("dcf2concise", {"--decode", dir / "k.bin", "--dcf", data_path("concise/node5.dcf")},
          dir.path());
  ASSERT_EQ(named.exit_code, 0) << named.err;
  std::vector<std::string> lines;
  std::istringstream in(named.out);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u) << named.out;
  EXPECT_TRUE(lines[0].ends_with("= 0x80000205")) << lines[0];
  EXPECT_TRUE(lines[1].ends_with("= 0x60400010")) << lines[1];
  EXPECT_TRUE(lines[2].ends_with("= 1000 (0x03E8)")) << lines[2];
}

// The file tests/data/concise/vendor_hex_domain.dcf (written for the tests) gives DOMAIN and
// OCTET_STRING values as one 0x-prefixed run of digits; 2000h holds 8000 bytes of the pattern
// (i * 37 + 11) mod 256 on one line. The concise DCF carries the bytes as they are (DSP 302 §6.2).
TEST(Dcf2Concise, HexPrefixedDomainValuesConvertToTheirBytes) {
  ScratchDir dir;
  auto r = run("dcf2concise", {data_path("concise/vendor_hex_domain.dcf"), "-o", "-"}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::uint8_t> table;
  for (unsigned i = 0; i < 8000; ++i)
    table.push_back(static_cast<std::uint8_t>((i * 37 + 11) & 0xFF));
  EXPECT_EQ(decode_string(r.out),
            (std::vector<ObjectWrite>{
                {0x2000, 0, table},
                {0x2001, 0, {0x04, 0x00, 0x00, 0x37, 0x00, 0x00, 0x24, 0x01, 0x01, 0x00, 0x00, 0x32,
                             0x00, 0x00, 0x24, 0x01, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x24}},
                {0x2002, 0, {0xC0, 0xFF, 0xEE, 0x01}}}));
}

}  // namespace
