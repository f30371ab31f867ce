// cfgmgr push end to end on the simulated bus (sim:): the sample network (samples/network) and
// the test networks of tests/data/network. The expected entries and bytes per node come from the
// nodes' concise DCFs as dcf2concise writes them from the same DCFs (CiA 302 §6.2 stream: a
// UNSIGNED32 count, then per entry index, sub-index, size and data).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "generated_network.hpp"
#include "push_test_support.hpp"

namespace {

using push_test::cfgmgr;
using push_test::Concise;
using push_test::concise_of;
using push_test::nodes_of;
using push_test::parse_json;
using tool_test::Json;
using tool_test::RunResult;
using tool_test::sample_network;
using tool_test::ScratchDir;
using tool_test::test_network;

TEST(Push, HelpDocumentsOptionsExamplesAndExitCodes) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"push", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text :
       {"NETWORK", "--bus", "--json", "--boot-time", "--dry-run", "--only", "--force", "--no-start",
        "--no-save", "--sdo-timeout", "--retries", "--trace", "--candump", "state=DIR",
        "1F81h = 11h", "10 s", "Examples:", "Exit codes:", "  4  "}) {
    EXPECT_NE(r.out.find(text), std::string::npos) << text;
  }
  EXPECT_NE(cfgmgr(dir, {"--help"}).out.find("push"), std::string::npos);
}

