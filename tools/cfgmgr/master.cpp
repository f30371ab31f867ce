// cfgmgr master NETWORK --bus URL: the CiA 302-2 NMT master (nmt::NmtMaster) as a program. It
// loads the network description (cfg/network.hpp), builds the master from the master's DCF or
// the derived one, gives it the nodes' configurations (NetworkSource) and runs it until
// SIGINT/SIGTERM or --run-for: on a real bus through BusEventLoop, on `sim:` on the simulated
// bus with a simulated device per node. All protocol behaviour is the engine's; this file parses
// arguments, wires the pieces and prints the events.
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/network.hpp"
#include "cfg/node_id.hpp"
#include "commands.hpp"
#include "network_source.hpp"
#include "nmt/bus.hpp"
#include "nmt/bus_event_loop.hpp"
#include "nmt/nmt_master.hpp"
#include "nmt/sim_bus.hpp"
#include "nmt/simulated_device.hpp"

namespace cfgmgr {
namespace {

/// The master's node-ID when neither --node-id nor the master DCF gives one: 7Fh, the highest,
/// so that the slaves keep the low node-IDs (and their higher-priority COB-IDs).
constexpr std::uint8_t kDefaultMasterNodeId = 0x7F;
/// How long `sim:` without --run-for may take, in simulated seconds, for NMT start-up to end.
constexpr double kSimDefaultBoundS = 60.0;
/// Exit code when NMT start-up did not end in operation (as `cfgmgr push` uses it).
constexpr int kExitMandatoryFailed = 4;

struct MasterCliOptions {
  std::string network;
  std::string bus;
  std::string node_id;
  unsigned net = 1;
  std::optional<double> run_for_s;
  std::string json_events;
  bool verbose = false;
};

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

[[noreturn]] void fail(int code, const std::string& message) {
  std::cerr << "cfgmgr master: " << message << '\n';
  exit_with(code);
}

std::string seconds_text(nmt::TimePoint start, nmt::TimePoint at) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>((at - start).count()) / 1e6);
  return buf;
}

std::string_view event_name(nmt::MasterEvent::Kind kind) {
  using K = nmt::MasterEvent::Kind;
  switch (kind) {
    case K::NotMaster:
      return "not_master";
    case K::StartupRefused:
      return "startup_refused";
    case K::StartupBegan:
      return "startup_began";
    case K::BootStepChanged:
      return "boot_step";
    case K::SlaveBooted:
      return "slave_booted";
    case K::BootError:
      return "boot_error";
    case K::StartupHalted:
      return "startup_halted";
    case K::StartupAwaitsApplication:
      return "startup_awaits_application";
    case K::StartupComplete:
      return "startup_complete";
    case K::MasterStateChanged:
      return "master_state";
    case K::SlaveStateChanged:
      return "slave_state";
    case K::HeartbeatLost:
      return "heartbeat_lost";
    case K::GuardingLost:
      return "guarding_lost";
    case K::ErrorControlResolved:
      return "error_control_resolved";
    case K::BootUp:
      return "boot_up";
    case K::NmtCommandSent:
      return "nmt_command";
    case K::ApplicationStep:
      return "application_step";
    case K::SdoFinished:
      return "sdo_finished";
  }
  return "unknown";
}

// Prints the master's events (one line each on stderr, JSON lines in --json-events) and keeps
// what the exit code depends on.
class Reporter {
 public:
  Reporter(bool verbose, std::ostream* json) : verbose_(verbose), json_(json) {}

  /// Event times are printed as seconds since `start` (0 on sim:).
  void set_start(nmt::TimePoint start) { start_ = start; }

