// cfgmgr push NETWORK --bus URL: commission a network in one run. It is `cfgmgr master` (the same
// NmtMaster, network and buses, master_run.hpp) that ends when NMT start-up has ended and every
// selected slave was tried once, then reports per node what happened (a table, and --json). With
// --dry-run it prints the writes the master would download instead, without a bus.
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/download_order.hpp"
#include "cfg/hex.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "commands.hpp"
#include "master_run.hpp"
#include "nmt/master/master_event_text.hpp"
#include "report_recorder.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "push";
/// --boot-time when neither it nor the master DCF's 1F89h (0: without end) gives one. CiA 302-2
/// §3.3: a mandatory slave that does not answer (status B) is tried again until it elapses.
constexpr double kDefaultBootTimeS = 10.0;
/// How long the run may take beyond the boot time before push gives up (downloads included).
constexpr double kRunMarginS = 60.0;

struct PushCliOptions : NetworkRunArgs {
  std::string json;
  std::optional<double> boot_time_s;
  bool dry_run = false;
  std::string only;
  bool force = false;
  bool no_start = false;
  bool no_save = false;
  double sdo_timeout_s = 0.5;
  unsigned retries = 2;
  RunTraces traces;
  LssRunArgs lss;
  HtmlReportArgs report;
};

/// NoConfiguration: booted, but the master had nothing to configure the node with (a master
/// DCF whose 1F22h sub N is empty), which is no "skipped: up to date".
enum class Result : std::uint8_t { Pending, Configured, Skipped, NoConfiguration, Error };

struct NodeReport {
  std::uint8_t node_id = 0;
  std::string name;
  bool mandatory = false;
  Result result = Result::Pending;
  /// The CiA 302-2 Table 1 letter ("C"), or for a boot that did not end before the run did
  /// "not_tried" (it never began) or "unfinished"; empty when configured or skipped.
  std::string status;
  std::string message;
  std::string last_try;     ///< "B: words" of the last try that failed and was repeated
  std::size_t entries = 0;  ///< configuration entries written (also when the boot then failed)
  std::size_t total = 0;    ///< entries to write, once the download was planned
  std::uint64_t bytes = 0;
  /// Software update (DSP 302 §9): image bytes confirmed of total, while UpdateSoftware runs.
  std::uint64_t program_bytes = 0;
  std::uint64_t program_total = 0;
  std::optional<nmt::TimePoint> program_began;
  nmt::TimePoint program_at{};
  unsigned retries = 0;   ///< boot tries repeated (CiA 302-2 §3.3)
  unsigned boot_try = 0;  ///< the try the last boot step belonged to (MasterEvent::boot_try)
  nmt::BootStep step = nmt::BootStep::Idle;
  std::optional<nmt::NmtState> state;  ///< as the master knows it
  std::optional<nmt::TimePoint> began;
  nmt::TimePoint ended{};
  bool lss_assigned = false;  ///< --lss: the node-ID was given to its device by LSS in this run
  /// EMCYs the node sent with an error code (CiA 301 §7.2.7; error resets not counted), those
  /// a flood's summary counted included.
  std::uint64_t emergencies = 0;
};

std::string_view result_name(Result result) {
  switch (result) {
    case Result::Configured:
      return "configured";
    case Result::Skipped:
      return "skipped";
    case Result::NoConfiguration:
      return "no_configuration";
    case Result::Pending:
    case Result::Error:
      break;
  }
  return "error";
}

// The slaves push boots: every node of the network, or those of --only (each must exist).
std::vector<const cfg::NetworkNode*> selected_nodes(const cfg::Network& network,
                                                    const PushCliOptions& options) {
  std::vector<const cfg::NetworkNode*> out;
  if (options.only.empty()) {
    for (const auto& node : network.nodes) out.push_back(&node);
    return out;
  }
  for (const std::uint8_t id : parse_only(kTool, options.only)) {
    const cfg::NetworkNode* node = network.find(*cfg::NodeId::from(id));
    if (node == nullptr) {
      fail_command(kTool, tools::kExitUsage,
                   "--only: node " + std::to_string(id) + " is not in " + options.network);
    }
    out.push_back(node);
  }
  return out;
}

std::string node_label(const cfg::NetworkNode& node) {
  return "node " + std::to_string(node.node_id.value()) +
         (node.name.empty() ? "" : " (" + node.name + ")");
}

// --dry-run: per node the configuration writes in the order the master downloads them
// (cfg::plan_download, CiA 302-2 §3.5 d), then what the master adds.
void print_plan(const std::vector<const cfg::NetworkNode*>& nodes, const PushCliOptions& options) {
  for (const cfg::NetworkNode* node : nodes) {
    const cfg::DownloadOrder order = cfg::plan_download(node->writes);
    std::size_t bytes = 0;
    for (const auto& w : order.writes) bytes += w.data.size();
    std::cout << node_label(*node) << ": " << tools::plural(order.writes.size(), "write") << ", "
              << tools::plural(bytes, "byte") << " from " << node->file << '\n';
    for (const auto& w : order.writes) {
      std::cout << "  " << cfg::to_string(cfg::ObjectAddress{w.index, w.sub_index}) << " = "
                << (w.data.empty() ? "(empty)" : tools::hex_string(w.data)) << '\n';
    }
    for (const std::uint16_t index : order.unknown_cob_id) {
      std::cout << "  (the COB-ID of " << cfg::object_name(index)
                << " is read from the device first, to make the PDO invalid around its mapping)\n";
    }
    std::cout << "  then 1020h sub 01h/02h = the configuration's date and time (1F26h/1F27h)"
              << (options.no_save ? "" : ", 1010h sub 01h = 'save'") << '\n';
  }
}

