// The files a master DCF alone names (cfg/network.hpp): 1F20h/1F22h/1F58h sub X by
// DownloadFile= or UploadFile= (lely's dcfgen writes only UploadFile=, with absolute paths of the
// machine that ran it), looked for by name in NetworkOptions::dcf_path and beside the master DCF
// when they are not where the DCF says, and check_network's warning for a slave the master boots
// without any configuration. The master DCFs are written here in dcfgen's layout.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/network.hpp"
#include "cfg/network_check.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A directory of its own per test, removed afterwards.
class MasterFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("cfg_master_files_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  void write(const std::string& name, const std::string& text) const {
    fs::create_directories(fs::path(path(name)).parent_path());
    std::ofstream(path(name), std::ios::binary) << text;
  }
  void write_concise(const std::string& name, const std::vector<cfg::ObjectWrite>& writes) const {
    const auto bytes = cfg::encode_concise_dcf(writes);
    write(name, std::string(bytes.begin(), bytes.end()));
  }

  // dcfgen's master DCF for slave 2 (1F81h sub 2 = 05h: slave, boot it): 1F22h sub 2 with the
  // key lines `key_lines` (e.g. "UploadFile=node2.bin"), and `more` sections after it.
  // Line numbers: [1F22sub2] is line 19, its first key line 23.
  std::string master(const std::string& key_lines, const std::string& more = "") const {
    return "[DeviceComissioning]\n"             // 1
           "NodeID=1\n"                         // 2
           "CANopenManager=1\n"                 // 3
           "\n"                                 // 4
           "[DeviceInfo]\n"                     // 5
           "VendorNumber=0x00000000\n"          // 6
           "\n"                                 // 7
           "[1F22]\n"                           // 8
           "SubNumber=2\n"                      // 9
           "ParameterName=Concise DCF\n"        // 10
           "ObjectType=0x08\n"                  // 11
           "\n"                                 // 12
           "[1F22sub0]\n"                       // 13
           "ParameterName=Highest sub-index\n"  // 14
           "DataType=0x0005\n"                  // 15
           "AccessType=const\n"                 // 16
           "DefaultValue=2\n"                   // 17
           "\n"                                 // 18
           "[1F22sub2]\n"                       // 19
           "ParameterName=Node-ID 2\n"          // 20
           "DataType=0x000F\n"                  // 21
           "AccessType=ro\n" +                  // 22
           key_lines +                          // 23...
           "\n"
           "[1F81]\n"
           "ParameterName=NMT slave assignment\n"
           "ObjectType=0x08\n"
           "DataType=0x0007\n"
           "AccessType=rw\n"
           "CompactSubObj=127\n"
           "\n"
           "[1F81Value]\n"
           "NrOfEntries=2\n"
           "2=0x00000005\n"
           "3=0x00000005\n" +
           more;
  }

  fs::path dir_;
};

// What load_network says about the files the master DCF names (not the reader's remarks on the
// short DCFs of these tests: no object lists, no 1000h/1001h/1018h).
cfg::Diagnostics about_files(const cfg::Diagnostics& diagnostics) {
  cfg::Diagnostics out;
  for (const auto& d : diagnostics.items()) {
    if (d.message.find("File") != std::string::npos) out.add(d.file, d.line, d.severity, d.message);
  }
  return out;
}

const cfg::Diagnostic* find(const cfg::Diagnostics& diagnostics, const std::string& text) {
  for (const auto& d : diagnostics.items()) {
    if (d.message.find(text) != std::string::npos) return &d;
  }
  return nullptr;
}

// One entry: 1017h sub 0 = 1000 ms (CiA 301 producer heartbeat time, UNSIGNED16).
const std::vector<cfg::ObjectWrite> kHeartbeat{{0x1017, 0, {0xE8, 0x03}}};

TEST_F(MasterFiles, UploadFileNamesTheConciseDcfOf1F22hAsDownloadFileDoes) {
  write("master.dcf", master("UploadFile=node2.bin\n"));
  write_concise("node2.bin", kHeartbeat);
  const auto load = cfg::load_network(path("master.dcf"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  EXPECT_TRUE(about_files(load.diagnostics).empty()) << load.diagnostics.format();
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].node_id.value(), 2);
  EXPECT_EQ(load.network->nodes[0].file, path("node2.bin"));
  EXPECT_EQ(load.network->nodes[0].writes, kHeartbeat);
}

TEST_F(MasterFiles, DownloadFileWinsOverAnUploadFileNamingAnotherFile) {
  write("master.dcf", master("DownloadFile=node2.bin\nUploadFile=other.bin\n"));
  write_concise("node2.bin", kHeartbeat);
  write_concise("other.bin", {});
  const auto load = cfg::load_network(path("master.dcf"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].writes, kHeartbeat);
  const cfg::Diagnostic* d = find(load.diagnostics, "name different files");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Warning);
  EXPECT_EQ(d->line, 23);
}

