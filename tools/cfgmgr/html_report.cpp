// The --report page (html_report.hpp): HTML with inline CSS and SVG, drawn in bus time.
#include "html_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

namespace cfgmgr::report {
namespace {

// The drawing, in CSS pixels: node labels on the left, the time axis over the chart.
constexpr double kLabelWidth = 200;
constexpr double kChartWidth = 860;
constexpr double kRightMargin = 24;
constexpr double kAxisY = 28;
constexpr double kLoadTop = 40;
constexpr double kLoadHeight = 72;
constexpr double kLanesTop = kLoadTop + kLoadHeight + 22;
constexpr double kLaneHeight = 20;
constexpr double kBarHeight = 12;
constexpr std::size_t kNameInLabel = 20;  // longer names are cut in the lane label only

// Colours for phases and marks, one place: the legend shows the same classes.
constexpr std::string_view kStyle = R"(
body { font: 14px/1.4 sans-serif; color: #1f2328; margin: 24px; background: #fff; }
h1 { font-size: 20px; margin: 0 0 4px; }
h2 { font-size: 16px; margin: 24px 0 8px; }
p.facts { margin: 0; color: #57606a; }
p.outcome { font-weight: bold; margin: 8px 0; }
p.outcome.ok { color: #1a7f37; }
p.outcome.failed { color: #cf222e; }
.legend span { display: inline-block; margin: 0 14px 4px 0; white-space: nowrap; }
.legend svg { vertical-align: middle; margin-right: 4px; }
svg text { font: 11px sans-serif; fill: #1f2328; }
svg text.failed { fill: #cf222e; font-weight: bold; }
svg .axis line { stroke: #d0d7de; }
svg .axis text { fill: #57606a; }
svg .lane-bg { fill: #f6f8fa; }
svg .failed .lane-bg { fill: #ffebe9; }
svg .load-area { fill: #8fb8de; stroke: #0969da; stroke-width: 1; }
svg .load-frame { fill: none; stroke: #d0d7de; }
svg .entries { stroke: #0b3d1a; stroke-width: 0.6; }
.p-bootup { fill: #afb8c1; }
.p-identify { fill: #54aeff; }
.p-program { fill: #bf8700; }
.p-verify { fill: #80ccff; }
.p-restore { fill: #d8b9ff; }
.p-download { fill: #4ac26b; }
.p-save { fill: #2da44e; }
.p-application { fill: #8250df; }
.p-errorcontrol { fill: #fff8c5; stroke: #d4a72c; stroke-width: 0.5; }
.p-retrywait { fill: #ffd8b5; }
.p-operational { fill: #dafbe1; stroke: #1a7f37; stroke-width: 0.5; }
.m-bootup { stroke: #24292f; stroke-width: 1.5; }
.m-error { fill: #cf222e; stroke: #fff; stroke-width: 0.8; }
.m-retry { fill: #fb8f44; stroke: #953800; stroke-width: 0.8; }
.m-emergency { fill: #8250df; stroke: #fff; stroke-width: 0.8; }
.m-errorframe { stroke: #cf222e; stroke-width: 1.5; }
.m-master { stroke: #57606a; stroke-width: 1; stroke-dasharray: 4 3; }
table { border-collapse: collapse; margin-top: 4px; }
th, td { border-bottom: 1px solid #d0d7de; padding: 3px 10px; text-align: left; vertical-align: top; }
th { background: #f6f8fa; }
td.n { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.failed td { background: #ffebe9; }
tr.failed td.result { color: #cf222e; font-weight: bold; }
)";

std::string number(double value, int decimals = 1) {
  char text[48];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return text;
}

std::string_view phase_class(PhaseKind kind) {
  switch (kind) {
    case PhaseKind::BootUp:
      return "p-bootup";
    case PhaseKind::Identify:
      return "p-identify";
    case PhaseKind::Program:
      return "p-program";
    case PhaseKind::Verify:
      return "p-verify";
    case PhaseKind::Restore:
      return "p-restore";
    case PhaseKind::Download:
      return "p-download";
    case PhaseKind::Save:
      return "p-save";
    case PhaseKind::Application:
      return "p-application";
    case PhaseKind::ErrorControl:
      return "p-errorcontrol";
    case PhaseKind::RetryWait:
      return "p-retrywait";
    case PhaseKind::Operational:
      return "p-operational";
  }
  return "p-bootup";
}

std::string_view phase_words(PhaseKind kind) {
  switch (kind) {
    case PhaseKind::BootUp:
      return "boot-up awaited";
    case PhaseKind::Identify:
      return "identity (1000h, 1018h)";
    case PhaseKind::Program:
      return "program download (1F50h)";
    case PhaseKind::Verify:
      return "configuration check (1020h)";
    case PhaseKind::Restore:
      return "restore (1011h)";
    case PhaseKind::Download:
      return "configuration download";
    case PhaseKind::Save:
      return "save (1010h)";
    case PhaseKind::Application:
      return "application step";
    case PhaseKind::ErrorControl:
      return "first heartbeat awaited";
    case PhaseKind::RetryWait:
      return "waiting to retry";
    case PhaseKind::Operational:
      return "operational";
  }
  return "";
}

// A step of 1, 2 or 5 times a power of ten that cuts `span` into about 8 pieces.
double tick_step(double span) {
  if (span <= 0) return 1;
  const double rough = span / 8;
  const double power = std::pow(10.0, std::floor(std::log10(rough)));
  for (const double m : {1.0, 2.0, 5.0}) {
    if (rough <= m * power) return m * power;
  }
  return 10 * power;
}

class Drawing {
 public:
  explicit Drawing(double duration_s) : duration_s_(duration_s > 0 ? duration_s : 1) {}
  double x(double at_s) const {
    return kLabelWidth + std::clamp(at_s / duration_s_, 0.0, 1.0) * kChartWidth;
  }

 private:
  double duration_s_;
};

std::string title(std::string_view text) {
  return "<title>" + escape_html(text) + "</title>";
}

// A mark at `x` on a lane whose middle is at `mid`.
std::string mark_svg(const Mark& m, double x, double mid) {
  const std::string xs = number(x);
  std::string shape;
  switch (m.kind) {
    case MarkKind::BootUp:
      shape = "<line class=\"m-bootup\" x1=\"" + xs + "\" y1=\"" + number(mid - 8) + "\" x2=\"" +
              xs + "\" y2=\"" + number(mid + 8) + "\"/>";
      break;
    case MarkKind::Error:  // a diamond
      shape = "<polygon class=\"m-error\" points=\"" + number(x) + "," + number(mid - 7) + " " +
              number(x + 6) + "," + number(mid) + " " + number(x) + "," + number(mid + 7) + " " +
              number(x - 6) + "," + number(mid) + "\"/>";
      break;
    case MarkKind::Retry:
      shape = "<circle class=\"m-retry\" cx=\"" + xs + "\" cy=\"" + number(mid) + "\" r=\"4.5\"/>";
      break;
    case MarkKind::Emergency:  // a triangle pointing down
      shape = "<polygon class=\"m-emergency\" points=\"" + number(x - 6) + "," + number(mid - 6) +
              " " + number(x + 6) + "," + number(mid - 6) + " " + number(x) + "," +
              number(mid + 6) + "\"/>";
      break;
    case MarkKind::ErrorFrame:
      shape = "<line class=\"m-errorframe\" x1=\"" + xs + "\" y1=\"" + number(mid - 6) +
              "\" x2=\"" + xs + "\" y2=\"" + number(mid + 6) + "\"/>";
      break;
    case MarkKind::Master:
      break;  // drawn across the lanes by the caller
  }
  return "<g class=\"mark\">" + title(m.title) + shape + "</g>";
}

std::string legend() {
  std::string out = "<div class=\"legend\">";
  for (const PhaseKind k :
       {PhaseKind::BootUp, PhaseKind::Identify, PhaseKind::Program, PhaseKind::Verify,
        PhaseKind::Restore, PhaseKind::Download, PhaseKind::Save, PhaseKind::Application,
        PhaseKind::ErrorControl, PhaseKind::RetryWait, PhaseKind::Operational}) {
    out += "<span><svg width=\"14\" height=\"12\"><rect class=\"" + std::string(phase_class(k)) +
           "\" x=\"0\" y=\"1\" width=\"14\" height=\"10\"/></svg>" + escape_html(phase_words(k)) +
           "</span>";
  }
  const auto key = [](MarkKind kind, std::string_view words) {
    const Mark m{kind, 0, std::string(words)};
    return "<span><svg width=\"16\" height=\"16\">" + mark_svg(m, 8, 8) + "</svg>" +
           escape_html(words) + "</span>";
  };
  out += key(MarkKind::BootUp, "boot-up message");
  out += key(MarkKind::Error, "error");
  out += key(MarkKind::Retry, "retry");
  out += key(MarkKind::Emergency, "EMCY");
  out += key(MarkKind::ErrorFrame, "error frame");
  return out + "</div>\n";
}

std::string timeline(const ReportData& data) {
  const Drawing d(data.duration_s);
  const double height = kLanesTop + kLaneHeight * static_cast<double>(data.nodes.size()) + 8;
  const double width = kLabelWidth + kChartWidth + kRightMargin;
  std::string out = "<svg class=\"timeline\" width=\"" + number(width, 0) + "\" height=\"" +
                    number(height, 0) + "\" viewBox=\"0 0 " + number(width, 0) + " " +
                    number(height, 0) + "\" role=\"img\">\n";
  out += title("timeline of " + std::to_string(data.nodes.size()) + " nodes over " +
               number(data.duration_s, 3) + " s of bus time");
  // The time axis: a line and a label per tick, across every lane.
  const double step = tick_step(data.duration_s);
  const int decimals = step >= 1 ? 0 : step >= 0.1 ? 1 : step >= 0.01 ? 2 : 3;
  out += "<g class=\"axis\">";
  for (int i = 0; i * step <= data.duration_s + step * 1e-9 && i < 100; ++i) {
    const double t = i * step;
    const std::string x = number(d.x(t));
    out += "<line x1=\"" + x + "\" y1=\"" + number(kAxisY + 4) + "\" x2=\"" + x + "\" y2=\"" +
           number(height - 4) + "\"/><text x=\"" + x + "\" y=\"" + number(kAxisY) +
           "\" text-anchor=\"middle\">" + number(t, decimals) + " s</text>";
  }
  out += "</g>\n";

  // The bus load: a step curve of the samples, 0 at the bottom of its frame, 100 % at the top.
  const double base = kLoadTop + kLoadHeight;
  double peak = 0;
  double bits_time = 0;
  std::string area = "M" + number(d.x(0)) + "," + number(base);
  for (const auto& s : data.load) {
    const double y = base - std::clamp(s.load, 0.0, 1.0) * kLoadHeight;
    area += " L" + number(d.x(s.begin_s)) + "," + number(y) + " L" + number(d.x(s.end_s)) + "," +
            number(y);
    peak = std::max(peak, s.load);
    bits_time += s.load * (s.end_s - s.begin_s);
  }
  area += " L" + number(d.x(data.load.empty() ? 0 : data.load.back().end_s)) + "," + number(base) +
          " Z";
  const double mean = data.duration_s > 0 ? bits_time / data.duration_s : 0;
  const double bucket_ms =
      data.load.empty() ? 0 : (data.load[0].end_s - data.load[0].begin_s) * 1e3;
  out +=
      "<g id=\"bus-load\">" +
      title("bus load at " + std::to_string(data.bitrate_bps) + " bit/s" +
            (data.bitrate_assumed ? " (assumed)" : "") + ": peak " + number(peak * 100, 0) +
            " %, mean " + number(mean * 100, 1) + " % (" + number(bucket_ms, 1) + " ms buckets)") +
      "<rect class=\"load-frame\" x=\"" + number(kLabelWidth) + "\" y=\"" + number(kLoadTop) +
      "\" width=\"" + number(kChartWidth) + "\" height=\"" + number(kLoadHeight) + "\"/>" +
      "<path class=\"load-area\" d=\"" + area + "\"/>" + "<text x=\"8\" y=\"" +
      number(kLoadTop + 14) + "\">bus load</text><text x=\"8\" y=\"" + number(kLoadTop + 28) +
      "\">peak " + number(peak * 100, 0) + " %, mean " + number(mean * 100, 1) +
      " %</text><text x=\"" + number(kLabelWidth - 4) + "\" y=\"" + number(kLoadTop + 10) +
      "\" text-anchor=\"end\">100 %</text><text x=\"" + number(kLabelWidth - 4) + "\" y=\"" +
      number(base) + "\" text-anchor=\"end\">0 %</text>";
  for (const auto& m : data.bus_marks) out += mark_svg(m, d.x(m.at_s), base - 6);
  out += "</g>\n";

  // A lane per node.
  for (std::size_t i = 0; i < data.nodes.size(); ++i) {
    const NodeRow& n = data.nodes[i];
    const double top = kLanesTop + kLaneHeight * static_cast<double>(i);
    const double mid = top + kLaneHeight / 2;
    const std::string id = std::to_string(n.node_id);
    std::string label =
        id + "  " +
        (n.name.size() > kNameInLabel ? n.name.substr(0, kNameInLabel - 3) + "..." : n.name);
    out += "<g class=\"lane" + std::string(n.failed ? " failed" : "") + "\" id=\"lane-" + id +
           "\" data-node=\"" + id + "\">" +
           title("node " + id + (n.name.empty() ? "" : " (" + n.name + ")") + ": " + n.result +
                 (n.message.empty() || n.message == n.result ? "" : ": " + n.message)) +
           "<rect class=\"lane-bg\" x=\"0\" y=\"" + number(top + 1) + "\" width=\"" +
           number(width) + "\" height=\"" + number(kLaneHeight - 2) + "\"/>" +
           "<text x=\"8\" y=\"" + number(mid + 4) + "\"" + (n.failed ? " class=\"failed\"" : "") +
           ">" + escape_html(label) + (n.failed ? " \u2716" : "") + "</text>";
    for (const Phase& p : n.phases) {
      const double x0 = d.x(p.begin_s);
      const double x1 = std::max(d.x(p.end_s), x0 + 0.8);  // a short step stays visible
      out += "<g class=\"phase\">" + title(p.title) + "<rect class=\"" +
             std::string(phase_class(p.kind)) + "\" x=\"" + number(x0) + "\" y=\"" +
             number(mid - kBarHeight / 2) + "\" width=\"" + number(x1 - x0) + "\" height=\"" +
             number(kBarHeight) + "\"/>";
      if (!p.entries_s.empty()) {
        std::string ticks;
        for (const double t : p.entries_s) {
          ticks +=
              "M" + number(d.x(t)) + "," + number(mid - kBarHeight / 2) + "v" + number(kBarHeight);
        }
        out += "<path class=\"entries\" d=\"" + ticks + "\"/>";
      }
      out += "</g>";
    }
    for (const Mark& m : n.marks) out += mark_svg(m, d.x(m.at_s), mid);
    out += "</g>\n";
  }

  // The master's own moments, across the lanes.
  for (const Mark& m : data.master_marks) {
    const std::string x = number(d.x(m.at_s));
    out += "<g class=\"mark master\">" + title(m.title) + "<line class=\"m-master\" x1=\"" + x +
           "\" y1=\"" + number(kLoadTop + kLoadHeight + 4) + "\" x2=\"" + x + "\" y2=\"" +
           number(height - 4) + "\"/><text x=\"" + x + "\" y=\"" +
           number(kLoadTop + kLoadHeight + 16) + "\" text-anchor=\"end\">" + escape_html(m.title) +
           "&#160;</text></g>\n";
  }
  return out + "</svg>\n";
}

std::string result_table(const ReportData& data) {
  std::string out =
      "<table id=\"results\"><thead><tr><th>node</th><th>name</th><th>result</th>"
      "<th>mandatory</th><th>entries</th><th>EMCY</th><th>retries</th><th>time</th>"
      "<th>message</th></tr></thead><tbody>\n";
  for (const NodeRow& n : data.nodes) {
    const std::string id = std::to_string(n.node_id);
    out += "<tr id=\"row-" + id + "\"" + (n.failed ? " class=\"failed\"" : "") + " title=\"" +
           escape_html(n.result) + "\"><td class=\"n\">" + id + "</td><td>" + escape_html(n.name) +
           "</td><td class=\"result\">" + escape_html(n.result) + "</td><td>" +
           (n.mandatory ? "yes" : "no") + "</td><td class=\"n\">" + std::to_string(n.entries) +
           "</td><td class=\"n\">" + std::to_string(n.emergencies) + "</td><td class=\"n\">" +
           std::to_string(n.retries) + "</td><td class=\"n\">" + number(n.seconds, 3) +
           " s</td><td>" + escape_html(n.message == n.result ? "" : n.message) + "</td></tr>\n";
  }
  return out + "</tbody></table>\n";
}

}  // namespace

std::string escape_html(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string html_report(const ReportData& data) {
  const std::string heading = "cfgmgr " + data.tool + ": " + data.network;
  std::size_t failed = 0;
  for (const auto& n : data.nodes) failed += n.failed ? 1 : 0;
  std::string out = "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>" +
                    escape_html(heading) + "</title>\n<style>" + std::string(kStyle) +
                    "</style></head>\n<body>\n";
  out += "<h1>" + escape_html(heading) + "</h1>\n<p class=\"facts\">bus " + escape_html(data.bus) +
         ", " + std::to_string(data.bitrate_bps) + " bit/s" +
         (data.bitrate_assumed ? " (assumed; give --report-bitrate)" : "") + ", " +
         number(data.duration_s, 3) + " s of bus time, " + std::to_string(data.frames) +
         " frames, " + std::to_string(data.nodes.size()) + " nodes, " + std::to_string(failed) +
         " failed</p>\n";
  out += "<p class=\"outcome " + std::string(data.ok ? "ok" : "failed") + "\" id=\"outcome\">" +
         escape_html(data.outcome) + "</p>\n";
  out += "<h2>Timeline</h2>\n" + legend() + timeline(data);
  out += "<h2>Results</h2>\n" + result_table(data);
  return out + "</body></html>\n";
}

}  // namespace cfgmgr::report