// A boot error in words from its fields, without the "node N: boot error X: " head: Table 1's
// text and why (the object and the SDO abort for J, the values compared for C, D, M, N, O).
std::string error_message(const nmt::MasterEvent& e) {
  if (!e.error) return nmt::describe(e);
  return nmt::describe_boot_error(e);
}

// Keeps each selected node's outcome from the master's events.
class Collector {
 public:
  explicit Collector(std::vector<NodeReport> nodes) : nodes_(std::move(nodes)) {}

  void observe(const nmt::MasterEvent& e) {
    using K = nmt::MasterEvent::Kind;
    if (e.kind == K::StartupHalted || e.kind == K::NotMaster) {
      stop_ = nmt::describe(e);
    }
    if (e.kind == K::LssUnmatched && e.lss_address) unmatched_.push_back(*e.lss_address);
    if (!e.node_id) return;  // an event of the master, about no node
    NodeReport* r = find(*e.node_id);
    if (r == nullptr) return;
    if (e.kind == K::LssAssigned) r->lss_assigned = true;
    if (e.kind == K::SlaveStateChanged && e.state) r->state = e.state;
    if (e.kind == K::Emergency && e.emergency &&
        e.emergency->emcy.error_code != nmt::emcy_code::kErrorReset) {
      ++r->emergencies;
    }
    if (e.kind == K::EmergencyFlood && e.emergency) r->emergencies += e.emergency->suppressed;
    if (r->result != Result::Pending) return;
    switch (e.kind) {
      case K::ProgramProgress:
        r->program_bytes = e.bytes;
        r->program_total = e.total;
        r->program_at = e.at;
        break;
      case K::BootStepChanged:
        if (e.step == nmt::BootStep::UpdateSoftware) {
          r->program_began = e.at;
          r->program_bytes = 0;
        }
        if (e.boot_try != r->boot_try) {
          // The first event of a try (CiA 302-2 §3.3): the engine does not report a repeated
          // error again, so a try is counted by its number.
          if (r->boot_try != 0) ++r->retries;
          r->boot_try = e.boot_try;
          r->entries = 0;  // a new try downloads from its first entry
          r->bytes = 0;
        }
        if (!r->began && e.step != nmt::BootStep::Idle) r->began = e.at;
        r->step = e.step;
        if (e.step == nmt::BootStep::Download) {
          // Each written entry is reported with the count so far: a boot that fails after
          // (or during) its download still tells how far it got.
          r->entries = e.written;
          r->total = e.total;
          r->bytes = e.bytes;
        }
        break;
      case K::SlaveBooted:
        r->result = e.configured         ? Result::Configured
                    : e.no_configuration ? Result::NoConfiguration
                                         : Result::Skipped;
        r->step = e.step;
        r->entries = e.written;
        r->total = e.total;
        r->bytes = e.bytes;
        // A slave 1F81h bit 2 leaves to the application ends its boot at step Idle (no
        // configuration, no start: CiA 302-2 §3.3, Table 22).
        r->message = e.configured ? "configured"
                     : e.no_configuration
                         ? nmt::describe_no_configuration(*e.node_id) + ": nothing downloaded"
                     : e.step == nmt::BootStep::Idle
                         ? "skipped: left to the application (1F81h bit 2 clear: no "
                           "configuration, no start)"
                         : "skipped: signature matches (1020h = 1F26h/1F27h)";
        r->ended = e.at;
        break;
      case K::BootError:
        // A mandatory slave is tried again after status B while the boot time lasts; an
        // optional one forever: its first error is its result.
        if (!e.final && r->mandatory) {
          r->step = nmt::BootStep::RetryWait;
          if (e.error)
            r->last_try = std::string(1, nmt::letter(*e.error)) + ": " + error_message(e);
          break;
        }
        r->step = nmt::BootStep::Failed;
        r->result = Result::Error;
        if (e.error) r->status = std::string(1, nmt::letter(*e.error));
        r->message = error_message(e);
        r->ended = e.at;
        break;
      default:
        break;
    }
  }

  // Every node has its result, or the master said why no (more) boot will run: not the NMT
  // master (1F80h bit 0 clear), or start-up halted.
  bool settled() const {
    return !stop_.empty() || std::all_of(nodes_.begin(), nodes_.end(), [](const NodeReport& r) {
      return r.result != Result::Pending;
    });
  }

  // Nodes whose boot had not ended when the run did: the run's bound, a signal, a device that
  // is not the master. Start-up halted by another node leaves none (the master reports the halt
  // once every slave's boot ended); should one remain, it says so too.
  void close(nmt::TimePoint now) {
    const std::string why = " (" + (stop_.empty() ? std::string("the run ended") : stop_) + ")";
    for (auto& r : nodes_) {
      if (r.result != Result::Pending) continue;
      r.result = Result::Error;
      r.ended = now;
      if (!r.began) {
        r.status = "not_tried";
        r.message = "not tried" + why;
        continue;
      }
      r.status = "unfinished";
      r.message = "not finished" + why + " at step " + std::string(nmt::to_string(r.step));
      if (!r.last_try.empty()) r.message += "; its last try ended with status " + r.last_try;
    }
  }