  void report(const nmt::MasterEvent& e) {
    using K = nmt::MasterEvent::Kind;
    std::string line;
    const std::string node = "node " + std::to_string(e.node_id) + ": ";
    bool again = false;
    switch (e.kind) {
      case K::NotMaster:
      case K::StartupRefused:
        finished_ = true;
        line = e.text;
        break;
      case K::StartupBegan:
        line = "NMT start-up began";
        break;
      case K::SlaveBooted:
        again = !booted_.insert(e.node_id).second;
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
          line = node + "boot error: " + e.text;
        }
        if (!e.final) line += " (trying again)";
        break;
      case K::StartupHalted:
        halted_ = true;
        finished_ = true;
        line = e.text;  // "NMT start-up halted: mandatory node N failed with status X (...)"
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
      default:
        if (verbose_) line = e.text;
        break;
    }
    if (!line.empty())
      std::cerr << seconds_text(start_, e.at) << "  " << line << '\n' << std::flush;
    if (json_ != nullptr) write_json(e);
  }

  bool finished() const { return finished_; }
  bool complete() const { return complete_; }
  bool halted() const { return halted_; }

 private:
  // {"time_s": 0.512, "event": "boot_error", "node_id": 3, "error": "C", "description": ...}
  void write_json(const nmt::MasterEvent& e) {
    using K = nmt::MasterEvent::Kind;
    std::string out = "{\"time_s\": " + seconds_text(start_, e.at) +
                      ", \"event\": " + tools::json_string(event_name(e.kind)) +
                      ", \"node_id\": " + std::to_string(e.node_id);
    switch (e.kind) {
      case K::BootError:
        if (e.error) {
          out += ", \"error\": " + tools::json_string(std::string(1, nmt::letter(*e.error))) +
                 ", \"description\": " + tools::json_string(nmt::describe(*e.error));
        } else {
          out += ", \"error\": null";
        }
        out += std::string(", \"final\": ") + (e.final ? "true" : "false");
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
      default:
        break;
    }
    out += ", \"text\": " + tools::json_string(e.text) + "}\n";
    *json_ << out << std::flush;
  }

  nmt::TimePoint start_{0};
  bool verbose_;
  std::ostream* json_;
  std::set<std::uint8_t> booted_;
  bool finished_ = false;
  bool complete_ = false;
  bool halted_ = false;
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

nmt::Duration seconds_to_duration(double s) {
  return nmt::Duration(static_cast<std::int64_t>(s * 1e6));
}

// The simulated bus: the master and a simulated device per node, in simulated time.
void run_on_sim(nmt::NmtMaster master, const cfg::Network& network, const SimBusOptions& sim,
                const MasterCliOptions& options, Reporter& reporter) {
  std::vector<cfg::NodeId> skipped;
  auto built = simulated_devices(network, sim, &skipped);
  if (!built) {
    std::cerr << built.error().message << '\n';
    exit_with(tools::kExitInputErrors);
  }
  for (const cfg::NodeId node : skipped) {
    std::cerr << "cfgmgr master: note: node " << int{node.value()}
              << " has no DCF (a concise DCF only): not simulated\n";
  }
  nmt::SimBus bus(sim.bitrate_bps);
  bus.set_loss_rate(sim.loss, sim.seed);
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  for (auto& device : built.value()) {
    devices.push_back(
        std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(std::move(device)));
    bus.attach(*devices.back());
  }
  nmt::SimEngineNode<nmt::NmtMaster> node(std::move(master));
  bus.attach(node);
  bool continued = false;
  node.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint) {
    reporter.report(e);
    continue_when_awaited(node.engine(), continued, [&node](auto fn) { node.apply(fn); });
  });

  std::cerr << "cfgmgr master: node-ID " << int{node.engine().node_id().value()} << ", "
            << tools::plural(devices.size(), "simulated device") << " on sim: at "
            << sim.bitrate_bps << " bit/s\n";
  for (auto& device : devices) {
    device->apply([](nmt::SimulatedDevice& d, nmt::TimePoint now, auto&) { d.power_on(now); });
  }
  node.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.start(now, out); });

  const bool bounded = options.run_for_s.has_value();
  const nmt::TimePoint limit =
      nmt::TimePoint{} + seconds_to_duration(bounded ? *options.run_for_s : kSimDefaultBoundS);
  // Without --run-for, sim: ends once NMT start-up has (there is no one to press Ctrl-C in a
  // script, and simulated time runs far ahead of the wall clock).
  const bool stopped =
      bus.run_until([&] { return g_stop.load() || (!bounded && reporter.finished()); }, limit);
  if (bounded && !stopped) bus.run_until(limit);  // the clock to the bound, nothing is due
  if (!bounded && !reporter.finished() && !g_stop.load()) {
    std::cerr << "cfgmgr master: NMT start-up did not end within " << kSimDefaultBoundS
              << " s of simulated time (give --run-for to run longer)\n";
    exit_with(kExitMandatoryFailed);
  }
  const auto stats = bus.statistics();
  std::cerr << "cfgmgr master: " << seconds_text(nmt::TimePoint{}, bus.now()) << " s simulated, "
            << stats.frames << " frames, bus load " << std::lround(stats.load() * 100.0) << "%\n";
}

