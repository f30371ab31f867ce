// The shared run of cfgmgr master and push (master_run.hpp).
#include "master_run.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/bytes.hpp"
#include "cfg/config_manager.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/node_id.hpp"
#include "commands.hpp"
#include "nmt/bus.hpp"
#include "nmt/bus_event_loop.hpp"
#include "nmt/device_state.hpp"
#include "nmt/entry_persister.hpp"
#include "nmt/master_config.hpp"
#include "nmt/master_event_text.hpp"
#include "nmt/sim_bus.hpp"
#include "nmt/simulated_device.hpp"
#include "nmt/trace.hpp"

namespace cfgmgr {
namespace {

/// The master's node-ID when neither --node-id nor the master DCF gives one: 7Fh, the highest,
/// so that the slaves keep the low node-IDs (and their higher-priority COB-IDs).
constexpr std::uint8_t kDefaultMasterNodeId = 0x7F;

// Set by SIGINT/SIGTERM; the running real-time loop is told at once.
std::atomic<bool> g_stop{false};
std::atomic<nmt::BusEventLoop*> g_running_loop{nullptr};

extern "C" void on_master_stop_signal(int) {
  g_stop.store(true);
  if (auto* loop = g_running_loop.load()) loop->request_stop();
}

// Installs the handlers for the lifetime of the object.
class StopSignals {
 public:
  StopSignals() {
    struct sigaction action {};
    action.sa_handler = on_master_stop_signal;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
  }
  ~StopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

// CiA 302-2 §3.1 g, 1F80h bit 2: the application lets the master enter operational. This
// program is the application and has nothing of its own to do first, so it does so at once.
template <class Apply>
void continue_when_awaited(const nmt::NmtMaster& master, bool& done, Apply&& apply) {
  if (done || master.startup_state() != nmt::StartupState::AwaitApplication) return;
  done = true;
  apply([](nmt::NmtMaster& m, nmt::TimePoint now, nmt::NmtMaster::Output& out) {
    m.enter_operational(now, out);
  });
}

std::string prefix(std::string_view tool) {
  return "cfgmgr " + std::string(tool) + ": ";
}

// --store DIR: the master leaves the disk to its driver (nmt_master.hpp, PersistEntry). On sim:
// the entry is written here, in the loop after the master's call (simulated time stands still
// meanwhile; a real bus uses nmt::EntryPersister's worker thread), and the master told, so that
// the SDO confirmation of the write leaves once the entry is durable (or an abort when it failed).
template <class Apply>
void persist_when_asked(const nmt::MasterEvent& e, const nmt::NmtMaster& master,
                        EventReporter& reporter, std::string_view tool, Apply&& apply) {
  if (e.kind != nmt::MasterEvent::Kind::PersistEntry || !e.persist) return;
  const cfg::ConfigManager* manager = master.config_manager();
  cfg::Status done = manager != nullptr ? manager->persist(*e.persist->update)
                                        : cfg::Status{cfg::Error{"no configuration manager"}};
  if (!done) reporter.note(prefix(tool) + "error: " + done.error().message);
  apply([ticket = e.persist->ticket, done = std::move(done)](nmt::NmtMaster& m, nmt::TimePoint now,
                                                             nmt::NmtMaster::Output& out) {
    m.entry_persisted(ticket, done, now, out);
  });
}

// The trace files of a run, open; exit 3 when one cannot be created.
struct OpenTraces {
  std::vector<std::unique_ptr<nmt::TraceWriter>> writers;
};

std::unique_ptr<nmt::TraceWriter> open_or_exit(
    std::string_view tool, cfg::Result<std::unique_ptr<nmt::TraceWriter>> opened) {
  if (!opened) fail_command(tool, tools::kExitIo, opened.error().message);
  return std::move(opened).value();
}

OpenTraces open_traces(std::string_view tool, const RunTraces& traces) {
  OpenTraces out;
  if (!traces.pcap.empty()) out.writers.push_back(open_or_exit(tool, nmt::open_pcap(traces.pcap)));
  if (!traces.candump.empty()) {
    out.writers.push_back(open_or_exit(tool, nmt::open_candump_log(traces.candump)));
  }
  return out;
}

// The traces complete on disk; exit 3 when one failed during the run or now.
void close_traces(std::string_view tool, const std::vector<nmt::TraceWriter*>& writers) {
  for (nmt::TraceWriter* w : writers) {
    if (auto flushed = w->flush(); !flushed) {
      fail_command(tool, tools::kExitIo,
                   "trace " + w->path().string() + ": " + flushed.error().message);
    }
  }
}

bool ended(const RunLimits& limits, const EventReporter& reporter) {
  return reporter.finished() && (!limits.settled || limits.settled());
}

// With until_startup_ends, a start-up that did not end within the bound is a failed run.
bool timed_out(const RunLimits& limits, EventReporter& reporter) {
  if (!limits.until_startup_ends || limits.run_for_s || ended(limits, reporter) || g_stop.load()) {
    return false;
  }
  std::ostringstream text;
  text << prefix(limits.tool) << "NMT start-up did not end within " << limits.bound_s << " s"
       << limits.bound_hint;
  reporter.note(text.str());
  return true;
}

}  // namespace

CLI::Option* add_network_run_options(CLI::App& cmd, NetworkRunArgs& args) {
  cmd.add_option("network", args.network,
                 "CiA 306-3 project file (nodelist.cpj; DCF paths relative to it) or a "
                 "master DCF (CANopenManager=1) whose 1F20h/1F22h name node files with "
                 "DownloadFile=")
      ->required()
      ->type_name("NETWORK");
  auto* bus =
      cmd.add_option("--bus", args.bus,
                     "Bus URL: socketcan:IFNAME, udp://GROUP:PORT (python-can "
                     "udp_multicast compatible), or sim: for the simulated bus with a "
                     "simulated device per node built from the network's DCFs, in "
                     "simulated time (sim:?bitrate=500000&latency_ms=1&loss=0.01&seed=N&state=DIR, "
                     "and &unconfigured=3,5-7; state=DIR keeps what each device saved with 1010h "
                     "between runs; the devices of the unconfigured= nodes power on without "
                     "node-ID and wait for LSS, CiA 305)")
          ->type_name("URL");
  cmd.add_option("--node-id", args.node_id,
                 "The master's node-ID (1..127, e.g. 1 or 0x01); default: the master DCF's "
                 "NodeID, else 0x7F (127)")
      ->type_name("N");
  cmd.add_option("--net", args.net,
                 "Which network of the project file: 1 is [Topology], N is [TopologyN]")
      ->capture_default_str()
      ->type_name("N");
  cmd.add_flag("-v,--verbose", args.verbose,
               "Also print boot steps, NMT commands and state changes");
  cmd.add_option("--program", args.programs.files,
                 "Node NODE should run the application program image FILE (DSP 302 §9), "
                 "overriding the project file's NodeXProgramFile=: a node whose 1F52h differs "
                 "from its expected version gets FILE downloaded to 1F50h sub 1 during its boot "
                 "(1F81h bit 6); repeatable")
      ->type_name("NODE=FILE");
  cmd.add_option("--program-version", args.programs.versions,
                 "The version node NODE should report in 1F52h (1F53h/1F54h, 1F81h bit 5), "
                 "overriding NodeXProgramVersion=: YYYY-MM-DD[THH:MM[:SS[.mmm]]] or DAYS,MS "
                 "(days since 1984-01-01, ms after midnight); repeatable")
      ->type_name("NODE=VERSION");
  return bus;
}

void fail_command(std::string_view tool, int code, const std::string& message) {
  std::cerr << prefix(tool) << message << '\n';
  exit_with(code);
}

void add_lss_options(CLI::App& cmd, LssRunArgs& args, bool with_period) {
  cmd.add_flag("--lss", args.lss,
               "Execute LSS first (CiA 305, DSP 302 section 4 step 3): before the reset of all "
               "nodes, find every device without node-ID (Fastscan) and give each whose LSS "
               "address (vendor-ID, product code, revision, serial number: 1018h sub 1-4 of a "
               "node's DCF, the serial number from [DeviceComissioning] LSS_SerialNumber) is a "
               "node's that node's node-ID, stored in the device; devices that match no node are "
               "reported and left without node-ID");
  cmd.add_option("--lss-scan-step", args.scan_step_ms,
                 "With --lss: how long each Fastscan request waits for answers, in ms (above "
                 "the devices' answer time; raise it for devices behind a slow link)")
      ->capture_default_str()
      ->type_name("MS")
      ->check(CLI::Range(1U, 10000U));
  if (!with_period) return;
  cmd.add_option("--lss-period", args.period_ms,
                 "With --lss: after start-up, look for devices without node-ID (a replaced "
                 "device) every MS milliseconds, and give them their node-ID; the master then "
                 "boots and configures them. Each look is one LSS frame (4Ch, about 0.25 ms of "
                 "bus time at 500 kbit/s: 0.025 % of the bus at 1000 ms) and one scan step of "
                 "waiting for answers; only when a device answers, a Fastscan follows (about "
                 "135 requests and as many answers per device, one scan step each; a device "
                 "that matches no node costs that at every look). Default: no looks")
      ->type_name("MS")
      ->check(CLI::Range(1U, 3600000U));
}

void apply_lss_options(std::string_view tool, const LssRunArgs& args, const cfg::Network& network,
                       nmt::MasterOptions& options) {
  if (!args.lss) {
    if (args.period_ms) fail_command(tool, tools::kExitUsage, "--lss-period needs --lss");
    return;
  }
  options.lss.enabled = true;
  options.lss.timing.scan_step = std::chrono::milliseconds(args.scan_step_ms);
  if (args.period_ms) options.lss.period = std::chrono::milliseconds(*args.period_ms);
  std::vector<std::string> notes;
  options.lss.addresses = lss_addresses(network, notes);
  for (const auto& note : notes) std::cerr << prefix(tool) << "note: " << note << '\n';
}

double lss_bound_s(const nmt::MasterOptions& options) {
  if (!options.lss.enabled) return 0;
  // The worst case, in which every device on the bus (taken as at most one per known address
  // and one more) matches no node: per known address its reset and 4 confirmations (5 steps,
  // lss_master.hpp), answered by every unconfigured device up to the serial number (4 N^2
  // answers); then per device the bit-by-bit Fastscan (1 + 4 x 33 steps), configure and store
  // (two timeouts at most), and the probes past a device left alone; the last, silent Fastscan
  // reset. Its answers: every device not yet found answers about 100 queries of each search
  // (devices of one product share the upper parts of their addresses), about 70 N^2 frames
  // (BENCHMARKS.md, bench_lss_fastscan). Frames of 135 bits at most at the bit rate (125 kbit/s
  // when unknown). When the devices match their nodes, the scan takes a small part of this
  // (BENCHMARKS.md, bench_push --lss).
  const double step_s = std::chrono::duration<double>(options.lss.timing.scan_step).count();
  const double answer_s = std::chrono::duration<double>(options.lss.timing.timeout).count();
  const double devices = static_cast<double>(options.lss.addresses.size()) + 1;
  const double frame_s = 135.0 / (options.bitrate != 0 ? options.bitrate : 125'000);
  return devices * (145 * step_s + 2 * answer_s) + devices * devices * 74 * frame_s + 1;
}

tools::ReportFile open_report_or_exit(const std::string& path) {
  auto opened = tools::ReportFile::open(path);
  if (!opened) {
    std::cerr << opened.error().message << '\n';
    exit_with(tools::kExitIo);
  }
  return std::move(*opened);
}

void finish_report_or_exit(tools::ReportFile& report, std::string_view text) {
  if (auto written = report.finish(text); !written) {
    std::cerr << written.error().message << '\n';
    exit_with(tools::kExitIo);
  }
}

std::string seconds_text(nmt::TimePoint start, nmt::TimePoint at) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>((at - start).count()) / 1e6);
  return buf;
}

nmt::Duration seconds_to_duration(double s) {
  return nmt::Duration(static_cast<std::int64_t>(s * 1e6));
}

nmt::Duration sdo_timeout_or_exit(std::string_view tool, double seconds) {
  constexpr double kMostS = 1e9;  // some 31 years: far below the 64-bit us the clock counts
  if (!(seconds * 1e6 >= 1.0) || seconds > kMostS) {
    char text[64];
    std::snprintf(text, sizeof text, "%g", seconds);
    fail_command(tool, tools::kExitUsage,
                 std::string("--sdo-timeout: ") + text +
                     " s is no SDO response timeout; give from 0.000001 s (1 us) to 1e9 s");
  }
  return seconds_to_duration(seconds);
}

void EventReporter::report(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  // An event of the master itself (no node_id) is never ignored.
  const int node_id = e.node_id ? int{e.node_id->value()} : 0;
  if (e.node_id && ignored_.contains(*e.node_id)) {
    if (observer_) observer_(e);
    return;
  }
  if (const auto updated = programs_.observe(e)) {
    note(seconds_text(start_, e.at) + "  " + *updated);
  }
  std::string line;
  const std::string node = "node " + std::to_string(node_id) + ": ";
  bool again = false;
  switch (e.kind) {
    case K::NotMaster:
      finished_ = true;
      line = nmt::describe(e);
      break;
    case K::StartupBegan:
      line = "NMT start-up began";
      break;
    case K::SlaveBooted:
      again = !booted_.insert(*e.node_id).second;
      if (e.configured) {
        line = node + (again ? "reconfigured" : "booted, configured") + " (" +
               std::to_string(e.written) + (e.written == 1 ? " entry" : " entries") + ", " +
               tools::plural(e.bytes, "byte") + ")";
      } else {
        line = node + (again ? "booted again" : "booted") + " (configuration up to date)";
      }
      break;
    case K::BootError:
      if (e.error) {
        line = node + "boot error " + std::string(1, nmt::letter(*e.error)) + ": " +
               std::string(nmt::describe(*e.error));
      } else {
        line = node + "boot error: " + nmt::describe(e);
      }
      if (!e.final) line += " (trying again)";
      break;
    case K::StartupHalted:
      halted_ = true;
      finished_ = true;
      line =
          nmt::describe(e);  // "NMT start-up halted: mandatory node N failed with status X (...)"
      break;
    case K::StartupComplete:
      complete_ = true;
      finished_ = true;
      line = "NMT start-up complete";
      break;
    case K::HeartbeatLost:
      line = node + "heartbeat lost";
      break;
    case K::GuardingLost:
      line = node + "node guarding lost";
      break;
    case K::ErrorControlResolved:
      line = node + "error control resolved";
      break;
    case K::BootUp:
      line = node + "boot-up seen" + (e.assigned ? "" : " (not a slave of this master)");
      break;
    case K::ProgramClearRefused:
      break;  // noted above (programs_), also under a live view
    case K::ActiveMaster:
    case K::Standby:
    case K::ForceNegotiation:
    case K::MultipleMasters:
    case K::ActiveMasterLost:
    case K::SrdRegistered:
    case K::SrdRegistrationFailed:
    case K::SdoConnectionEstablished:
    case K::SdoConnectionRefused:
    case K::SdoConnectionReleased:
    case K::SrdLost:
    case K::SrdDeregistered:
    case K::SlaveFailedReported:
    case K::LssAssigned:
    case K::LssUnmatched:
    case K::LssFailed:
    case K::LssScanEnded:
      // flying master: who is active and why; SDO manager: what it did; LSS: which device got
      // which node-ID, and which matched no node
      line = nmt::describe(e);
      break;
    default:
      if (verbose_) line = nmt::describe(e);
      break;
  }
  if (!line.empty() && !quiet_)
    std::cerr << seconds_text(start_, e.at) << "  " << line << '\n' << std::flush;
  if (json_ != nullptr) write_json(e);
  if (observer_) observer_(e);
}

void EventReporter::note(const std::string& line) {
  if (note_handler_) {
    note_handler_(line);
  } else {
    std::cerr << line << '\n' << std::flush;
  }
}

namespace {
// A boot error's facts (nmt::BootFailure) as a JSON object: the reason, the step it failed in,
// and what the reason has (the object and values compared, the failed transfer and its abort).
std::string json_failure(const nmt::BootFailure& f) {
  using R = nmt::BootFailure::Reason;
  std::string out = "{\"reason\": " + tools::json_string(nmt::to_string(f.reason)) +
                    ", \"step\": " + tools::json_string(nmt::to_string(f.step));
  if (f.reason == R::ValueDiffers) {
    out += ", \"object\": " + tools::json_string(cfg::to_string(f.object)) +
           ", \"actual\": " + std::to_string(f.actual) +
           ", \"expected_by\": " + tools::json_string(cfg::hex_digits(f.expected_by, 4) + "h") +
           ", \"expected\": " + std::to_string(f.expected);
  }
  if (f.transfer) {
    out += ", \"object\": " + tools::json_string(cfg::to_string(f.transfer->address)) +
           ", \"abort\": " + std::to_string(static_cast<std::uint32_t>(f.transfer->abort)) +
           ", \"abort_text\": " + tools::json_string(nmt::to_string(f.transfer->abort));
  }
  if (f.reason == R::WriteFailed) {
    out +=
        ", \"entry\": " + std::to_string(f.entry) + ", \"entries\": " + std::to_string(f.entries);
  }
  if (f.reason == R::NoFirstHeartbeat) {
    out += ", \"consumer_time_ms\": " + std::to_string(f.consumer_time_ms);
  }
  if (f.boot_time_ms) out += ", \"boot_time_ms\": " + std::to_string(*f.boot_time_ms);
  return out + "}";
}
}  // namespace

void EventReporter::write_json(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  std::string out = "{\"time_s\": " + seconds_text(start_, e.at) +
                    ", \"event\": " + tools::json_string(nmt::to_string(e.kind)) +
                    ", \"node_id\": " + std::to_string(e.node_id ? int{e.node_id->value()} : 0);
  switch (e.kind) {
    case K::BootError:
      if (e.error) {
        out += ", \"error\": " + tools::json_string(std::string(1, nmt::letter(*e.error))) +
               ", \"description\": " + tools::json_string(nmt::describe(*e.error));
      } else {
        out += ", \"error\": null";
      }
      out += std::string(", \"final\": ") + (e.final ? "true" : "false");
      if (e.failure) out += ", \"failure\": " + json_failure(*e.failure);
      break;
    case K::StartupHalted: {
      std::string list;
      for (const auto& f : e.halted_by) {
        list += std::string(list.empty() ? "" : ", ") +
                "{\"node_id\": " + std::to_string(f.node.value()) +
                ", \"error\": " + tools::json_string(std::string(1, nmt::letter(f.error))) + "}";
      }
      out += ", \"halted_by\": [" + list + "]";
      break;
    }
    case K::NotMaster:
      out += ", \"nmt_startup\": " + std::to_string(e.nmt_startup);
      break;
    case K::SlaveBooted:
      out += std::string(", \"configured\": ") + (e.configured ? "true" : "false") +
             ", \"entries\": " + std::to_string(e.written) +
             ", \"bytes\": " + std::to_string(e.bytes);
      break;
    case K::BootUp:
      out += std::string(", \"assigned\": ") + (e.assigned ? "true" : "false");
      break;
    case K::BootStepChanged:
      out += ", \"step\": " + tools::json_string(nmt::to_string(e.step));
      break;
    case K::MasterStateChanged:
    case K::SlaveStateChanged:
      if (e.state) out += ", \"state\": " + tools::json_string(nmt::to_string(*e.state));
      break;
    case K::NmtCommandSent:
      if (e.command) out += ", \"command\": " + tools::json_string(nmt::to_string(*e.command));
      break;
    case K::NegotiationBegan:
    case K::ActiveMaster:
    case K::Standby:
    case K::ForceNegotiation:
    case K::MultipleMasters:
    case K::ActiveMasterLost:
    case K::MasterDetection:
      if (e.priority) out += ", \"priority\": " + std::to_string(*e.priority);
      if (e.flying) out += ", \"reason\": " + tools::json_string(nmt::to_string(e.flying->reason));
      break;
    case K::LssAssigned:
    case K::LssFailed:
    case K::LssUnmatched:
      if (e.lss) {
        out += ", \"outcome\": " + tools::json_string(nmt::to_string(e.lss->outcome)) +
               ", \"error_code\": " + std::to_string(e.lss->error_code);
      }
      break;
    case K::LssScanEnded:
      if (e.lss_scan) {
        out += ", \"found\": " + std::to_string(e.lss_scan->found) +
               ", \"assigned\": " + std::to_string(e.lss_scan->assigned);
      }
      break;
    case K::SdoConnectionReleased:
    case K::SrdLost:
      out += ", \"reason\": " + tools::json_string(nmt::to_string(e.manager_reason.kind));
      break;
    case K::SrdRegistrationFailed:
    case K::SdoConnectionRefused:
      // The JSON keeps 1F10h's byte (DSP 302 §7.2.3), the value a script compares with.
      if (e.connection_error) {
        out +=
            ", \"connection_error\": " + std::to_string(static_cast<unsigned>(*e.connection_error));
      }
      out += ", \"reason\": " + tools::json_string(nmt::to_string(e.manager_reason.kind));
      break;
    case K::ProgramClearRefused:
      if (e.sdo) out += ", \"abort\": " + tools::json_string(nmt::to_string(e.sdo->abort));
      break;
    default:
      break;
  }
  if (e.connection) {
    // SDO manager kinds (DSP 302 §7.2.3): the connection, as 1F03h describes it, and its COB-IDs.
    const auto& c = *e.connection;
    out += ", \"connection\": {\"row\": " + std::to_string(c.row) +
           ", \"client_node_id\": " + std::to_string(c.srd) +
           ", \"client_index\": " + std::to_string(c.client_index) +
           ", \"server_node_id\": " + std::to_string(c.server) +
           ", \"server_index\": " + std::to_string(c.server_index) +
           ", \"request_cob_id\": " + std::to_string(c.request.word()) +
           ", \"response_cob_id\": " + std::to_string(c.response.word()) + "}";
  }
  if (e.lss_address)
    out += ", \"lss_address\": " + tools::json_string(nmt::address_digits(*e.lss_address));
  if (e.boot_try != 0) out += ", \"try\": " + std::to_string(e.boot_try);
  out += ", \"text\": " + tools::json_string(nmt::describe(e)) + "}\n";
  *json_ << out << std::flush;
}

void EventReporter::report_bus(const nmt::BusEvent& e, nmt::TimePoint at) {
  using K = nmt::BusEvent::Kind;
  const bool routine =
      e.kind == K::LostArbitration || e.kind == K::BusError || e.kind == K::ErrorWarning;
  if (!quiet_ && (verbose_ || !routine)) {
    note(seconds_text(start_, at) + "  bus: " + e.text);
  }
  if (json_ == nullptr) return;
  *json_ << "{\"time_s\": " << seconds_text(start_, at)
         << ", \"event\": " << tools::json_string(nmt::to_string(e.kind))
         << ", \"node_id\": 0, \"frame\": " << tools::json_string(nmt::to_candump(e.frame))
         << ", \"text\": " << tools::json_string(e.text) << "}\n"
         << std::flush;
}

namespace {
// The loop's transmit and error-frame counters in one line, or nothing when all are zero.
std::string bus_counters_text(const nmt::BusCounters& c) {
  std::vector<std::string> parts;
  if (c.queue_full != 0) {
    parts.push_back(tools::plural(c.queue_full, "send") + " waited for a full transmit queue");
  }
  if (c.send_failures != 0)
    parts.push_back(tools::plural(c.send_failures, "send") + " failed and retried");
  if (c.refused != 0) parts.push_back(tools::plural(c.refused, "frame") + " refused by the driver");
  if (c.error_frames != 0) {
    std::string text = tools::plural(c.error_frames, "error frame");
    std::vector<std::string> kinds;
    const auto add = [&kinds](std::uint64_t n, const char* what) {
      if (n != 0) kinds.push_back(std::to_string(n) + " " + what);
    };
    add(c.bus_off, "bus-off");
    add(c.restarted, "restarted");
    add(c.error_passive, "error passive");
    add(c.error_warning, "warning level");
    add(c.lost_arbitration, "lost arbitration");
    add(c.controller_overflows, "controller overflow");
    add(c.bus_errors, "bus error");
    if (!kinds.empty()) {
      text += " (";
      for (std::size_t i = 0; i < kinds.size(); ++i) text += (i == 0 ? "" : ", ") + kinds[i];
      text += ")";
    }
    parts.push_back(text);
  }
  if (c.bus_off_time != nmt::Duration::zero()) {
    parts.push_back(seconds_text(nmt::TimePoint{}, nmt::TimePoint{} + c.bus_off_time) +
                    " s in bus-off");
  }
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) out += (i == 0 ? "" : ", ") + parts[i];
  return out;
}
}  // namespace