  const std::vector<NodeReport>& nodes() const { return nodes_; }
  /// --lss: the devices without node-ID that matched no node (left so).
  const std::vector<nmt::LssAddress>& unmatched() const { return unmatched_; }

 private:
  NodeReport* find(std::uint8_t node) {
    for (auto& r : nodes_) {
      if (r.node_id == node) return &r;
    }
    return nullptr;
  }
  std::vector<NodeReport> nodes_;
  std::vector<nmt::LssAddress> unmatched_;
  std::string stop_;  ///< the words of the event that ended start-up (halted, not master)
};

// The result column: "configured", "skipped", "no_configuration", "error C"; the words go under
// the table (the live view shows the same).
std::string result_text(const NodeReport& r) {
  if (r.result == Result::Error && !r.status.empty()) return "error " + r.status;
  return std::string(result_name(r.result));
}

// The live view on a terminal: per node its NMT state, boot step, entries written of total,
// bytes, retries and EMCYs (their lines go above the view, EventReporter::set_quiet), and a
// progress bar for the whole network, drawn on stderr over the last drawing (ANSI cursor movement),
// at most every kRedraw of wall-clock time.
class LiveView {
 public:
  static constexpr std::chrono::milliseconds kRedraw{100};  // ~10 Hz: readable, cheap

  /// On when stderr is a terminal that understands cursor movement.
  static bool wanted() {
    const char* term = std::getenv("TERM");
    return ::isatty(STDERR_FILENO) == 1 && term != nullptr && std::string_view(term) != "dumb";
  }

  /// Draws `nodes` unless the last drawing is younger than kRedraw (`now`: draw anyway).
  void update(const std::vector<NodeReport>& nodes, bool now) {
    const auto wall = std::chrono::steady_clock::now();
    if (!now && drawn_ && wall - last_ < kRedraw) return;
    last_ = wall;
    std::string text = erase();
    shown_ = render(nodes);
    for (const auto& line : shown_) text += line + "\x1b[K\n";
    lines_ = shown_.size();
    drawn_ = true;
    std::cerr << text << std::flush;
  }

  /// Prints `line` above the view, which stays below it.
  void note(const std::string& line) {
    std::string text = erase() + line + "\x1b[K\n";
    for (const auto& l : shown_) text += l + "\x1b[K\n";
    lines_ = shown_.size();
    std::cerr << text << std::flush;
  }

  /// Removes the drawing (before the table is printed).
  void clear() {
    if (!drawn_) return;
    std::cerr << erase() << std::flush;
    lines_ = 0;
    shown_.clear();
  }

 private:
  // Cursor to the first line of the last drawing, and everything below it cleared.
  std::string erase() const {
    if (lines_ == 0) return "";
    return "\x1b[" + std::to_string(lines_) + "F\x1b[J";
  }

  static std::size_t rows() {
    winsize size{};
    if (::ioctl(STDERR_FILENO, TIOCGWINSZ, &size) == 0 && size.ws_row > 0) return size.ws_row;
    return 24;
  }

  static std::string row(const NodeReport& r) {
    char line[160];
    const std::string entries = r.total == 0
                                    ? std::to_string(r.entries)
                                    : std::to_string(r.entries) + "/" + std::to_string(r.total);
    std::string step =
        r.result == Result::Pending ? std::string(nmt::to_string(r.step)) : result_text(r);
    if (r.result == Result::Pending && r.step == nmt::BootStep::UpdateSoftware &&
        r.program_total != 0 && r.program_began) {
      // The image's progress, its rate on the bus and what remains at that rate.
      const double s = static_cast<double>((r.program_at - *r.program_began).count()) / 1e6;
      const double rate = s > 0 ? static_cast<double>(r.program_bytes) / s : 0;
      char text[64];
      std::snprintf(text, sizeof text, "update %llu%% %.0f kB/s ETA %.0f s",
                    static_cast<unsigned long long>(r.program_bytes * 100 / r.program_total),
                    rate / 1e3,
                    rate > 0 ? static_cast<double>(r.program_total - r.program_bytes) / rate : 0.0);
      step = text;
    }
    std::snprintf(line, sizeof line, "%4d  %-12.12s  %-15.15s  %-28.28s  %9s  %7llu  %7u  %4llu",
                  r.node_id, r.name.c_str(),
                  r.state ? std::string(nmt::to_string(*r.state)).c_str() : "-", step.c_str(),
                  entries.c_str(), static_cast<unsigned long long>(r.bytes), r.retries,
                  static_cast<unsigned long long>(r.emergencies));
    return line;
  }