// A real bus (SocketCAN, UDP): the engine in the real-time event loop.
void run_on_bus(nmt::NmtMaster master, const MasterCliOptions& options, Reporter& reporter) {
  auto opened = nmt::open_bus(options.bus);
  if (!opened) fail(tools::kExitIo, opened.error().message);
  std::unique_ptr<nmt::Bus> bus = std::move(opened).value();
  nmt::BusEventLoop loop(*bus);
  reporter.set_start(loop.now());
  nmt::EngineRef<nmt::NmtMaster> ref(master);
  bool continued = false;
  ref.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint) {
    reporter.report(e);
    continue_when_awaited(master, continued, [&ref](auto fn) { ref.apply(fn); });
  });
  loop.add(ref);
  std::cerr << "cfgmgr master: node-ID " << int{master.node_id().value()} << " on " << bus->url()
            << (options.run_for_s ? "" : "; stop with Ctrl-C") << '\n';

  g_running_loop.store(&loop);
  ref.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.start(now, out); });
  const cfg::Status status = g_stop.load() ? cfg::Status{}
                             : options.run_for_s
                                 ? loop.run_for(seconds_to_duration(*options.run_for_s))
                                 : loop.run();
  g_running_loop.store(nullptr);
  if (!status) fail(tools::kExitIo, status.error().message);
}

std::uint8_t master_node_id(const MasterCliOptions& options, const cfg::Network& network) {
  if (!options.node_id.empty()) {
    const auto parsed = cfg::parse_integer_literal(options.node_id);
    if (!parsed.literal || !cfg::is_node_id(parsed.literal->value)) {
      fail(tools::kExitUsage, "--node-id " + options.node_id + ": expected a node-ID 1..127");
    }
    return static_cast<std::uint8_t>(parsed.literal->value);
  }
  if (network.master_node_id) return network.master_node_id->value();
  return kDefaultMasterNodeId;
}

void run_master(const MasterCliOptions& options) {
  // Arguments first, files next, the bus last: a typo should not touch the bus.
  std::optional<SimBusOptions> sim;
  if (is_sim_url(options.bus)) {
    auto parsed = parse_sim_url(options.bus);
    if (!parsed) fail(tools::kExitUsage, "--bus: " + parsed.error().message);
    sim = parsed.value();
  } else if (auto syntax = nmt::check_bus_url(options.bus); !syntax) {
    fail(tools::kExitUsage, "--bus: " + syntax.error().message);
  }
  if (options.net == 0) fail(tools::kExitUsage, "--net: networks are numbered from 1");

  cfg::NetworkOptions load_options;
  load_options.net = options.net;
  auto load = cfg::load_network(options.network, load_options);
  tools::print_diagnostics(load.diagnostics);
  if (load.unreadable) exit_with(tools::kExitIo);
  if (!load.ok()) exit_with(tools::kExitInputErrors);
  auto network = std::make_shared<const cfg::Network>(std::move(*load.network));

  const std::uint8_t node_id = master_node_id(options, *network);
  if (const cfg::NetworkNode* clash = network->find(*cfg::NodeId::from(node_id))) {
    fail(options.node_id.empty() ? tools::kExitInputErrors : tools::kExitUsage,
         "the master's node-ID " + std::to_string(node_id) + " is also the node-ID of " +
             clash->file + " (give another with --node-id N)");
  }
  nmt::MasterOptions master_options;
  master_options.configurations = std::make_shared<NetworkSource>(network);
  auto master = nmt::NmtMaster::create(network->master, *cfg::NodeId::from(node_id),
                                       std::move(master_options));
  if (!master) {
    const std::string& from = network->master_from_file ? network->master_file : options.network;
    std::cerr << from << ": error: " << master.error().message << '\n';
    exit_with(tools::kExitInputErrors);
  }

  std::ofstream json_file;
  if (!options.json_events.empty()) {
    json_file.open(options.json_events, std::ios::binary | std::ios::trunc);
    if (!json_file) {
      std::cerr << tools::io_error(options.json_events, "cannot open for writing").message << '\n';
      exit_with(tools::kExitIo);
    }
  }
  std::ostream* json = options.json_events.empty() ? nullptr : &json_file;

  g_stop.store(false);
  const StopSignals signals;
  Reporter reporter(options.verbose, json);
  if (sim) {
    run_on_sim(std::move(master).value(), *network, *sim, options, reporter);
  } else {
    run_on_bus(std::move(master).value(), options, reporter);
  }
  if (json != nullptr && !json_file.flush()) {
    std::cerr << tools::io_error(options.json_events, "write error").message << '\n';
    exit_with(tools::kExitIo);
  }
  if (reporter.halted()) exit_with(kExitMandatoryFailed);
}

}  // namespace