std::optional<SimBusOptions> parse_bus_url(std::string_view tool, const std::string& url) {
  if (is_sim_url(url)) {
    auto parsed = parse_sim_url(url);
    if (!parsed) fail_command(tool, tools::kExitUsage, "--bus: " + parsed.error().message);
    return parsed.value();
  }
  if (auto syntax = nmt::check_bus_url(url); !syntax) {
    fail_command(tool, tools::kExitUsage, "--bus: " + syntax.error().message);
  }
  return std::nullopt;
}

std::optional<std::uint64_t> parse_hex_argument(std::string_view text, std::size_t digits) {
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    text.remove_prefix(2);
  } else if (!text.empty() && (text.back() == 'h' || text.back() == 'H')) {
    text.remove_suffix(1);
  }
  if (text.empty()) return std::nullopt;
  return cfg::parse_hex_number(text, digits);
}

std::set<std::uint8_t> parse_only(std::string_view tool, const std::string& text) {
  auto nodes = parse_node_list(text);
  if (!nodes)
    fail_command(tool, tools::kExitUsage, "--only " + text + ": " + nodes.error().message);
  return std::move(nodes).value();
}

namespace {

// NODE=TEXT of --program/--program-version: the node and the text; exit 2 when malformed.
std::pair<cfg::NodeId, std::string> node_assignment_or_exit(std::string_view option,
                                                            const std::string& spec) {
  const std::size_t eq = spec.find('=');
  const auto id = tools::parse_node_id_argument(std::string_view(spec).substr(0, eq));
  if (eq == std::string::npos || !id || eq + 1 == spec.size()) {
    std::cerr << "cfgmgr: " << option << " " << spec
              << ": expected NODE=" << (option == "--program" ? "FILE" : "VERSION")
              << " with NODE a node-ID (1..127)\n";
    exit_with(tools::kExitUsage);
  }
  return {*id, spec.substr(eq + 1)};
}

// --program/--program-version applied to the network; errors go to `diagnostics`.
void apply_program_overrides(cfg::Network& network, const ProgramOverrides& programs,
                             cfg::Diagnostics& diagnostics) {
  std::map<std::uint8_t, std::pair<std::string, std::optional<cfg::ProgramVersion>>> wanted;
  for (const auto& spec : programs.files) {
    auto [node, file] = node_assignment_or_exit("--program", spec);
    wanted[node.value()].first = file;
  }
  for (const auto& spec : programs.versions) {
    auto [node, text] = node_assignment_or_exit("--program-version", spec);
    auto version = cfg::parse_program_version(text);
    if (!version) {
      std::cerr << "cfgmgr: --program-version " << spec << ": " << version.error().message << '\n';
      exit_with(tools::kExitUsage);
    }
    wanted[node.value()].second = *version;
  }
  for (const auto& [id, program] : wanted) {
    const auto node = *cfg::NodeId::from(id);
    if (auto set = cfg::set_node_program(network, node, program.first, program.second); !set) {
      diagnostics.add("--program", 0, cfg::Severity::Error,
                      "node " + std::to_string(id) + ": " + set.error().message);
    }
  }
}

}  // namespace