  static std::vector<std::string> render(const std::vector<NodeReport>& nodes) {
    std::size_t done = 0;
    std::size_t written = 0;
    std::size_t total = 0;
    double progress = 0;
    for (const auto& r : nodes) {
      written += r.entries;
      total += std::max(r.total, r.entries);
      if (r.result != Result::Pending) {
        ++done;
        progress += 1.0;
      } else if (r.total > 0) {
        // The download is most of a boot; identification and save the rest.
        progress += 0.1 + 0.8 * static_cast<double>(r.entries) / static_cast<double>(r.total);
      }
    }
    if (!nodes.empty()) progress /= static_cast<double>(nodes.size());
    constexpr int kBar = 30;
    const int filled = static_cast<int>(progress * kBar);
    std::vector<std::string> lines;
    lines.push_back("[" + std::string(static_cast<std::size_t>(filled), '#') +
                    std::string(static_cast<std::size_t>(kBar - filled), '-') + "] " +
                    std::to_string(static_cast<int>(progress * 100)) + "%  " +
                    std::to_string(done) + " of " + tools::plural(nodes.size(), "node") +
                    " done, " + std::to_string(written) + " of " + std::to_string(total) +
                    (total == 1 ? " entry" : " entries") + " written");
    char head[160];
    std::snprintf(head, sizeof head, "%4s  %-12s  %-15s  %-28s  %9s  %7s  %7s  %4s", "node", "name",
                  "state", "step", "entries", "bytes", "retries", "emcy");
    lines.emplace_back(head);
    // Nodes still booting first, then those waiting, then those done; as many as fit.
    std::vector<const NodeReport*> order;
    for (int pass = 0; pass < 3; ++pass) {
      for (const auto& r : nodes) {
        const int kind = r.result != Result::Pending ? 2 : r.began ? 0 : 1;
        if (kind == pass) order.push_back(&r);
      }
    }
    const std::size_t room = std::max<std::size_t>(rows(), 6) - 4;
    for (std::size_t i = 0; i < order.size() && i < room; ++i) lines.push_back(row(*order[i]));
    if (order.size() > room) {
      lines.push_back("  ... " + tools::plural(order.size() - room, "more node"));
    }
    return lines;
  }

  bool drawn_ = false;
  std::size_t lines_ = 0;
  std::vector<std::string> shown_;
  std::chrono::steady_clock::time_point last_{};
};

double node_seconds(const NodeReport& r, nmt::TimePoint start) {
  const nmt::TimePoint from = r.began.value_or(start);
  return static_cast<double>((r.ended - from).count()) / 1e6;
}

// The table (node, name, result, entries, time; with --lss also whether LSS gave the node-ID)
// within 100 columns whatever the messages, then one line per node whose result has words to it:
// "node 2 (io): error D: ...", one per node whose program was downloaded, and one per device LSS
// found that matched no node.
void print_table(const std::vector<NodeReport>& nodes, nmt::TimePoint start, bool lss,
                 const std::vector<nmt::LssAddress>& unmatched, const ProgramUpdates& programs) {
  constexpr std::size_t kNameWidth = 32;  // longer names are cut ("...") in the table only
  std::size_t name_width = 4;
  std::size_t result_width = 6;
  for (const auto& r : nodes) {
    name_width = std::max(name_width, std::min(r.name.size(), kNameWidth));
    result_width = std::max(result_width, result_text(r).size());
  }
  const auto pad = [](std::string text, std::size_t width) {
    if (text.size() > width) text = text.substr(0, width - 3) + "...";
    text.resize(width, ' ');
    return text;
  };
  std::cout << "node  " << pad("name", name_width) << "  " << pad("result", result_width)
            << (lss ? "  lss     " : "") << "  entries  emcy  time\n";
  for (const auto& r : nodes) {
    char number[8];
    std::snprintf(number, sizeof number, "%4d", r.node_id);
    char entries[16];
    std::snprintf(entries, sizeof entries, "%7zu", r.entries);
    char emcy[24];
    std::snprintf(emcy, sizeof emcy, "%4llu", static_cast<unsigned long long>(r.emergencies));
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%.3f s", node_seconds(r, start));
    std::cout << number << "  " << pad(r.name, name_width) << "  "
              << pad(result_text(r), result_width)
              << (lss ? (r.lss_assigned ? "  assigned" : "  -       ") : "") << "  " << entries
              << "  " << emcy << "  " << seconds << '\n';
  }
  bool first = true;
  // DSP 302 §9: each node whose program was downloaded in this run, with what it took.
  for (const auto& r : nodes) {
    const ProgramUpdate* u = programs.find(r.node_id);
    if (u == nullptr || !u->updated) continue;
    if (first) std::cout << '\n';
    first = false;
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%.3f s", u->seconds());
    std::cout << "node " << static_cast<int>(r.node_id)
              << (r.name.empty() ? "" : " (" + r.name + ")")
              << ": program updated: " << tools::plural(u->total, "byte") << " in " << seconds;
    if (u->identification_before) {
      // CiA 302-3 (1F55h): the identifications, not the versions.
      std::cout << ", before software identification " << cfg::hex(*u->identification_before, 8)
                << ", after "
                << (u->identification_after ? cfg::hex(*u->identification_after, 8)
                                            : std::string("?"))
                << " (1F56h sub 1)";
    } else {
      std::cout << ", before "
                << (u->before ? cfg::to_string(*u->before) : std::string("(not reported)"))
                << ", after " << (u->after ? cfg::to_string(*u->after) : std::string("?"));
    }
    std::cout << (u->clear_refused
                      ? "; clear (1F51h = 3) refused: " + nmt::to_string(*u->clear_refused)
                      : std::string())
              << '\n';
  }
  for (const auto& r : nodes) {
    if (r.result != Result::Error && r.result != Result::NoConfiguration) continue;
    if (first) std::cout << '\n';
    first = false;
    // A node without configuration: its message says so ("no configuration for node 2 ...").
    std::cout << "node " << static_cast<int>(r.node_id)
              << (r.name.empty() ? "" : " (" + r.name + ")") << ": "
              << (r.result == Result::Error ? result_text(r) + ": " : std::string()) << r.message
              << '\n';
  }
  if (!unmatched.empty()) std::cout << '\n';
  for (const auto& address : unmatched) {
    std::cout << "LSS: device " << nmt::address_digits(address)
              << " without node-ID matches no node: left without node-ID\n";
  }
}

