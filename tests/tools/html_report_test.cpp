// The --report page of push and master (tools/cfgmgr/html_report.hpp) from its data, and the
// data from a run's events and frames (report_recorder.hpp). The page as a browser shows it is
// push_report_test.cpp's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <string>
#include <vector>

#include "html_report.hpp"
#include "nmt/master/master_event.hpp"
#include "nmt/protocol/frame_bits.hpp"
#include "report_recorder.hpp"

namespace {

using cfgmgr::ReportRecorder;
using cfgmgr::report::MarkKind;
using cfgmgr::report::NodeRow;
using cfgmgr::report::PhaseKind;
using cfgmgr::report::ReportData;

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

// Three nodes, node 2 failed with status B after a retry, node 3 with an EMCY.
ReportData sample() {
  ReportData d;
  d.tool = "push";
  d.network = "nodelist.cpj";
  d.bus = "sim:";
  d.ok = false;
  d.outcome = "NMT start-up halted";
  d.duration_s = 4.0;
  d.bitrate_bps = 500000;
  for (int id = 1; id <= 3; ++id) {
    NodeRow n;
    n.node_id = static_cast<std::uint8_t>(id);
    n.name = "io" + std::to_string(id);
    n.result = "configured";
    n.phases.push_back({PhaseKind::Identify, 0.1, 0.2, "identify (try 1)", {}});
    n.phases.push_back({PhaseKind::Download, 0.2, 0.5, "download", {0.3, 0.4}});
    d.nodes.push_back(n);
  }
  d.nodes[1].result = "error B";
  d.nodes[1].failed = true;
  d.nodes[1].message = "no response received for upload request of object 1000h";
  d.nodes[1].marks.push_back({MarkKind::Error, 1.0, "node 2: boot error B"});
  d.nodes[1].marks.push_back({MarkKind::Retry, 2.0, "try 2 of the boot began"});
  d.nodes[2].marks.push_back({MarkKind::Emergency, 0.6, "node 3: emergency 8130h"});
  d.load.push_back({0.0, 2.0, 0.5});
  d.load.push_back({2.0, 4.0, 0.25});
  d.bus_marks.push_back({MarkKind::ErrorFrame, 3.0, "error frame"});
  d.master_marks.push_back({MarkKind::Master, 3.5, "NMT start-up halted"});
  return d;
}

TEST(HtmlReport, IsOnePageWithNoScriptAndNothingFetched) {
  const std::string page = lower(cfgmgr::report::html_report(sample()));
  EXPECT_EQ(page.rfind("<!doctype html>", 0), 0U);
  // Readable without JavaScript and offline: no script, no URL of any kind, no external
  // style sheet, font or image.
  for (const char* banned : {"<script", "http:", "https:", "url(", "@import", "@font-face",
                             " src=", " href=", "<link", "<img", "<iframe", "javascript:"}) {
    EXPECT_EQ(page.find(banned), std::string::npos) << banned;
  }
  EXPECT_NE(page.find("<style>"), std::string::npos);
  EXPECT_NE(page.find("<svg"), std::string::npos);
}

TEST(HtmlReport, HasALaneAndATableRowPerNodeAndMarksTheFailedOne) {
  const std::string page = cfgmgr::report::html_report(sample());
  for (const char* id : {"1", "2", "3"}) {
    EXPECT_NE(page.find(std::string("id=\"lane-") + id + "\""), std::string::npos) << id;
    EXPECT_NE(page.find(std::string("<tr id=\"row-") + id + "\""), std::string::npos) << id;
  }
  EXPECT_NE(page.find("<tr id=\"row-2\" class=\"failed\" title=\"error B\">"), std::string::npos);
  EXPECT_NE(page.find("<g class=\"lane failed\" id=\"lane-2\""), std::string::npos);
  EXPECT_EQ(page.find("class=\"failed\" title=\"configured\""), std::string::npos);
  EXPECT_EQ(page.find("lane failed\" id=\"lane-1\""), std::string::npos);
  EXPECT_NE(page.find("no response received for upload request of object 1000h"),
            std::string::npos);
  // The marks carry their words for a pointer over them.
  EXPECT_NE(page.find("<title>node 3: emergency 8130h</title>"), std::string::npos);
  EXPECT_NE(page.find("<title>try 2 of the boot began</title>"), std::string::npos);
  EXPECT_NE(page.find("<title>error frame</title>"), std::string::npos);
}

TEST(HtmlReport, SaysThePeakAndMeanBusLoad) {
  // 50 % over the first 2 s, 25 % over the next 2 s: peak 50 %, mean 37.5 %.
  const std::string page = cfgmgr::report::html_report(sample());
  EXPECT_NE(page.find("peak 50 %, mean 37.5 %"), std::string::npos);
}

TEST(HtmlReport, EscapesTheTextsItIsGiven) {
  ReportData d = sample();
  d.network = "a<b>&c.cpj";
  d.nodes[0].name = "<script>alert('x')</script>";
  d.nodes[0].message = "\"quoted\" & <tagged>";
  const std::string page = cfgmgr::report::html_report(d);
  EXPECT_EQ(page.find("<script"), std::string::npos);
  EXPECT_EQ(page.find("a<b>"), std::string::npos);
  EXPECT_NE(page.find("a&lt;b&gt;&amp;c.cpj"), std::string::npos);
  EXPECT_NE(page.find("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;"), std::string::npos);
  EXPECT_NE(page.find("&quot;quoted&quot; &amp; &lt;tagged&gt;"), std::string::npos);
  EXPECT_EQ(cfgmgr::report::escape_html("<&>\"'"), "&lt;&amp;&gt;&quot;&#39;");
}

// --- the recorder --------------------------------------------------------------------------

nmt::TimePoint at_ms(int ms) {
  return nmt::TimePoint{} + std::chrono::milliseconds(ms);
}

nmt::MasterEvent step(int node, nmt::BootStep s, int ms, unsigned boot_try) {
  nmt::MasterEvent e{nmt::MasterEvent::Kind::BootStepChanged};
  e.node_id = cfg::NodeId::from(static_cast<std::uint8_t>(node));
  e.step = s;
  e.at = at_ms(ms);
  e.boot_try = boot_try;
  return e;
}

TEST(ReportRecorder, MakesPhasesFromBootStepsAndTicksFromWrittenEntries) {
  ReportRecorder recorder({{4, "drive", true}}, 500000, false);
  recorder.observe(step(4, nmt::BootStep::AwaitBootUp, 0, 1));
  recorder.observe(step(4, nmt::BootStep::Identify, 100, 1));
  auto download = step(4, nmt::BootStep::Download, 200, 1);
  download.total = 2;
  recorder.observe(download);
  for (int i = 1; i <= 2; ++i) {
    auto written = step(4, nmt::BootStep::Download, 200 + 10 * i, 1);
    written.entry_written = true;
    written.written = static_cast<std::size_t>(i);
    written.total = 2;
    recorder.observe(written);
  }
  recorder.observe(step(4, nmt::BootStep::Save, 250, 1));
  nmt::MasterEvent booted{nmt::MasterEvent::Kind::SlaveBooted};
  booted.node_id = cfg::NodeId::from(4);
  booted.at = at_ms(300);
  booted.configured = true;
  booted.written = 2;
  recorder.observe(booted);

  const ReportData d = recorder.finish(at_ms(0), at_ms(1000), {});
  ASSERT_EQ(d.nodes.size(), 1U);
  const NodeRow& n = d.nodes[0];
  EXPECT_EQ(n.result, "configured");
  EXPECT_FALSE(n.failed);
  EXPECT_TRUE(n.mandatory);
  EXPECT_EQ(n.entries, 2U);
  EXPECT_DOUBLE_EQ(n.seconds, 0.3);
  ASSERT_EQ(n.phases.size(), 4U);
  EXPECT_EQ(n.phases[0].kind, PhaseKind::BootUp);
  EXPECT_EQ(n.phases[1].kind, PhaseKind::Identify);
  EXPECT_DOUBLE_EQ(n.phases[1].begin_s, 0.1);
  EXPECT_EQ(n.phases[2].kind, PhaseKind::Download);
  EXPECT_DOUBLE_EQ(n.phases[2].begin_s, 0.2);
  EXPECT_DOUBLE_EQ(n.phases[2].end_s, 0.25);
  EXPECT_EQ(n.phases[2].entries_s, (std::vector<double>{0.21, 0.22}));
  EXPECT_EQ(n.phases[2].title, "configuration download: 2 of 2 entries written (try 1)");
  EXPECT_EQ(n.phases[3].kind, PhaseKind::Save);
  EXPECT_DOUBLE_EQ(n.phases[3].end_s, 0.3);
  EXPECT_DOUBLE_EQ(d.duration_s, 1.0);
}

// CiA 302-2 §3.3: a mandatory slave that does not answer (B) is tried again; each try after the
// first is a retry on its lane, the error a mark, the wait in between a phase.
TEST(ReportRecorder, MarksErrorsAndRetriesOfABootThatIsTriedAgain) {
  ReportRecorder recorder({{3, "", true}}, 500000, false);
  recorder.observe(step(3, nmt::BootStep::Identify, 0, 1));
  nmt::MasterEvent error{nmt::MasterEvent::Kind::BootError};
  error.node_id = cfg::NodeId::from(3);
  error.at = at_ms(500);
  error.error = nmt::BootError::B;
  error.boot_try = 1;
  recorder.observe(error);
  recorder.observe(step(3, nmt::BootStep::Identify, 1500, 2));
  error.at = at_ms(2000);
  error.boot_try = 2;
  error.final = true;
  recorder.observe(error);

  const NodeRow n = recorder.finish(at_ms(0), at_ms(3000), {}).nodes.at(0);
  EXPECT_TRUE(n.failed);
  EXPECT_EQ(n.result, "error B");
  EXPECT_EQ(n.retries, 1U);
  std::vector<MarkKind> kinds;
  for (const auto& m : n.marks) kinds.push_back(m.kind);
  EXPECT_EQ(kinds, (std::vector<MarkKind>{MarkKind::Error, MarkKind::Retry, MarkKind::Error}));
  ASSERT_EQ(n.phases.size(), 3U);
  EXPECT_EQ(n.phases[1].kind, PhaseKind::RetryWait);
  EXPECT_DOUBLE_EQ(n.phases[1].begin_s, 0.5);
  EXPECT_DOUBLE_EQ(n.phases[1].end_s, 1.5);
}

// The load of a bucket is the bits of the frames on the bus in it (ISO 11898-1 length with stuff
// bits, nmt::frame_bits) over what the bit rate carries in it.
TEST(ReportRecorder, TakesTheBusLoadFromTheFramesBits) {
  ReportRecorder recorder({}, 500000, true);
  nmt::CanFrame frame{};
  frame.id = 0x601;
  frame.dlc = 8;
  const unsigned bits = nmt::frame_bits(frame).total();
  ASSERT_LT(bits, 500U);  // shorter than a millisecond at 500 kbit/s
  for (int ms = 1; ms <= 100; ++ms) recorder.on_frame(frame, at_ms(ms));
  const ReportData d = recorder.finish(at_ms(0), at_ms(100), {});
  EXPECT_EQ(d.frames, 100U);
  EXPECT_TRUE(d.bitrate_assumed);
  ASSERT_GE(d.load.size(), 99U);
  // One frame a millisecond: each 1 ms bucket holds one frame's bits of the 500 it can carry.
  EXPECT_DOUBLE_EQ(d.load[0].end_s - d.load[0].begin_s, 0.001);
  EXPECT_DOUBLE_EQ(d.load[0].load, bits / 500.0);
  EXPECT_DOUBLE_EQ(d.load[98].load, bits / 500.0);
}

// A frame's bits go to the time it was on the bus: back to back frames fill the bus to 100 %,
// never more.
TEST(ReportRecorder, SharesAFramesBitsBetweenTheBucketsItSpans) {
  ReportRecorder recorder({}, 125000, false);
  nmt::CanFrame frame{};
  frame.id = 0x601;
  frame.dlc = 8;
  const unsigned bits = nmt::frame_bits(frame).total();  // 8 us a bit at 125 kbit/s
  nmt::TimePoint end = at_ms(0);
  for (int i = 0; i < 200; ++i) {
    end += std::chrono::microseconds(bits * 8);
    recorder.on_frame(frame, end);
  }
  const ReportData d = recorder.finish(at_ms(0) - std::chrono::microseconds(bits * 8), end, {});
  double peak = 0;
  for (std::size_t i = 0; i + 1 < d.load.size(); ++i) peak = std::max(peak, d.load[i].load);
  EXPECT_NEAR(peak, 1.0, 1e-9);
}

TEST(ReportRecorder, KeepsALongRunToABoundedNumberOfBuckets) {
  ReportRecorder recorder({}, 125000, false);
  nmt::CanFrame frame{};
  frame.id = 0x701;
  frame.dlc = 1;
  for (int s = 0; s < 3600; ++s) recorder.on_frame(frame, at_ms(s * 1000));
  const ReportData d = recorder.finish(at_ms(0), at_ms(3600 * 1000), {});
  EXPECT_LE(d.load.size(), 512U);
  double bits = 0;
  for (const auto& sample : d.load) bits += sample.load * (sample.end_s - sample.begin_s) * 125000;
  // Merging buckets keeps every bit.
  EXPECT_NEAR(bits, 3600.0 * nmt::frame_bits(frame).total(), 1e-3);
}

TEST(ReportRecorder, MarksErrorFramesOnTheBus) {
  ReportRecorder recorder({}, 125000, false);
  nmt::CanFrame frame{};
  frame.error = true;
  frame.id = 0x004;  // CAN_ERR_CRTL (linux/can/error.h)
  recorder.on_frame(frame, at_ms(250));
  const ReportData d = recorder.finish(at_ms(0), at_ms(1000), {});
  ASSERT_EQ(d.bus_marks.size(), 1U);
  EXPECT_EQ(d.bus_marks[0].kind, MarkKind::ErrorFrame);
  EXPECT_DOUBLE_EQ(d.bus_marks[0].at_s, 0.25);
}

TEST(ReportRecorder, MarksAnErrorStormsFirstFramesAndCountsTheRest) {
  ReportRecorder recorder({}, 125000, false);
  nmt::CanFrame frame{};
  frame.error = true;
  frame.id = 0x004;
  const std::size_t storm = ReportRecorder::kMaxErrorFrameMarks + 50;
  for (int i = 0; i < static_cast<int>(storm); ++i) recorder.on_frame(frame, at_ms(i));
  const ReportData d = recorder.finish(at_ms(0), at_ms(1000), {});
  ASSERT_EQ(d.bus_marks.size(), ReportRecorder::kMaxErrorFrameMarks);
  EXPECT_EQ(d.frames, storm);  // every frame still counts to the load
  EXPECT_NE(d.bus_marks.back().title.find("; 50 more error frames after it, not marked"),
            std::string::npos)
      << d.bus_marks.back().title;
}

}  // namespace
