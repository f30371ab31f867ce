// cfgmgr push --report FILE.html read by a real browser: headless Chromium (Debian's
// chromium-headless-shell, tools/install-deps.sh) loads the page from disk, dumps the DOM it
// built (--dump-dom) and renders it to a PNG (--screenshot). The test reads what the page shows
// from that DOM: a lane and a table row per node, the failed node marked, its EMCY on its lane.
// Without Chromium it skips (fails under CI=true).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "generated_network.hpp"
#include "push_test_support.hpp"

namespace {

using push_test::cfgmgr;
using push_test::nodes_of;
using push_test::parse_json;
using tool_test::ScratchDir;
using tool_test::shell_quote;
using tool_test::slurp;

// Debian 12's chromium-headless-shell installs /usr/bin/chromium-headless-shell; the full
// browser (package chromium) does as well with --headless. CHROMIUM names another (and only
// that one: a CHROMIUM that is not there is a missing prerequisite). "" when there is none.
std::string chromium() {
  if (const char* named = std::getenv("CHROMIUM"); named != nullptr && *named != '\0') {
    return ::access(named, X_OK) == 0 ? named : "";
  }
  for (const char* path : {"/usr/bin/chromium-headless-shell", "/usr/bin/chromium"}) {
    if (::access(path, X_OK) == 0) return path;
  }
  return "";
}

// Runs Chromium headless on `page` with `args`; stdout to `out`. Its own profile in `dir`, no
// sandbox (tests run as root in CI, where Chromium refuses its sandbox), and no network.
int run_chromium(const std::string& browser, const ScratchDir& dir, const std::string& page,
                 const std::vector<std::string>& args, const std::string& out) {
  std::string command = "timeout 120 " + shell_quote(browser) +
                        " --headless --no-sandbox --disable-gpu --no-first-run"
                        " --user-data-dir=" +
                        shell_quote(dir / "chromium-profile") +
                        " --proxy-server=127.0.0.1:9 --window-size=1200,900";
  for (const auto& a : args) command += " " + shell_quote(a);
  command += " " + shell_quote("file://" + page) + " >" + shell_quote(out) + " 2>" +
             shell_quote(dir / "chromium.err");
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The element with `id` as Chromium serialised it: its start tag.
std::string start_tag(const std::string& dom, const std::string& id) {
  const auto at = dom.find("id=\"" + id + "\"");
  if (at == std::string::npos) return "";
  const auto open = dom.rfind('<', at);
  return dom.substr(open, dom.find('>', at) - open + 1);
}

// The element with `id` up to the first end tag `</tag>` after it (for elements without
// children of their kind).
std::string element(const std::string& dom, const std::string& id, const std::string& tag) {
  const auto at = dom.find("id=\"" + id + "\"");
  if (at == std::string::npos) return "";
  const auto begin = dom.rfind('<', at);
  const auto end = dom.find("</" + tag + ">", at);
  return end == std::string::npos ? "" : dom.substr(begin, end - begin);
}

// Node `id`'s lane of the timeline: from its group to the next lane or the end of the lanes.
std::string lane(const std::string& dom, int id) {
  const auto at = dom.find("id=\"lane-" + std::to_string(id) + "\"");
  if (at == std::string::npos) return "";
  const auto begin = dom.rfind('<', at);
  const auto end = std::min({dom.find("id=\"lane-", at + 1), dom.find("class=\"mark master", at),
                             dom.find("</svg>", at)});
  return end == std::string::npos ? "" : dom.substr(begin, end - begin);
}

// CiA 302-2 §3.3: node 3 is listed by the master as mandatory but has no device (no boot-up, no
// SDO answer): status B once the boot time (--boot-time 3) is over, after retries; nodes 1 and 2
// are configured, node 1 sends an EMCY 8130h (CiA 301 Table 21: life guard or heartbeat error)
// 300 ms into the run.
TEST(PushReport, ChromiumShowsEveryNodeAndMarksTheFailedOne) {
  const std::string browser = chromium();
  if (browser.empty()) {
    PREREQUISITE_MISSING(
        "Chromium not found (apt-get install chromium-headless-shell, or set "
        "CHROMIUM)");
  }
  ScratchDir dir;
  generated::NetworkSpec spec;
  spec.nodes = 2;
  spec.master_dcf = true;
  spec.absent = {3};
  const std::string cpj = generated::write_network(dir.path() / "net", spec);
  const std::string page = dir / "push.html";
  const std::string json = dir / "push.json";
  const auto r = cfgmgr(dir, {"push", cpj, "--bus", "sim:?emcy=1@300:8130:10", "--boot-time", "3",
                              "--report", page, "--json", json});
  ASSERT_EQ(r.exit_code, 4) << r.err;  // a mandatory node failed
  const auto nodes = nodes_of(parse_json(json));
  ASSERT_EQ(nodes.size(), 3U);
  ASSERT_EQ(nodes.at(3)->get("status")->string, "B");
  ASSERT_GE(nodes.at(3)->get("retries")->number, 1.0);
  ASSERT_TRUE(std::filesystem::exists(page)) << r.err;

  const std::string dom_file = dir / "dom.html";
  ASSERT_EQ(run_chromium(browser, dir, page, {"--dump-dom"}, dom_file), 0)
      << slurp(dir / "chromium.err");
  const std::string dom = slurp(dom_file);
  // The browser's own serialisation of what it parsed: the page title and every node.
  ASSERT_NE(dom.find("<title>cfgmgr push: "), std::string::npos) << dom.substr(0, 2000);
  for (int id : {1, 2, 3}) {
    const std::string row = start_tag(dom, "row-" + std::to_string(id));
    const std::string lane = start_tag(dom, "lane-" + std::to_string(id));
    ASSERT_FALSE(row.empty()) << "no table row for node " << id;
    ASSERT_FALSE(lane.empty()) << "no timeline lane for node " << id;
    const bool failed = id == 3;
    EXPECT_EQ(row.find("class=\"failed\"") != std::string::npos, failed) << row;
    EXPECT_EQ(lane.find("failed") != std::string::npos, failed) << lane;
  }
  // Node 3's row says its status, its lane its error marks and retries with the words of
  // Table 1; node 1's lane has its EMCY.
  const std::string row3 = element(dom, "row-3", "tr");
  EXPECT_NE(row3.find(">error B<"), std::string::npos) << row3;
  const std::string lane3 = lane(dom, 3);
  EXPECT_NE(lane3.find("class=\"m-error\""), std::string::npos);
  EXPECT_NE(lane3.find("class=\"m-retry\""), std::string::npos) << lane3;
  EXPECT_NE(lane3.find("boot error B"), std::string::npos);
  const std::string lane1 = lane(dom, 1);
  EXPECT_NE(lane1.find("class=\"m-emergency\""), std::string::npos) << lane1;
  EXPECT_NE(lane1.find("8130h"), std::string::npos) << lane1;
  EXPECT_NE(lane1.find("class=\"p-download\""), std::string::npos) << lane1;
  // The bus carried frames: the load curve's title says a peak above 0 %.
  const std::string load = element(dom, "bus-load", "g");
  EXPECT_NE(load.find("peak "), std::string::npos) << load;
  EXPECT_EQ(load.find("peak 0 %"), std::string::npos) << load;

  // The rendering: a PNG of the window's size (IHDR, ISO/IEC 15948 §11.2.2) with more than a
  // blank page in it.
  const std::string png = dir / "push.png";
  ASSERT_EQ(run_chromium(browser, dir, page, {"--screenshot=" + png, "--hide-scrollbars"},
                         dir / "screenshot.out"),
            0)
      << slurp(dir / "chromium.err");
  const std::string image = slurp(png);
  ASSERT_GT(image.size(), 24U);
  EXPECT_EQ(image.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const auto be32 = [&image](std::size_t at) {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<std::uint8_t>(image[at + i]);
    return v;
  };
  EXPECT_EQ(image.substr(12, 4), "IHDR");
  EXPECT_EQ(be32(16), 1200U);
  EXPECT_EQ(be32(20), 900U);
  // A white page compresses to about 5 kB at this size; lanes, curve and text do not.
  EXPECT_GT(image.size(), 20000U);
}

// A report that cannot be written is an I/O error before any bus work (exit 3).
TEST(PushReport, AnUnwritableReportIsExit3BeforeTheBus) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"push", tool_test::sample_network("nodelist.cpj"), "--bus",
                              "sim:", "--report", dir / "no-such-dir/push.html"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("push.html: error: cannot create"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("simulated device"), std::string::npos) << r.err;
}

// A write error at the end (a full disk: /dev/full refuses every write with ENOSPC) is exit 3
// with the file's name and the reason.
TEST(PushReport, AReportThatCannotBeWrittenAtTheEndIsExit3) {
  if (!std::filesystem::exists("/dev/full")) PREREQUISITE_MISSING("/dev/full is absent");
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"push", tool_test::sample_network("nodelist.cpj"), "--bus",
                              "sim:", "--report", "/dev/full"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("/dev/full: error: write error: No space left on device"), std::string::npos)
      << r.err;
}

// cfgmgr master --report writes the page when it stops: a lane per slave of the sample network.
TEST(PushReport, MasterWritesItsReportWhenItStops) {
  ScratchDir dir;
  const std::string page = dir / "master.html";
  const auto r = cfgmgr(dir, {"master", tool_test::sample_network("nodelist.cpj"), "--bus",
                              "sim:", "--run-for", "2", "--report", page});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string html = slurp(page);
  for (int id : {2, 3, 4}) {
    EXPECT_NE(html.find("<tr id=\"row-" + std::to_string(id) + "\" title=\"configured\">"),
              std::string::npos)
        << id;
  }
  EXPECT_NE(html.find("p-operational"), std::string::npos);  // started, §3.1 h
  EXPECT_NE(html.find("NMT start-up complete"), std::string::npos);
}

}  // namespace