std::shared_ptr<const cfg::Network> load_network_or_exit(const std::string& path, unsigned net,
                                                         const ProgramOverrides& programs) {
  cfg::NetworkOptions load_options;
  load_options.net = net;
  auto load = cfg::load_network(path, load_options);
  if (load.network) {
    apply_program_overrides(*load.network, programs, load.diagnostics);
    cfg::check_programs(*load.network, load.diagnostics);
  }
  tools::print_diagnostics(load.diagnostics);
  if (load.unreadable) exit_with(tools::kExitIo);
  if (!load.ok()) exit_with(tools::kExitInputErrors);
  return std::make_shared<const cfg::Network>(std::move(*load.network));
}

nmt::MasterConfig master_config_or_exit(std::string_view tool, const std::string& description,
                                        const std::shared_ptr<const cfg::Network>& network,
                                        const std::string& node_id_text,
                                        nmt::MasterOptions options) {
  std::uint8_t node_id = kDefaultMasterNodeId;
  if (!node_id_text.empty()) {
    const auto parsed = tools::parse_node_id_argument(node_id_text);
    if (!parsed) {
      fail_command(tool, tools::kExitUsage,
                   tools::node_id_argument_error("--node-id", node_id_text));
    }
    node_id = *parsed;
  } else if (network->master_node_id) {
    node_id = network->master_node_id->value();
  }
  if (const cfg::NetworkNode* clash = network->find(*cfg::NodeId::from(node_id))) {
    fail_command(tool, node_id_text.empty() ? tools::kExitInputErrors : tools::kExitUsage,
                 "the master's node-ID " + std::to_string(node_id) + " is also the node-ID of " +
                     clash->file + " (give another with --node-id N)");
  }
  options.configurations = std::make_shared<NetworkSource>(network);
  // DSP 302 §6: the master is the network's configuration manager, 1F20h-1F27h included; a
  // node with nothing stored reads the network's configuration (NetworkSource). Without a store
  // directory, what a tool writes over SDO lives as long as the process.
  if (!options.manager) options.manager = std::make_shared<cfg::ConfigManager>();
  // The master DCF goes through the typed configuration, as an embedder's master does.
  auto config =
      nmt::MasterConfig::from_dcf(network->master, *cfg::NodeId::from(node_id), std::move(options));
  // What the DCF says is checked here, so that a later failure of build_master_or_exit is the
  // caller's change.
  cfg::Status valid = config ? config->validate() : cfg::Status(config.error());
  if (!valid) {
    const std::string& from = network->master_from_file ? network->master_file : description;
    std::cerr << from << ": error: " << valid.error().message << '\n';
    exit_with(tools::kExitInputErrors);
  }
  return std::move(config).value();
}

