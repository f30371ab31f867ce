// cfgmgr's start-up: libpcap is loaded only when a pcap trace is opened (libnmt/io loads it with
// dlopen), so a command without --trace does not load it and the libraries it needs (libdbus-1,
// libsystemd, libgcrypt, ...). Which files the dynamic loader opens comes from glibc's own
// report (ld.so(8), LD_DEBUG=files: a line "file=NAME [0];  ..." for every object it loads),
// written to LD_DEBUG_OUTPUT.PID, one file for each process (the shell that starts the tool too).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "generated_network.hpp"
#include "tool_test_support.hpp"

#ifndef CANOPEN_PCAP_SONAME
#error "tests/CMakeLists.txt defines CANOPEN_PCAP_SONAME for tools_tests"
#endif

namespace {

using testing::HasSubstr;
using testing::Not;
using tool_test::run;
using tool_test::ScratchDir;

// Sets an environment variable of this process, and so of the tools it runs, for a scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

// The loader's line for a loaded object: "file=libpcap.so.0.8 [0];  dynamically loaded by ...".
std::string loaded(const std::string& soname) {
  return "file=" + soname + " [0];";
}

// Runs cfgmgr with `args` under LD_DEBUG=files; the exit code, and in `err` the tool's stderr
// followed by the loader's reports of all processes of the run.
tool_test::RunResult run_reporting_loads(const ScratchDir& dir,
                                         const std::vector<std::string>& args) {
  const auto reports = dir.path() / "ld-debug";
  std::filesystem::create_directories(reports);
  tool_test::RunResult r;
  {
    const ScopedEnv debug("LD_DEBUG", "files");
    const ScopedEnv output("LD_DEBUG_OUTPUT", (reports / "report").string());
    r = run("cfgmgr", args, dir.path().string());
  }
  for (const auto& report : std::filesystem::directory_iterator(reports)) {
    r.err += tool_test::slurp(report.path());
  }
  return r;
}

// A network of one node for `cfgmgr push --bus sim:`, the command that opens a trace here.
std::string one_node_network(const ScratchDir& dir) {
  generated::NetworkSpec spec;
  spec.nodes = 1;
  return generated::write_network(dir.path() / "net", spec);
}

TEST(CfgmgrStartup, CheckDoesNotLoadLibpcap) {
  ScratchDir dir;
  auto r = run_reporting_loads(dir, {"check", tool_test::data_path("sim_device.eds")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The report is there (the C++ runtime is loaded by every run), and it has no libpcap.
  EXPECT_THAT(r.err, HasSubstr("file=libstdc++.so.6 [0];"));
  EXPECT_THAT(r.err, Not(HasSubstr(loaded(CANOPEN_PCAP_SONAME))));
}

TEST(CfgmgrStartup, VersionDoesNotLoadLibpcap) {
  ScratchDir dir;
  auto r = run_reporting_loads(dir, {"--version"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("file=libstdc++.so.6 [0];"));
  EXPECT_THAT(r.err, Not(HasSubstr(loaded(CANOPEN_PCAP_SONAME))));
}

TEST(CfgmgrStartup, PcapTraceLoadsLibpcapWhenItIsOpened) {
  ScratchDir dir;
  const std::string cpj = one_node_network(dir);
  const std::string pcap = dir / "boot.pcap";
  auto r = run_reporting_loads(dir, {"push", cpj, "--bus", "sim:", "--trace", pcap});
  ASSERT_EQ(r.exit_code, 0) << r.err.substr(0, 4000);
  EXPECT_THAT(r.err, HasSubstr(loaded(CANOPEN_PCAP_SONAME) + "  dynamically loaded by"));
  // pcap-savefile(5): the 24-byte global header, then 32 bytes a frame (16 + struct can_frame).
  const auto size = std::filesystem::file_size(pcap);
  EXPECT_GT(size, 24u);
  EXPECT_EQ((size - 24) % 32, 0u);
}

TEST(CfgmgrStartup, MissingLibpcapIsAnIoErrorThatNamesThePackage) {
  // The dynamic loader searches LD_LIBRARY_PATH first (ld.so(8)); an empty file under
  // libpcap's name there stands for a broken or missing libpcap: dlopen fails, "file too
  // short". Nothing else of cfgmgr needs libpcap, so only the trace fails, with exit code 3
  // (I/O), before anything is sent.
  ScratchDir dir;
  const std::string cpj = one_node_network(dir);
  const std::filesystem::path fake = dir.path() / "fake-lib";
  std::filesystem::create_directories(fake);
  std::ofstream(fake / CANOPEN_PCAP_SONAME).close();
  const std::string pcap = dir / "boot.pcap";
  const ScopedEnv path("LD_LIBRARY_PATH", fake.string());
  auto r = run("cfgmgr", {"push", cpj, "--bus", "sim:", "--trace", pcap}, dir.path().string());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr(pcap + ": writing a pcap trace needs libpcap (Debian package "
                                      "libpcap0.8): "));
  EXPECT_THAT(r.err, HasSubstr(CANOPEN_PCAP_SONAME ": file too short"));
  EXPECT_FALSE(std::filesystem::exists(pcap));
}

}  // namespace