TEST(Push, ConfiguresEveryNodeOfTheSampleNetworkWithTheirConciseDcfWrites) {
  ScratchDir dir;
  const std::string report = dir / "report.json";
  auto r = cfgmgr(dir, {"push", sample_network("nodelist.cpj"), "--bus", "sim:", "--json", report});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Not on a terminal: one line per event on stderr, as cfgmgr master prints them.
  EXPECT_NE(r.err.find("node 3: booted, configured"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("NMT start-up complete"), std::string::npos) << r.err;

  const Json json = parse_json(report);
  ASSERT_NE(json.get("ok"), nullptr);
  EXPECT_TRUE(json.get("ok")->boolean);
  ASSERT_TRUE(json.get("elapsed_s")->is(Json::Kind::Number));
  EXPECT_GT(json.get("elapsed_s")->number, 0.0);
  ASSERT_NE(json.get("bus"), nullptr);
  EXPECT_TRUE(json.get("bus")->is(Json::Kind::Null)) << "sim: has no controller to count";
  const auto nodes = nodes_of(json);
  // samples/network/nodelist.cpj: nodes 2 (io_left), 3 (axis_x), 4 (io_right).
  const std::map<int, std::pair<std::string, std::string>> expected = {
      {2, {"io_left", "io_module_node2.dcf"}},
      {3, {"axis_x", "drive_node3.dcf"}},
      {4, {"io_right", "io_module_node4.dcf"}}};
  ASSERT_EQ(nodes.size(), expected.size()) << tool_test::slurp(report);
  for (const auto& [id, what] : expected) {
    SCOPED_TRACE("node " + std::to_string(id));
    ASSERT_TRUE(nodes.count(id));
    const Json& n = *nodes.at(id);
    const Concise concise = concise_of(dir, sample_network(what.second));
    EXPECT_EQ(n.get("name")->string, what.first);
    EXPECT_EQ(n.get("result")->string, "configured");
    EXPECT_TRUE(n.get("status")->is(Json::Kind::Null));
    EXPECT_TRUE(n.get("message")->is(Json::Kind::String));
    EXPECT_EQ(n.get("entries")->number, static_cast<double>(concise.entries));
    EXPECT_EQ(n.get("bytes")->number, static_cast<double>(concise.bytes));
    EXPECT_GE(n.get("seconds")->number, 0.0);
    EXPECT_LE(n.get("seconds")->number, json.get("elapsed_s")->number);
  }
  // The table on stdout names every node with its result.
  EXPECT_NE(r.out.find("axis_x"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("configured"), std::string::npos) << r.out;
}

TEST(Push, ForceStillConfiguresEveryNode) {
  ScratchDir dir;
  const std::string report = dir / "report.json";
  // --force: download even when 1020h matches (CiA 302-2 §3.5 c is skipped); --no-save and
  // --no-start change what the master does after the download, not the result.
  auto r = cfgmgr(dir, {"push", sample_network("nodelist.cpj"), "--bus", "sim:", "--force",
                        "--json", report, "--no-save", "--retries", "3", "--sdo-timeout", "0.2"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  for (const auto& [id, n] : nodes_of(json)) {
    EXPECT_EQ(n->get("result")->string, "configured") << id;
  }
  r = cfgmgr(dir,
             {"push", sample_network("nodelist.cpj"), "--bus", "sim:", "--force", "--no-start"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

TEST(Push, DryRunListsTheWritesInDownloadOrderWithoutABus) {
  ScratchDir dir;
  auto r = cfgmgr(dir, {"push", sample_network("nodelist.cpj"), "--dry-run", "--only", "3"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find("sim:"), std::string::npos) << "no bus is opened: " << r.err;
  EXPECT_NE(r.out.find("node 3 (axis_x): "), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("node 2"), std::string::npos) << r.out;
  const Concise concise = concise_of(dir, sample_network("drive_node3.dcf"));
  EXPECT_NE(r.out.find(std::to_string(concise.entries) + " writes"), std::string::npos) << r.out;
  // drive_node3.dcf: 1017h = 500 ms (01F4h); 1601h sub 1 maps 6040h sub 0, 16 bits. CiA 301
  // §7.3.5: the mapping's sub 0 goes to 0 before the entries and to 2 after them.
  const auto at = [&r](const std::string& line) { return r.out.find(line); };
  EXPECT_NE(at("  1017h sub 00h = f401\n"), std::string::npos) << r.out;
  const auto zero = at("  1601h sub 00h = 00\n");
  const auto entry = at("  1601h sub 01h = 10004060\n");
  const auto count = at("  1601h sub 00h = 02\n");
  ASSERT_NE(zero, std::string::npos) << r.out;
  ASSERT_NE(entry, std::string::npos) << r.out;
  ASSERT_NE(count, std::string::npos) << r.out;
  EXPECT_LT(zero, entry);
  EXPECT_LT(entry, count);
}

TEST(Push, WrongIdentityOfAMandatoryNodeIsAnErrorWithItsLetterAndExit4) {
  // wrong_identity.cpj's master DCF expects vendor-ID 0x00000BAD at node 2, which has
  // 0x00000ABC: CiA 302-2 §3.4 / Table 1 status D; a mandatory slave (§3.1 f).
  ScratchDir dir;
  const std::string report = dir / "report.json";
  auto r =
      cfgmgr(dir, {"push", test_network("wrong_identity.cpj"), "--bus", "sim:", "--json", report});
  EXPECT_EQ(r.exit_code, 4) << r.err;
  const Json json = parse_json(report);
  EXPECT_FALSE(json.get("ok")->boolean);
  const auto nodes = nodes_of(json);
  ASSERT_TRUE(nodes.count(2)) << tool_test::slurp(report);
  EXPECT_EQ(nodes.at(2)->get("result")->string, "error");
  EXPECT_EQ(nodes.at(2)->get("status")->string, "D");
  EXPECT_NE(nodes.at(2)->get("message")->string.find("1F85h"), std::string::npos)
      << nodes.at(2)->get("message")->string;
  EXPECT_NE(r.out.find("error D: "), std::string::npos) << r.out;
}

TEST(Push, AnOptionalNodesFailureIsReportedAndExits0) {
  // wrong_identity.cpj with node 2 optional: 1F81h sub 2 = 05h (slave, boot; bit 3 mandatory
  // clear, CiA 302-2 Table 21). Its status D is reported; start-up goes on (§3.1 f is about
  // mandatory slaves only).
  ScratchDir dir;
  namespace fs = std::filesystem;
  fs::create_directories(dir / "nodes");
  fs::copy_file(test_network("wrong_identity.cpj"), dir / "net.cpj");
  fs::copy_file(test_network("nodes/io_node2.dcf"), dir / "nodes/io_node2.dcf");
  std::string master = tool_test::slurp(test_network("master_wrong_vendor.dcf"));
  const std::string mandatory = "ParameterValue=0x0000000D";
  const auto at = master.find(mandatory, master.find("[1F81sub2]"));
  ASSERT_NE(at, std::string::npos);
  master.replace(at, mandatory.size(), "ParameterValue=0x00000005");
  { std::ofstream(dir / "master_wrong_vendor.dcf", std::ios::binary) << master; }
  const std::string report = dir / "report.json";
  auto r = cfgmgr(dir, {"push", dir / "net.cpj", "--bus", "sim:", "--json", report});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  EXPECT_TRUE(json.get("ok")->boolean);
  const auto nodes = nodes_of(json);
  ASSERT_TRUE(nodes.count(2)) << tool_test::slurp(report);
  EXPECT_EQ(nodes.at(2)->get("result")->string, "error");
  EXPECT_EQ(nodes.at(2)->get("status")->string, "D");
}

TEST(Push, OnlyRestrictsTheNodes) {
  ScratchDir dir;
  const std::string report = dir / "report.json";
  auto r = cfgmgr(dir, {"push", sample_network("nodelist.cpj"), "--bus", "sim:", "--only", "3-4",
                        "--json", report});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Json json = parse_json(report);
  const auto nodes = nodes_of(json);
  EXPECT_EQ(nodes.size(), 2U);
  EXPECT_TRUE(nodes.count(3) && nodes.count(4));
  EXPECT_EQ(r.err.find("node 2: booted"), std::string::npos) << r.err;
}

TEST(Push, NotOnATerminalEachEventIsOneLineWithItsTime) {
  // stderr is a file here: no live view, no escape sequences; each line is "S.mmm  text" or a
  // "cfgmgr push: " line (the bus and the summary).
  ScratchDir dir;
  auto r = cfgmgr(dir, {"push", sample_network("nodelist.cpj"), "--bus", "sim:"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << r.err;
  std::istringstream lines(r.err);
  std::string line;
  std::vector<std::string> events;
  while (std::getline(lines, line)) {
    if (line.rfind("cfgmgr push: ", 0) == 0) continue;
    ASSERT_GE(line.size(), 7U) << line;
    EXPECT_TRUE(std::isdigit(static_cast<unsigned char>(line[0])) && line.find('.') < 6 &&
                line.find("  ") != std::string::npos)
        << line;
    events.push_back(line.substr(line.find("  ") + 2));
  }
  // One line per event, in the order they happened: start-up, each node's result, the end.
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front(), "NMT start-up began");
  EXPECT_EQ(events.back(), "NMT start-up complete");
  for (const char* node : {"node 2: booted, configured (", "node 3: booted, configured (",
                           "node 4: booted, configured ("}) {
    EXPECT_EQ(std::count_if(events.begin(), events.end(),
                            [node](const std::string& e) { return e.rfind(node, 0) == 0; }),
              1)
        << node << " in " << r.err;
  }
}

// Runs cfgmgr with stdout and stderr on a pseudo terminal of 40 x 120 and returns what it
// wrote there; `exit_code` gets its exit status.
std::string run_on_terminal(const std::vector<std::string>& args, int& exit_code) {
  int master = -1;
  int slave = -1;
  winsize size{};
  size.ws_row = 40;
  size.ws_col = 120;
  if (::openpty(&master, &slave, nullptr, nullptr, &size) != 0) return "openpty failed";
  std::vector<std::string> argv_text = {tool_test::tool_path("cfgmgr")};
  argv_text.insert(argv_text.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_text) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setsid();
    const int null = ::open("/dev/null", O_RDONLY);
    ::dup2(null, 0);
    ::dup2(slave, 1);
    ::dup2(slave, 2);
    ::close(master);
    ::setenv("TERM", "xterm", 1);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(slave);
  std::string out;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(master, buf, sizeof buf);
    if (n > 0) {
      out.append(buf, static_cast<std::size_t>(n));
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      break;  // EIO once the child closed its side
    }
  }
  ::close(master);
  int status = 0;
  ::waitpid(pid, &status, 0);
  exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

TEST(Push, OnATerminalALiveViewIsDrawnAndTheTableEndsTheOutput) {
  int exit_code = -1;
  const std::string out = run_on_terminal(
      {"push", sample_network("nodelist.cpj"), "--bus", "sim:?latency_ms=1"}, exit_code);
  ASSERT_EQ(exit_code, 0) << out;
  // The view: a progress bar and a row per node with state, step, entries, bytes, retries,
  // redrawn in place (ANSI CSI: cursor to the previous line, erase below).
  EXPECT_NE(out.find("] 0%"), std::string::npos) << out;
  EXPECT_NE(out.find("retries"), std::string::npos) << out;
  EXPECT_NE(out.find("\x1b[J"), std::string::npos) << out;
  // Instead of event lines.
  EXPECT_EQ(out.find("booted, configured"), std::string::npos) << out;
  // After the view is erased for the last time: the table (samples/network: nodes 2-4) and
  // nothing else.
  const std::string tail = out.substr(out.rfind("\x1b[J") + 3);
  const auto table = tail.find("node  name");
  ASSERT_NE(table, std::string::npos) << tail;
  std::istringstream lines(tail.substr(table));
  std::string line;
  std::vector<std::string> rows;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();  // the terminal's ONLCR
    if (!line.empty()) rows.push_back(line);
  }
  ASSERT_EQ(rows.size(), 4U) << tail;
  EXPECT_EQ(rows[1].rfind("   2  io_left   configured", 0), 0U) << rows[1];
  EXPECT_EQ(rows[2].rfind("   3  axis_x    configured", 0), 0U) << rows[2];
  EXPECT_EQ(rows[3].rfind("   4  io_right  configured", 0), 0U) << rows[3];
}

TEST(Push, OnATerminalTheLiveViewShowsEachFailedNodesStatusLetter) {
  // CiA 302-2 Table 1: node 1 expected with another device type (C), node 2 with another
  // vendor-ID (D). The view's step column says "error C"/"error D" once they end, as the table's
  // result column does.
  ScratchDir dir;
  const std::string cpj =
      generated::write_network(dir.path() / "net", generated::wrong_type_and_vendor());
  int exit_code = -1;
  const std::string out = run_on_terminal({"push", cpj, "--bus", "sim:"}, exit_code);
  EXPECT_EQ(exit_code, 4) << out;
  const std::string view = out.substr(0, out.rfind("node  name"));
  EXPECT_NE(view.find("error C"), std::string::npos) << view;
  EXPECT_NE(view.find("error D"), std::string::npos) << view;
}

TEST(Push, OnATerminalEmergenciesGoAboveTheLiveViewAndAreCountedInIt) {
  // CiA 301 §7.2.7: node 3 sends 8130h at 5 ms. The view has no words for it: its line is printed
  // above the view, and the view's emcy column counts it.
  int exit_code = -1;
  const std::string out = run_on_terminal(
      {"push", sample_network("nodelist.cpj"), "--bus", "sim:?latency_ms=1&emcy=3@5:8130:10"},
      exit_code);
  ASSERT_EQ(exit_code, 0) << out;
  EXPECT_NE(out.find("node 3: emergency 8130h life guard error or heartbeat error"),
            std::string::npos)
      << out;
  const std::string view = out.substr(0, out.rfind("node  name"));
  EXPECT_NE(view.find("retries  emcy"), std::string::npos) << view;
  // Node 3's row once the EMCY came: its count 1 in the last column.
  bool counted = false;
  std::istringstream lines(view);
  for (std::string line; std::getline(lines, line);) {
    const auto row = line.find("   3  axis_x");
    if (row == std::string::npos) continue;
    const std::string cut = line.substr(0, line.find("\x1b[K"));
    if (cut.size() >= 4 && cut.substr(cut.size() - 4) == "   1") counted = true;
  }
  EXPECT_TRUE(counted) << view;
}

TEST(Push, OnlyLeavesTheOtherNodesAlone) {
  // --only 3: nodes 2 and 4 get no NMT command at all (no reset, no start; CiA 302-2 §3.1 d
  // with keep-alive slaves: reset communication per node instead of 000#8200) and no SDO.
  ScratchDir dir;
  const std::string log = dir / "only.log";
  auto r = cfgmgr(dir, {"push", sample_network("nodelist.cpj"), "--bus", "sim:", "--only", "3",
                        "--candump", log});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string trace = tool_test::slurp(log);
  EXPECT_EQ(trace.find(" 000#8200"), std::string::npos) << trace;
  EXPECT_NE(trace.find(" 000#8203"), std::string::npos) << trace;
  for (const char* untouched : {" 000#8202", " 000#8102", " 000#0102", " 000#8204", " 000#0104",
                                " 000#0100", " 602#", " 604#"}) {
    EXPECT_EQ(trace.find(untouched), std::string::npos) << untouched;
  }
  EXPECT_NE(trace.find(" 603#"), std::string::npos);
  EXPECT_NE(trace.find(" 000#0103"), std::string::npos) << trace;
  EXPECT_EQ(r.err.find("node 2"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("node 4"), std::string::npos) << r.err;
}

TEST(Push, BadArgumentsExit2) {
  ScratchDir dir;
  const std::string cpj = sample_network("nodelist.cpj");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"push", cpj},  // no --bus, no --dry-run
        {"push", cpj, "--bus", "sim:?speed=1"},
        {"push", cpj, "--bus", "sim:", "--only", "0"},
        {"push", cpj, "--bus", "sim:", "--only", "5-3"},
        {"push", cpj, "--bus", "sim:", "--only", "9"},  // not in the network
        {"push", cpj, "--bus", "sim:", "--only", "3,x"},
        {"push", cpj, "--bus", "sim:", "--boot-time", "-1"},
        {"push", cpj, "--bus", "sim:", "--sdo-timeout", "0"},
        {"push", cpj, "--bus", "sim:", "--no-such-option"}}) {
    auto r = cfgmgr(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args.back() << ": " << r.err;
  }
  EXPECT_EQ(cfgmgr(dir, {"push", dir / "absent.cpj", "--bus", "sim:"}).exit_code, 3);
}

// The master takes only a positive SDO response timeout in whole us (MasterOptions::validate):
// one that rounds to 0 us is a usage error naming the option, before the bus.
TEST(Push, SdoTimeoutBelowOneMicrosecondIsAUsageError) {
  ScratchDir dir;
  const std::string cpj = sample_network("nodelist.cpj");
  for (const std::string value : {"0.0000001", "1e-300"}) {
    auto r = cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--sdo-timeout", value});
    EXPECT_EQ(r.exit_code, 2) << value << ": " << r.err;
    EXPECT_NE(r.err.find("--sdo-timeout"), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "") << "nothing ran";
  }
}

// --boot-time goes into 1F89h through the master's typed configuration: UNSIGNED32 ms (CiA
// 302-2 §6.11), so 5000000 s (5e9 ms) does not fit, and nothing reaches the bus.
TEST(Push, BootTimeBeyond1F89hIsAUsageErrorNamingTheObject) {
  ScratchDir dir;
  auto r = cfgmgr(
      dir, {"push", sample_network("nodelist.cpj"), "--bus", "sim:", "--boot-time", "5000000"});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--boot-time: boot time (1F89h) 5000000000 ms is above 4294967295 ms"),
            std::string::npos)
      << r.err;
}

// 1F89h is UNSIGNED32 ms where 0 means "tried again without end" (CiA 302-2 §6.11): a --boot-time
// beyond it, below its 1 ms (which would become that 0), or no number at all is a usage error
// before the bus (the start-up never begins), not a run with a boot time nobody asked for.
TEST(Push, BootTimeThatIs1F89hNoValueIsAUsageErrorBeforeTheBus) {
  ScratchDir dir;
  const std::string cpj = sample_network("nodelist.cpj");
  const std::vector<std::pair<std::string, std::string>> cases{
      {"1e300",
       "--boot-time: boot time (1F89h) 1e+303 ms is above 4294967295 ms; give at most "
       "4294967.295 s"},
      {"4294967.296", "--boot-time: boot time (1F89h) 4294967296 ms is above 4294967295 ms"},
      {"0.0001",
       "--boot-time: 0.0001 s is below 1 ms, the unit of boot time (1F89h), where 0 "
       "means 'tried again without end'"},
      {"nan", "--boot-time: nan is no time"}};
  for (const auto& [value, message] : cases) {
    const auto r = cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--boot-time", value});
    EXPECT_EQ(r.exit_code, 2) << value << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << value << ": " << r.err;
    EXPECT_EQ(r.err.find("NMT start-up began"), std::string::npos) << value << ": " << r.err;
  }
  // The largest 1F89h and the smallest run.
  for (const char* value : {"4294967.295", "0.001"}) {
    const auto r = cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--boot-time", value, "--only", "2"});
    EXPECT_EQ(r.exit_code, 0) << value << ": " << r.err;
  }
}

}  // namespace