nmt::NmtMaster build_master_or_exit(const nmt::MasterConfig& config, const std::string& description,
                                    const cfg::Network& network) {
  auto master = config.build();
  if (!master) {
    const std::string& from = network.master_from_file ? network.master_file : description;
    std::cerr << from << ": error: " << master.error().message << '\n';
    exit_with(tools::kExitInputErrors);
  }
  return std::move(master).value();
}

nmt::NmtMaster build_master(std::string_view tool, const std::string& description,
                            const std::shared_ptr<const cfg::Network>& network,
                            const std::string& node_id_text, nmt::MasterOptions options) {
  return build_master_or_exit(
      master_config_or_exit(tool, description, network, node_id_text, std::move(options)),
      description, *network);
}

std::vector<nmt::SimulatedDevice> simulated_devices_or_exit(std::string_view tool,
                                                            const cfg::Network& network,
                                                            const SimBusOptions& sim) {
  std::vector<cfg::NodeId> skipped;
  auto built = simulated_devices(network, sim, &skipped);
  if (!built) {
    std::cerr << built.error().message << '\n';
    exit_with(tools::kExitInputErrors);
  }
  for (const cfg::NodeId node : skipped) {
    std::cerr << prefix(tool) << "note: node " << int{node.value()}
              << " has no DCF (a concise DCF only): not simulated\n";
  }
  return std::move(built).value();
}