// The --json report (fixed keys of the configuration manager issue; "mandatory" added).
std::string json_report(const std::vector<NodeReport>& nodes, bool ok, nmt::Duration elapsed,
                        nmt::TimePoint start, const std::vector<nmt::LssAddress>& unmatched,
                        const ProgramUpdates& programs,
                        const std::optional<nmt::BusCounters>& bus) {
  char number[32];
  std::snprintf(number, sizeof number, "%.6f", static_cast<double>(elapsed.count()) / 1e6);
  std::string out = std::string("{\"ok\": ") + (ok ? "true" : "false") +
                    ", \"elapsed_s\": " + number + ", \"nodes\": [";
  bool first = true;
  for (const auto& r : nodes) {
    std::snprintf(number, sizeof number, "%.6f", node_seconds(r, start));
    const std::string status = r.status.empty() ? "null" : tools::json_string(r.status);
    out += std::string(first ? "" : ", ") + "{\"node_id\": " + std::to_string(r.node_id) +
           ", \"name\": " + tools::json_string(r.name) +
           ", \"result\": " + tools::json_string(result_name(r.result)) +
           ", \"status\": " + status + ", \"message\": " + tools::json_string(r.message) +
           ", \"entries\": " + std::to_string(r.entries) +
           ", \"bytes\": " + std::to_string(r.bytes) +
           ", \"retries\": " + std::to_string(r.retries) + ", \"seconds\": " + number +
           ", \"mandatory\": " + (r.mandatory ? "true" : "false") +
           ", \"lss_assigned\": " + (r.lss_assigned ? "true" : "false") +
           ", \"emergencies\": " + std::to_string(r.emergencies) +
           ", \"program\": " + programs.json(r.node_id) + "}";
    first = false;
  }
  out += "], \"lss_unmatched\": [";
  for (std::size_t i = 0; i < unmatched.size(); ++i) {
    out += (i == 0 ? "" : ", ") + tools::json_string(nmt::address_digits(unmatched[i]));
  }
  out += "], \"bus\": ";
  if (!bus) return out + "null}\n";  // sim: has no controller
  const auto field = [](const char* name, std::uint64_t value) {
    return std::string(", \"") + name + "\": " + std::to_string(value);
  };
  std::snprintf(number, sizeof number, "%.6f",
                static_cast<double>(bus->bus_off_time.count()) / 1e6);
  out += "{\"error_frames\": " + std::to_string(bus->error_frames) +
         field("error_warning", bus->error_warning) + field("error_passive", bus->error_passive) +
         field("bus_off", bus->bus_off) + field("restarted", bus->restarted) +
         field("lost_arbitration", bus->lost_arbitration) +
         field("controller_overflows", bus->controller_overflows) +
         field("bus_errors", bus->bus_errors) + field("queue_full", bus->queue_full) +
         field("send_failures", bus->send_failures) + field("refused", bus->refused) +
         field("max_queued", bus->max_queued) + ", \"bus_off_s\": " + number + "}";
  return out + "}\n";
}

// The --report page: the lanes the recorder kept, the table's rows as print_table has them.
std::string html_page(ReportRecorder& recorder, const std::vector<NodeReport>& nodes,
                      const PushCliOptions& options, bool ok, const RunOutcome& outcome,
                      nmt::TimePoint start, bool halted) {
  std::size_t failed = 0;
  for (const auto& r : nodes) {
    report::NodeRow row;
    row.node_id = r.node_id;
    row.result = result_text(r);
    row.failed = r.result == Result::Error;
    row.message = r.message;
    row.entries = r.entries;
    row.emergencies = r.emergencies;
    row.retries = r.retries;
    row.seconds = node_seconds(r, start);
    recorder.set_result(row);
    failed += row.failed ? 1 : 0;
  }
  report::ReportData header;
  header.tool = std::string(kTool);
  header.network = options.network;
  header.bus = options.bus;
  header.ok = ok;
  // The outcome as the exit code tells it (--help's "Exit codes").
  header.outcome = outcome.timed_out ? "NMT start-up did not end within the run's bound (exit 4)"
                   : halted          ? "NMT start-up halted: a mandatory node failed (CiA 302-2 "
                                       "§3.1 f), no node was started (exit 4)"
                   : !ok             ? "a mandatory node failed (exit 4)"
                   : failed == 0     ? "every node configured or skipped"
                                     : "every mandatory node configured or skipped; " +
                                       tools::plural(failed, "optional node") + " failed";
  return report::html_report(recorder.finish(start, start + outcome.elapsed, std::move(header)));
}

// What the run bound allows for the software updates (DSP 302 §9) the nodes may need: each
// image byte as 1/7 of an 8-byte frame (135 bits at most with stuffing), twice (the master's
// pacing counts each segment with an answer's length), at the sim: bit rate, on a real bus at
// 125 kbit/s (its rate is not known here). A 256 KiB image: 81 s at 125 kbit/s.
double program_download_bound_s(const std::vector<const cfg::NetworkNode*>& nodes,
                                const std::optional<SimBusOptions>& sim) {
  constexpr double kBitsPerByte = 2.0 * 135.0 / 7.0;
  const double bitrate = sim ? static_cast<double>(sim->bitrate_bps) : 125'000.0;
  double bytes = 0;
  for (const cfg::NetworkNode* node : nodes) {
    if (node->program) bytes += static_cast<double>(node->program->image.size());
  }
  return bytes * kBitsPerByte / bitrate;
}