void add_master_command(CLI::App& app) {
  auto options = std::make_shared<MasterCliOptions>();
  auto* cmd = app.add_subcommand(
      "master",
      "Run the CiA 302-2 NMT master for a network: boot every slave (identity check, "
      "configuration download unless 1020h matches 1F26h/1F27h, start), keep them under "
      "heartbeat or guarding control, reboot and reconfigure slaves that restart or are "
      "replaced, and serve the master's objects (1F80h-1F8Ah ...) by SDO, until Ctrl-C or "
      "--run-for");
  cmd->add_option("network", options->network,
                  "CiA 306-3 project file (nodelist.cpj; DCF paths relative to it) or a "
                  "master DCF (CANopenManager=1) whose 1F20h/1F22h name node files with "
                  "DownloadFile=")
      ->required()
      ->type_name("NETWORK");
  cmd->add_option("--bus", options->bus,
                  "Bus URL: socketcan:IFNAME, udp://GROUP:PORT (python-can udp_multicast "
                  "compatible), or sim: for the simulated bus with a simulated device per node "
                  "built from the network's DCFs, in simulated time "
                  "(sim:?bitrate=500000&latency_ms=1&loss=0.01&seed=N)")
      ->required()
      ->type_name("URL");
  cmd->add_option("--node-id", options->node_id,
                  "The master's node-ID (1..127, e.g. 1 or 0x01); default: the master DCF's "
                  "NodeID, else 0x7F (127)")
      ->type_name("N");
  cmd->add_option("--net", options->net,
                  "Which network of the project file: 1 is [Topology], N is [TopologyN]")
      ->capture_default_str()
      ->type_name("N");
  cmd->add_option("--run-for", options->run_for_s,
                  "Stop after this many seconds (simulated seconds on sim:). Without it sim: "
                  "stops when NMT start-up has ended (at most 60 simulated seconds) and a real "
                  "bus runs until Ctrl-C/SIGTERM")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--json-events", options->json_events,
                  "Also write every event as one JSON object a line: time_s, event "
                  "(slave_booted, boot_error, heartbeat_lost, boot_up, startup_complete, ...), "
                  "node_id, text, and per event error/description/final, configured/entries/"
                  "bytes, assigned, step, state, command")
      ->type_name("FILE");
  cmd->add_flag("-v,--verbose", options->verbose,
                "Also print boot steps, NMT commands and state changes");
  cmd->footer(std::string(
      "Without a master DCF, every present node is a mandatory slave that is booted and "
      "started; the expected identity comes from its DCF and 1F26h/1F27h from its "
      "configuration (rules in cfg/network.hpp). With 1F80h bit 2 set, cfgmgr master is the "
      "application that lets the master enter operational, at once.\n\n"
      "Events, one a line on stderr, seconds since the start first: node N: booted, "
      "configured (E entries, B bytes) / booted (configuration up to date) / reconfigured / "
      "boot error X: <CiA 302-2 Table 1 text> / heartbeat lost / node guarding lost / boot-up "
      "seen; NMT start-up complete / halted.\n\n"
      "Examples:\n"
      "  cfgmgr master samples/network/nodelist.cpj --bus sim:\n"
      "  cfgmgr master samples/network/nodelist.cpj --bus sim:?loss=0.01 --run-for 5\n"
      "  cfgmgr master nodelist.cpj --bus socketcan:can0 --json-events events.jsonl\n"
      "  cfgmgr master master.dcf --bus udp://239.74.163.2:43113 --node-id 1\n\n"
      "Exit codes:\n"
      "  0  stopped by Ctrl-C/SIGTERM or --run-for, or (sim: without --run-for) NMT start-up "
      "complete\n"
      "  1  the network description has errors (printed as FILE:LINE: error: ...), or the "
      "master cannot be built from it\n"
      "  2  usage error (bad command line, a --bus URL that does not parse, a --node-id "
      "outside 1..127 or of a slave)\n"
      "  3  I/O error: the description cannot be read, the bus cannot be opened or fails, "
      "--json-events cannot be written\n"
      "  4  NMT start-up halted: a mandatory slave failed its boot (CiA 302-2 section 3.1 f); on "
      "sim: without --run-for also when start-up did not end within 60 s\n"));
  cmd->callback([options] { run_master(*options); });
}

}  // namespace cfgmgr