RunOutcome run_master_on_sim(nmt::NmtMaster master, const cfg::Network& network,
                             const SimBusOptions& sim, const RunLimits& limits,
                             EventReporter& reporter, const RunTraces& traces) {
  std::vector<nmt::SimulatedDevice> built = simulated_devices_or_exit(limits.tool, network, sim);
  OpenTraces trace_files = open_traces(limits.tool, traces);
  nmt::SimBus bus(sim.bitrate_bps);
  bus.set_loss_rate(sim.loss, sim.seed);
  std::vector<nmt::TraceWriter*> writers;
  for (auto& w : trace_files.writers) {
    writers.push_back(w.get());
    bus.add_observer(nmt::trace_observer(*w));
  }
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  bool state_failed = false;
  // The network's node of each device (simulated_devices builds one per node with a DCF, in
  // order): its state file's, whatever node-ID LSS gives the device.
  std::vector<cfg::NodeId> owners;
  for (const auto& n : network.nodes) {
    if (n.dcf) owners.push_back(n.node_id);
  }
  for (auto& device : built) {
    devices.push_back(
        std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(std::move(device)));
    bus.attach(*devices.back());
    if (sim.state_dir.empty()) continue;
    // The device's non-volatile memory follows every save (1010h), restore (1011h) and LSS
    // store at once, as on a real device: a run that is cut short keeps what was saved before.
    auto* d = devices.back().get();
    const cfg::NodeId owner = owners[devices.size() - 1];
    d->set_event_handler([d, owner, &sim, &limits, &reporter, &state_failed](
                             const nmt::SlaveEvent& e, nmt::TimePoint) {
      if (!nmt::changes_device_state(e.kind)) return;
      if (auto saved = nmt::save_device_state(sim.state_dir, owner, d->engine().node()); !saved) {
        if (!state_failed) reporter.note(prefix(limits.tool) + saved.error().message);
        state_failed = true;
      }
    });
  }
  nmt::SimEngineNode<nmt::NmtMaster> node(std::move(master));
  bus.attach(node);
  bool continued = false;
  node.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint) {
    reporter.report(e);
    persist_when_asked(e, node.engine(), reporter, limits.tool,
                       [&node](auto fn) { node.apply(fn); });
    continue_when_awaited(node.engine(), continued, [&node](auto fn) { node.apply(fn); });
  });

  std::cerr << prefix(limits.tool) << "node-ID " << int{node.engine().node_id().value()} << ", "
            << tools::plural(devices.size(), "simulated device") << " on sim: at "
            << sim.bitrate_bps << " bit/s\n";
  g_stop.store(false);
  const StopSignals signals;
  for (auto& device : devices) {
    device->apply(
        [](nmt::SimulatedDevice& d, nmt::TimePoint now, auto& out) { d.start(now, out); });
  }
  node.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.start(now, out); });

  const bool bounded = limits.run_for_s.has_value();
  const bool until_ended = limits.until_startup_ends && !bounded;
  const nmt::TimePoint limit =
      nmt::TimePoint{} + seconds_to_duration(bounded ? *limits.run_for_s : limits.bound_s);
  // Without run_for, sim: ends once NMT start-up has (there is no one to press Ctrl-C in a
  // script, and simulated time runs far ahead of the wall clock).
  const bool stopped = bus.run_until(
      [&] { return g_stop.load() || (until_ended && ended(limits, reporter)); }, limit);
  if (bounded && !stopped) bus.run_until(limit);  // the clock to the bound, nothing is due
  // Start-up ended with the master's last frames (the starts of §3.1 h) queued: let them go
  // out, as a real master's would, so that the slaves and the traces get them.
  if (stopped && !g_stop.load()) {
    bus.run_until([&] { return bus.frames_queued(node) == 0; },
                  bus.now() + std::chrono::seconds(1));
  }
  const bool late = timed_out(limits, reporter);
  close_traces(limits.tool, writers);
  if (state_failed) exit_with(tools::kExitIo);
  const auto stats = bus.statistics();
  reporter.note(prefix(limits.tool) + seconds_text(nmt::TimePoint{}, bus.now()) + " s simulated, " +
                std::to_string(stats.frames) + " frames, bus load " +
                std::to_string(std::lround(stats.load() * 100.0)) + "%");
  return {bus.now() - nmt::TimePoint{}, late};
}