TEST_F(MasterFiles, AFileThatIsNowhereIsAnErrorAtItsKeyLineNamingItAndTheWayOut) {
  // What dcfgen writes on another machine: its dcf_path joined to the slave's name.
  write("master.dcf", master("UploadFile=/opt/ros/share/canopen_tests/config/node2.bin\n"));
  cfg::NetworkOptions options;
  options.dcf_path_hint = " with --dcf-path DIR";
  const auto load = cfg::load_network(path("master.dcf"), options);
  EXPECT_FALSE(load.ok());
  ASSERT_TRUE(load.network.has_value());
  EXPECT_TRUE(load.network->nodes.empty());
  ASSERT_EQ(load.diagnostics.count(cfg::Severity::Error), 1U) << load.diagnostics.format();
  const cfg::Diagnostic* error = find(load.diagnostics, "no such file");
  ASSERT_NE(error, nullptr) << load.diagnostics.format();
  const cfg::Diagnostic& d = *error;
  EXPECT_EQ(d.file, path("master.dcf"));
  EXPECT_EQ(d.line, 23);
  EXPECT_THAT(d.message,
              HasSubstr("1F22h sub 02h UploadFile "
                        "'/opt/ros/share/canopen_tests/config/node2.bin': no such file"));
  EXPECT_THAT(d.message, HasSubstr("'" + path("node2.bin") + "'"));  // where it looked too
  EXPECT_THAT(d.message, HasSubstr("rebuild the master DCF"));
  EXPECT_THAT(d.message,
              HasSubstr("pass the directory that holds 'node2.bin' with --dcf-path DIR"));
}

TEST_F(MasterFiles, AFileThatIsNotWhereItIsSaidIsTakenByItsNameFromDcfPath) {
  write("master.dcf", master("UploadFile=/opt/ros/share/canopen_tests/config/node2.bin\n"));
  write_concise("bins/node2.bin", kHeartbeat);
  cfg::NetworkOptions options;
  options.dcf_path = {path("empty"), path("bins")};
  const auto load = cfg::load_network(path("master.dcf"), options);
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  EXPECT_TRUE(about_files(load.diagnostics).empty()) << load.diagnostics.format();
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].file, path("bins/node2.bin"));
  EXPECT_EQ(load.network->nodes[0].writes, kHeartbeat);
}

TEST_F(MasterFiles, AFileBesideTheMasterDcfIsUsedWithAWarningNamingBothPaths) {
  write("master.dcf", master("UploadFile=/opt/ros/share/canopen_tests/config/node2.bin\n"));
  write_concise("node2.bin", kHeartbeat);
  const auto load = cfg::load_network(path("master.dcf"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  ASSERT_EQ(load.network->nodes.size(), 1U);
  EXPECT_EQ(load.network->nodes[0].writes, kHeartbeat);
  const cfg::Diagnostics files = about_files(load.diagnostics);
  ASSERT_EQ(files.size(), 1U) << load.diagnostics.format();
  const cfg::Diagnostic& d = files.items()[0];
  EXPECT_EQ(d.severity, cfg::Severity::Warning);
  EXPECT_EQ(d.line, 23);
  EXPECT_THAT(d.message, HasSubstr("'/opt/ros/share/canopen_tests/config/node2.bin' does not "
                                   "exist; using '" +
                                   path("node2.bin") + "'"));
}

TEST_F(MasterFiles, ProgramDataOf1F58hIsTheNodesProgramImage) {
  // CiA 302-3 1F58h sub 2, as dcfgen writes it for software_file.
  write("master.dcf", master("UploadFile=node2.bin\n",
                             "\n"
                             "[1F58]\n"
                             "SubNumber=2\n"
                             "ParameterName=Program data\n"
                             "ObjectType=0x08\n"
                             "\n"
                             "[1F58sub0]\n"
                             "ParameterName=Highest sub-index supported\n"
                             "DataType=0x0005\n"
                             "AccessType=const\n"
                             "DefaultValue=2\n"
                             "\n"
                             "[1F58sub2]\n"
                             "ParameterName=Program data of node-ID 2\n"
                             "DataType=0x000F\n"
                             "AccessType=ro\n"
                             "UploadFile=firmware.bin\n"));
  write_concise("node2.bin", kHeartbeat);
  write("firmware.bin", "IMAGE");
  const auto load = cfg::load_network(path("master.dcf"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  ASSERT_EQ(load.network->nodes.size(), 1U);
  const auto& program = load.network->nodes[0].program;
  ASSERT_TRUE(program.has_value());
  EXPECT_EQ(program->file, path("firmware.bin"));
  EXPECT_EQ(program->image, (std::vector<std::uint8_t>{'I', 'M', 'A', 'G', 'E'}));
  EXPECT_FALSE(program->version.has_value());  // the master DCF's 1F53h/1F54h give it
}

TEST_F(MasterFiles, CheckWarnsOfASlaveTheMasterBootsWithoutConfiguration) {
  // Node 2 has its concise DCF; node 3 (1F81h sub 3 = 05h) has no 1F22h sub 3 at all.
  write("master.dcf", master("UploadFile=node2.bin\n"));
  write_concise("node2.bin", kHeartbeat);
  auto load = cfg::load_network(path("master.dcf"));
  ASSERT_TRUE(load.ok()) << load.diagnostics.format();
  cfg::check_network(*load.network, load.diagnostics);
  const cfg::Diagnostic* d = find(load.diagnostics, "node 3");
  ASSERT_NE(d, nullptr) << load.diagnostics.format();
  EXPECT_EQ(d->severity, cfg::Severity::Warning);
  EXPECT_EQ(d->line, 35);  // 3=0x00000005 of [1F81Value]
  EXPECT_THAT(d->message, HasSubstr("no configuration for node 3 (1F22h sub 03h empty)"));
  EXPECT_EQ(find(load.diagnostics, "node 2"), nullptr) << load.diagnostics.format();
}

}  // namespace
