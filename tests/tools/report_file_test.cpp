// The report files of the commands that run a network (cfgmgr master --json-events, push --json,
// verify --json) share one rule (tools::ReportFile): a path that cannot be opened fails at once,
// before the bus is touched, with exit 3; a write error at the end (a full disk) is exit 3 too.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

#include "prerequisite.hpp"
#include "tool_test_support.hpp"

namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using tool_test::cfgmgr;
using tool_test::ScratchDir;
using tool_test::test_network;

struct ReportCommand {
  std::string command;  // the subcommand
  std::string option;   // its report option
};

// What a failing test names: "push --json", not the struct's bytes.
void PrintTo(const ReportCommand& c, std::ostream* out) {
  *out << c.command << ' ' << c.option;
}

class ReportFile : public ::testing::TestWithParam<ReportCommand> {
 protected:
  tool_test::RunResult run_with_report(const ScratchDir& dir, const std::string& report) {
    return cfgmgr(dir, {GetParam().command, test_network("nodelist.cpj"), "--bus",
                        "sim:", GetParam().option, report});
  }
};

TEST_P(ReportFile, AnUnopenablePathExits3BeforeAnyBusWork) {
  ScratchDir dir;
  const std::string report = dir / "no/such/dir/report.json";
  const auto r = run_with_report(dir, report);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr(report + ": error: cannot open for writing: "
                                        "No such file or directory"));
  // Nothing was booted or read: the master never ran (its event lines and tables are absent).
  EXPECT_THAT(r.err, Not(HasSubstr("node 2")));
  EXPECT_EQ(r.out, "");
}

TEST_P(ReportFile, AWriteErrorExits3) {
  // /dev/full opens, and every write to it fails with ENOSPC (Linux null(4)).
  if (!std::filesystem::exists("/dev/full")) PREREQUISITE_MISSING("no /dev/full");
  ScratchDir dir;
  const auto r = run_with_report(dir, "/dev/full");
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_THAT(r.err, HasSubstr("/dev/full: error: write error"));
}

INSTANTIATE_TEST_SUITE_P(Commands, ReportFile,
                         ::testing::Values(ReportCommand{"master", "--json-events"},
                                           ReportCommand{"push", "--json"},
                                           ReportCommand{"verify", "--json"}),
                         [](const auto& test) { return test.param.command; });

}  // namespace