RunOutcome run_master_on_bus(nmt::NmtMaster master, const std::string& url, const RunLimits& limits,
                             EventReporter& reporter, const RunTraces& traces) {
  auto opened = nmt::open_bus(url);
  if (!opened) fail_command(limits.tool, tools::kExitIo, opened.error().message);
  std::unique_ptr<nmt::Bus> bus = std::move(opened).value();
  // Each trace wraps the bus (TracingBus records what it sends and receives).
  std::vector<nmt::TracingBus*> tracing;
  for (auto& w : open_traces(limits.tool, traces).writers) {
    auto wrapped = std::make_unique<nmt::TracingBus>(std::move(bus), std::move(w));
    tracing.push_back(wrapped.get());
    bus = std::move(wrapped);
  }
  nmt::BusEventLoop loop(*bus);
  reporter.set_start(loop.now());
  nmt::EngineRef<nmt::NmtMaster> ref(master);
  loop.add(ref);
  // --store DIR: entries are written on a worker thread, so an fsync does not stall the loop;
  // the SDO confirmation leaves once the entry is durable (nmt/entry_persister.hpp).
  nmt::EntryPersister persister(ref, [&reporter, &limits](const cfg::Status& done) {
    if (!done) reporter.note(prefix(limits.tool) + "error: " + done.error().message);
  });
  bool continued = false;
  ref.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint) {
    reporter.report(e);
    persister.on_event(e);
    continue_when_awaited(master, continued, [&ref](auto fn) { ref.apply(fn); });
    if (limits.until_startup_ends && !limits.run_for_s && ended(limits, reporter)) {
      loop.request_stop();
    }
  });
  loop.set_bus_event_handler(
      [&reporter](const nmt::BusEvent& e, nmt::TimePoint at) { reporter.report_bus(e, at); });
  const bool forever = !limits.run_for_s && !limits.until_startup_ends;
  std::cerr << prefix(limits.tool) << "node-ID " << int{master.node_id().value()} << " on "
            << bus->url() << (forever ? "; stop with Ctrl-C" : "") << '\n';

  g_stop.store(false);
  const StopSignals signals;
  g_running_loop.store(&loop);
  ref.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.start(now, out); });
  const nmt::TimePoint began = loop.now();
  const cfg::Status status =
      g_stop.load() ? cfg::Status{}
      : forever     ? loop.run()
                    : loop.run_for(seconds_to_duration(limits.run_for_s.value_or(limits.bound_s)));
  g_running_loop.store(nullptr);
  if (!status) fail_command(limits.tool, tools::kExitIo, status.error().message);
  // Start-up's last frames (the starts of §3.1 h) may wait in the loop's transmit queue behind
  // a full interface queue: out with them, unless a signal asked to stop.
  if (!g_stop.load()) {
    loop.clear_stop();
    if (auto sent = loop.run_until_sent(std::chrono::seconds(1)); !sent) {
      fail_command(limits.tool, tools::kExitIo, sent.error().message);
    }
  }
  if (const std::string counters = bus_counters_text(loop.counters()); !counters.empty()) {
    reporter.note(prefix(limits.tool) + "bus: " + counters);
  }
  std::vector<nmt::TraceWriter*> writers;
  writers.reserve(tracing.size());
  for (auto* t : tracing) writers.push_back(&t->trace());
  close_traces(limits.tool, writers);
  return {loop.now() - began, timed_out(limits, reporter)};
}

}  // namespace cfgmgr