// --boot-time as the master's 1F89h (CiA 302-2 §6.11: UNSIGNED32, whole ms; there 0 means a
// mandatory slave is tried again without end, which no positive --boot-time means), checked
// where it is applied: the rest of the configuration was checked as the DCF was read.
nmt::Duration boot_time_or_exit(double seconds) {
  constexpr double kMostMs = 4294967295.0;
  const double ms = std::round(seconds * 1e3);
  char text[64];
  if (std::isnan(ms)) {
    fail_command(kTool, tools::kExitUsage, "--boot-time: nan is no time; give seconds, e.g. 10");
  }
  if (ms > kMostMs) {
    std::snprintf(text, sizeof text, "%.15g", ms);
    fail_command(kTool, tools::kExitUsage,
                 std::string("--boot-time: boot time (1F89h) ") + text +
                     " ms is above 4294967295 ms; give at most 4294967.295 s");
  }
  if (ms < 1.0) {
    std::snprintf(text, sizeof text, "%g", seconds);
    fail_command(kTool, tools::kExitUsage,
                 std::string("--boot-time: ") + text +
                     " s is below 1 ms, the unit of boot time (1F89h), where 0 means 'tried "
                     "again without end'; give at least 0.001 s");
  }
  return std::chrono::milliseconds(static_cast<std::int64_t>(ms));
}

void run_push(const PushCliOptions& options) {
  // Arguments first, files next, the bus last: a typo should not touch the bus.
  if (!options.dry_run && options.bus.empty()) {
    fail_command(kTool, tools::kExitUsage, "--bus is required (or give --dry-run)");
  }
  const std::optional<SimBusOptions> sim =
      options.bus.empty() ? std::nullopt : parse_bus_url(kTool, options.bus);
  if (options.net == 0) {
    fail_command(kTool, tools::kExitUsage, "--net: networks are numbered from 1");
  }
  const nmt::Duration sdo_timeout = sdo_timeout_or_exit(kTool, options.sdo_timeout_s);
  if (!options.only.empty()) parse_only(kTool, options.only);  // a usage error before any file
  const auto network = load_network_or_exit(options.network, options.net, options.programs,
                                            options.dcf_path, options.defines);
  const auto selected = selected_nodes(*network, options);
  if (options.dry_run) {
    print_plan(selected, options);
    return;
  }

  nmt::MasterOptions master_options;
  master_options.sdo.timeout = sdo_timeout;
  master_options.sdo.retries = options.retries;
  master_options.boot.save_configuration = !options.no_save;
  master_options.boot.force_download = options.force;
  if (sim) master_options.pacing.bitrate = sim->bitrate_bps;
  apply_lss_options(kTool, options.lss, *network, master_options);
  if (!options.only.empty()) {
    // --only leaves the other nodes as they are: their devices get no node-ID by LSS either
    // (found without one, they are reported as matching no node).
    std::erase_if(master_options.lss.addresses, [&selected](const auto& entry) {
      return std::none_of(selected.begin(), selected.end(), [&entry](const cfg::NetworkNode* n) {
        return n->node_id == entry.first;
      });
    });
  }
  const double lss_s = lss_bound_s(master_options);
  nmt::MasterConfig config =
      master_config_or_exit(kTool, options.network, network, options.node_id, master_options);

  // The options as the master's own objects (CiA 302-2 §6), through the typed configuration so
  // that they are checked, and its boot follows them.
  if (options.boot_time_s) {
    config.boot_time = boot_time_or_exit(*options.boot_time_s);
  } else if (config.boot_time == nmt::Duration::zero()) {
    config.boot_time =
        std::chrono::duration_cast<nmt::Duration>(std::chrono::duration<double>(kDefaultBootTimeS));
  }
  const double boot_time_s = std::chrono::duration<double>(config.boot_time).count();
  if (options.no_start) config.startup.no_start_slaves = true;  // 1F80h bit 3
  std::set<std::uint8_t> chosen;
  std::set<std::uint8_t> left_out;
  for (const auto* node : selected) chosen.insert(node->node_id.value());
  std::vector<NodeReport> reports;
  for (nmt::SlaveConfig& slave : config.slaves) {
    if (!slave.slave) continue;
    const std::uint8_t id = slave.node.value();
    if (!options.only.empty() && !chosen.contains(id)) {
      // --only leaves the other nodes as they are: a keep-alive slave (1F81h bit 4, Table 22)
      // gets no reset communication at start-up (CiA 302-2 §3.1 d), and with bit 2 clear
      // (Table 20) it is neither configured nor started; bit 3 clear: its absence is no error.
      // Nothing else of 1F81h: no guarding, no software check, no restore.
      nmt::SlaveConfig kept(slave.node);
      kept.boot = false;
      kept.keep_alive = true;
      kept.identity = slave.identity;
      kept.heartbeat = slave.heartbeat;
      kept.restore_subindex = slave.restore_subindex;
      slave = kept;
      left_out.insert(id);
      continue;
    }
    NodeReport r;
    r.node_id = id;
    if (const auto* node = network->find(slave.node)) r.name = node->name;
    r.mandatory = slave.mandatory;
    reports.push_back(std::move(r));
  }
  std::sort(reports.begin(), reports.end(),
            [](const NodeReport& a, const NodeReport& b) { return a.node_id < b.node_id; });
  nmt::NmtMaster master = build_master_or_exit(config, options.network, *network);

  tools::ReportFile json = open_report_or_exit(options.json);
  std::optional<tools::OutputFile> html = open_html_report_or_exit(options.report);
  std::optional<ReportRecorder> recorder;
  RunTraces traces = options.traces;
  if (html) {
    std::vector<ReportRecorder::Node> lanes;
    for (const auto& r : reports) lanes.push_back({r.node_id, r.name, r.mandatory});
    const ReportBitrate bitrate = report_bitrate(options.report, sim);
    recorder.emplace(std::move(lanes), bitrate.bps, bitrate.assumed);
    traces.frames = recorder->frame_sink();
  }

  Collector collector(std::move(reports));
  EventReporter reporter(options.verbose, nullptr);
  reporter.track_programs(network);
  reporter.ignore_nodes(left_out);
  std::optional<LiveView> view;
  if (LiveView::wanted()) {
    view.emplace();
    reporter.set_quiet(true);  // the view shows what the event lines would
    reporter.set_note_handler([&view](const std::string& line) { view->note(line); });
  }
  reporter.set_observer([&collector, &view, &recorder](const nmt::MasterEvent& e) {
    collector.observe(e);
    if (recorder) recorder->observe(e);
    if (view) view->update(collector.nodes(), false);
  });
  RunLimits limits;
  limits.tool = kTool;
  limits.until_startup_ends = true;
  limits.bound_s = boot_time_s + kRunMarginS + lss_s + program_download_bound_s(selected, sim);
  limits.bound_hint = sim ? " of simulated time" : "";
  // StartupHalted comes once every slave's boot ended (nmt_master.hpp), so each node has its
  // own result by then.
  limits.settled = [&] { return reporter.halted() || collector.settled(); };
  const RunOutcome outcome =
      sim ? run_master_on_sim(std::move(master), *network, *sim, limits, reporter, traces)
          : run_master_on_bus(std::move(master), options.bus, limits, reporter, traces);
  const nmt::Duration elapsed = outcome.elapsed;
  collector.close(reporter.start() + elapsed);
  if (view) {
    view->update(collector.nodes(), true);  // the last state, then the table in its place
    view->clear();
  }

  bool ok = !reporter.halted() && !outcome.timed_out;
  for (const auto& r : collector.nodes()) {
    if (r.mandatory && r.result == Result::Error) ok = false;
  }
  print_table(collector.nodes(), reporter.start(), options.lss.lss, collector.unmatched(),
              reporter.programs());
  if (json.stream() != nullptr) {
    finish_report_or_exit(
        json, json_report(collector.nodes(), ok, elapsed, reporter.start(), collector.unmatched(),
                          reporter.programs(), outcome.bus));
  }
  if (html) {
    write_html_report_or_exit(*html, html_page(*recorder, collector.nodes(), options, ok, outcome,
                                               reporter.start(), reporter.halted()));
  }
  if (!ok) exit_with(kExitMandatoryFailed);
}

}  // namespace

void add_push_command(CLI::App& app) {
  auto options = std::make_shared<PushCliOptions>();
  auto* cmd = app.add_subcommand(
      "push",
      "Commission a network: boot every slave through the CiA 302-2 NMT master (identity "
      "check, configuration download unless 1020h matches 1F26h/1F27h, save, start), stop when "
      "NMT start-up has ended, and report per node: configured, skipped (signature matches) or "
      "error with its CiA 302-2 status letter");
  auto* bus = add_network_run_options(*cmd, *options);
  bus->description(bus->get_description() + ". Required unless --dry-run");
  cmd->add_option(
         "--json", options->json,
         "Also write the report as JSON: ok, elapsed_s (bus time; simulated on sim:), "
         "nodes [{node_id, name, result (configured/skipped/no_configuration/error: "
         "no_configuration when the master had nothing to configure the node with, a master "
         "DCF whose 1F22h sub N is empty), status (with an error: "
         "its CiA 302-2 letter, or not_tried / unfinished when its boot did not end "
         "before the run did; null otherwise), message, entries, bytes, retries, "
         "seconds, mandatory, lss_assigned (true when --lss gave the node its node-ID in "
         "this run), emergencies (EMCYs the node sent with an error code, CiA 301 §7.2.7; "
         "error resets not counted), program: null, or for a node whose program was downloaded "
         "(DSP 302 §9) "
         "{updated, before, after (each null or {date_days, time_ms, text}), bytes, seconds, "
         "clear_refused (null, or the abort with which the device refused 1F51h = 3)}}], "
         "lss_unmatched [LSS addresses VVVVVVVV:PPPPPPPP:RRRRRRRR:SSSSSSSS of devices --lss "
         "found that match no node], bus: null on sim:, else the controller's counters "
         "{error_frames, error_warning, error_passive, bus_off, restarted, lost_arbitration, "
         "controller_overflows, bus_errors, queue_full, send_failures, refused, max_queued, "
         "bus_off_s}")
      ->type_name("FILE");
  cmd->add_option("--boot-time", options->boot_time_s,
                  "How long a mandatory slave that does not answer is tried again (overrides "
                  "1F89h); default: the master DCF's 1F89h when not 0, else 10 s. The run gives "
                  "up 60 s after it, plus the time the program images (--program) may take on "
                  "the bus")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--dry-run", options->dry_run,
                "Print per node the writes the master would download, in download order "
                "(PDO-safe), without a bus");
  cmd->add_option("--only", options->only,
                  "Boot only these nodes, e.g. 3,5-7. The others are left as they are: no reset, "
                  "no configuration, no start (this run makes them keep-alive slaves that are "
                  "not booted, 1F81h = 11h: NMT start-up then resets each booted node on its "
                  "own instead of all nodes at once)")
      ->type_name("NODES");
  cmd->add_option("--trace", options->traces.pcap,
                  "Record every frame of the run in a pcap file (LINKTYPE_CAN_SOCKETCAN, for "
                  "Wireshark/tshark); on sim: stamped with simulated time")
      ->type_name("FILE.pcap");
  cmd->add_option("--candump", options->traces.candump,
                  "Record every frame of the run as a candump log (candump -l format, for "
                  "can-utils and python-can); on sim: stamped with simulated time")
      ->type_name("FILE.log");
  add_html_report_options(*cmd, options->report, "at the end of the run");
  add_lss_options(*cmd, options->lss, /*with_period=*/false);
  cmd->add_flag("--force", options->force, "Download even when 1020h matches 1F26h/1F27h");
  cmd->add_flag("--no-start", options->no_start,
                "Do not start the slaves (1F80h bit 3): they stay pre-operational");
  cmd->add_flag("--no-save", options->no_save, "Do not write 1010h sub 1 'save' after a download");
  cmd->add_option("--sdo-timeout", options->sdo_timeout_s,
                  "Timeout of each SDO response, in seconds")
      ->capture_default_str()
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--retries", options->retries, "How often a timed-out SDO transfer is repeated")
      ->capture_default_str()
      ->type_name("N");
  cmd->footer(std::string(
      "On a terminal, stderr shows a live view while the run lasts (redrawn at most 10 times a "
      "second): a progress bar, and per node its NMT state, boot step, entries written of "
      "total, bytes and retries (boot tries repeated). Otherwise events are printed one a line "
      "on stderr as cfgmgr master prints them. The table goes to stdout at the end: node, name, "
      "result (configured, skipped, no_configuration, error X with the CiA 302-2 status "
      "letter), entries (configuration writes, PDO-safe order; for an error, those written "
      "before it), time (from the node's first boot step to its result); under it one line "
      "per error with its words (\"node 2 (io): error D: ...\") and one per node the master "
      "had no configuration for (\"node 2: no configuration for node 2 (1F22h sub 02h empty): "
      "nothing downloaded\").\n\n"
      "A mandatory node that fails halts NMT start-up (CiA 302-2 section 3.1 f): no node is "
      "started and the master stays pre-operational, but every other node's boot still runs "
      "to its own end, so one run reports each node's own result.\n\n"
      "While it runs, push is the network's configuration manager as cfgmgr master is (DSP "
      "302 section 6): 1F22h sub N reads the concise DCF it downloads to node N (as cfgmgr "
      "build writes it), 1F20h sub N the node's DCF, 1F26h/1F27h the stamps it compares with "
      "1020h; what a tool writes to them is held in memory until push ends.\n\n"
      "With --bus sim:?state=DIR each simulated device keeps what it saved with 1010h (the "
      "configuration and 1020h) in DIR between runs, one file per node, and loads it when it "
      "powers on: a second push finds every 1020h as the first left it and skips every "
      "node (\"skipped: signature matches\").\n\n"
      "Devices out of the box (no node-ID, CiA 305): with --lss push first finds every device "
      "without node-ID and gives each the node-ID of the node whose DCF has its LSS address "
      "(1018h sub 1-3 and [DeviceComissioning] LSS_SerialNumber, else 1018h sub 4), stored in "
      "the device; then it boots the network as usual. The table gets a column lss (assigned: "
      "this run gave the node-ID), and devices that match no node are listed under it and left "
      "alone. The search costs about 135 LSS requests of 10 ms per device; with every device "
      "configured it is 2 frames and 10 ms.\n\n"
      "Examples:\n"
      "  cfgmgr push samples/network/nodelist.cpj --bus sim:\n"
      "  cfgmgr push nodelist.cpj --bus 'sim:?unconfigured=2-4' --lss\n"
      "  cfgmgr push samples/network/nodelist.cpj --dry-run --only 3\n"
      "  cfgmgr push samples/network/nodelist.cpj --bus 'sim:?state=/tmp/devices' "
      "--candump boot.log\n"
      "  cfgmgr push nodelist.cpj --bus socketcan:can0 --json report.json\n"
      "  cfgmgr push samples/network/nodelist.cpj --bus sim: --report push.html\n"
      "  cfgmgr push master.dcf --bus udp://239.74.163.2:43113 --force --no-save\n"
      "  cfgmgr push nodelist.cpj --bus socketcan:can0 --lss --json report.json\n\n"
      "Exit codes:\n"
      "  0  every mandatory node configured or skipped and started (optional failures are "
      "reported)\n"
      "  1  the network description has errors (printed as FILE:LINE: error: ...), or the "
      "master cannot be built from it\n"
      "  2  usage error (bad command line, a --bus URL that does not parse, --only naming a "
      "node that is not in the network)\n"
      "  3  I/O error: the description cannot be read, the bus cannot be opened or fails, "
      "--json or --report cannot be written\n"
      "  4  a mandatory node failed (NMT start-up halted, CiA 302-2 section 3.1 f: no node "
      "started; every node's result is still reported), or start-up did not end within the "
      "boot time + 60 s\n"));
  cmd->callback([options] { run_push(*options); });
}

}  // namespace cfgmgr
