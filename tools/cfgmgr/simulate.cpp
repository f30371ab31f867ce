// cfgmgr simulate --bus URL DEVICE.eds[@NODE-ID]...: run simulated CANopen slaves built from
// device files on a real bus (UDP multicast, SocketCAN) until SIGINT/SIGTERM or --for. All
// protocol behaviour is libnmt's SimulatedDevice (a slave node with faults) driven by its
// BusEventLoop; this file parses arguments, opens the bus and traces, and prints.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/device_file.hpp"
#include "cfg/node_id.hpp"
#include "commands.hpp"
#include "network_source.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/trace.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/sim/device_state.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace cfgmgr {
namespace {

struct SimulateOptions {
  std::string bus = "udp://239.74.163.2:43113";
  std::vector<std::string> devices;
  std::optional<double> for_seconds;
  bool verbose = false;
  std::string pcap;
  std::string candump;
  double boot_delay_ms = 0;
  double sdo_latency_ms = 0;
  double loss = 0;
  std::string state_dir;
};

// The loop a signal handler stops; set only while run_simulation runs.
std::atomic<nmt::BusEventLoop*> g_running_loop{nullptr};

extern "C" void on_stop_signal(int) {
  if (auto* loop = g_running_loop.load()) loop->request_stop();
}

struct DeviceArg {
  std::string path;
  std::optional<std::uint8_t> node_id;
  /// @255 or @unconfigured: the device powers on without node-ID (CiA 305 FFh) and waits for
  /// LSS to give it one.
  bool unconfigured = false;
};

// "file.eds@5" / "file.eds@0x05" -> path and node-ID; "file.eds@255" / "file.eds@0xFF" /
// "file.eds@unconfigured" -> unconfigured. A suffix that is not a number is part of the path.
// Fails on a number outside 1..127 and 255.
cfg::Result<DeviceArg> parse_device_arg(const std::string& arg) {
  const auto at = arg.rfind('@');
  if (at == std::string::npos || at + 1 == arg.size()) return DeviceArg{arg, std::nullopt};
  const std::string suffix = arg.substr(at + 1);
  // The node-ID argument rules every tool uses (tools/common/tool_support.hpp).
  const auto value = tools::node_id_argument_value(suffix, /*unconfigured_ok=*/true);
  if (!value) return DeviceArg{arg, std::nullopt};
  // CiA 305: node-ID FFh is "not configured".
  if (*value == nmt::lss::kUnconfigured) return DeviceArg{arg.substr(0, at), std::nullopt, true};
  const auto node = cfg::NodeId::from(*value);
  if (!node) {
    return cfg::Error{arg + ": node-ID " + suffix +
                      " is out of range 1..127 (255 or 'unconfigured': a device without node-ID "
                      "that waits for LSS)"};
  }
  return DeviceArg{arg.substr(0, at), node->value()};
}

std::string seconds_since(nmt::TimePoint start, nmt::TimePoint now) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%10.6f", static_cast<double>((now - start).count()) / 1e6);
  return buf;
}

// "node 5", or "unconfigured" while the device waits for LSS to give it a node-ID.
std::string device_label(const nmt::SlaveNode& node) {
  if (!node.has_node_id()) return "unconfigured";
  return "node " + std::to_string(node.node_id().value());
}

nmt::Duration ms_to_duration(double ms) {
  return nmt::Duration(static_cast<std::int64_t>(ms * 1000.0));
}

void run_simulate(const SimulateOptions& options) {
  if (options.loss < 0.0 || options.loss > 1.0) {
    std::cerr << "cfgmgr simulate: --loss must be between 0 and 1\n";
    exit_with(tools::kExitUsage);
  }
  // A --bus that does not parse is a usage error; one that parses but cannot be opened is I/O.
  if (auto syntax = nmt::check_bus_url(options.bus); !syntax) {
    std::cerr << "cfgmgr simulate: --bus: " << syntax.error().message << '\n';
    exit_with(tools::kExitUsage);
  }
  nmt::DeviceFaults faults;
  faults.boot_delay = ms_to_duration(options.boot_delay_ms);
  faults.sdo_latency = ms_to_duration(options.sdo_latency_ms);
  faults.frame_loss_rate = options.loss;

  // Devices first: a bad file should not touch the bus.
  // Held by pointer: the loop's EngineRefs keep their addresses.
  std::vector<std::unique_ptr<nmt::SimulatedDevice>> devices;
  std::vector<std::string> names;
  std::vector<bool> unconfigured;  // per device: powers on without node-ID
  // Per device, whose --state file it has: the node-ID it was given, or the LSS address of one
  // started unconfigured (LSS may give either another node-ID).
  std::vector<nmt::DeviceStateOwner> owners;
  std::map<std::uint8_t, std::string> by_node;
  std::map<nmt::LssAddress, std::string> by_address;  // --state: one file per LSS address
  for (const auto& arg : options.devices) {
    auto parsed = parse_device_arg(arg);
    if (!parsed) {
      std::cerr << "cfgmgr simulate: " << parsed.error().message << '\n';
      exit_with(tools::kExitUsage);
    }
    auto text = tools::read_input(parsed->path);
    if (!text) {
      std::cerr << text.error().message << '\n';
      exit_with(tools::exit_code_for(text.error()));
    }
    cfg::ReadOptions read_options;
    read_options.file_name = parsed->path;
    auto read = cfg::parse_device_description(*text, read_options);
    tools::print_diagnostics(read.diagnostics);
    if (!read.ok()) exit_with(tools::kExitInputErrors);
    if (parsed->unconfigured) {
      // The identity the file says, as for a device with a node-ID (node-ID 1 stands in for
      // $NODEID until LSS gives the real one, as in SlaveNode::create_unconfigured).
      auto device = nmt::SimulatedDevice::create_unconfigured(
          *read.device, with_identity_of(*read.device, *cfg::NodeId::from(1), faults));
      if (!device) {
        std::cerr << parsed->path
                  << ": error: cannot simulate it unconfigured (@255): " << device.error().message
                  << '\n';
        exit_with(tools::kExitInputErrors);
      }
      const nmt::LssAddress address = device->node().lss()->address();
      if (auto [it, inserted] = by_address.emplace(address, parsed->path);
          !inserted && !options.state_dir.empty()) {
        // Their --state file is named by the LSS address (nmt/sim/device_state.hpp): two such
        // devices would overwrite each other's. CiA 305 wants LSS addresses unique anyway.
        std::cerr << "cfgmgr simulate: --state: " << it->second << "@255 and " << parsed->path
                  << "@255 have the same LSS address " << nmt::address_digits(address)
                  << " and would share the state file lss-" << nmt::address_digits(address, '-')
                  << ".saved; give one its own serial number ([DeviceComissioning] "
                     "LSS_SerialNumber), or run them without --state\n";
        exit_with(tools::kExitUsage);
      }
      devices.push_back(std::make_unique<nmt::SimulatedDevice>(std::move(device).value()));
      names.push_back(parsed->path);
      unconfigured.push_back(true);
      owners.emplace_back(address);
      continue;
    }
    if (!parsed->node_id && !read.device->node_id()) {
      std::cerr << parsed->path << ": error: no node-ID: give one (" << parsed->path
                << "@ID, or @255 for a device that waits for LSS) or set NodeID in "
                   "[DeviceComissioning]\n";
      exit_with(tools::kExitInputErrors);
    }
    const std::uint8_t node_id = parsed->node_id ? *parsed->node_id : *read.device->node_id();
    const auto node = cfg::NodeId::from(node_id);
    if (!node) {
      std::cerr << parsed->path << ": error: node-ID " << int{node_id} << " is not 1..127\n";
      exit_with(tools::kExitInputErrors);
    }
    // The identity the file says, as `sim:` devices and the real device answer it.
    auto device = nmt::SimulatedDevice::create(*read.device, node_id,
                                               with_identity_of(*read.device, *node, faults));
    if (!device) {
      std::cerr << parsed->path << ": error: " << device.error().message << '\n';
      exit_with(tools::kExitInputErrors);
    }
    if (auto [it, inserted] = by_node.emplace(node_id, parsed->path); !inserted) {
      std::cerr << "cfgmgr simulate: node-ID " << int{node_id} << " given twice (" << it->second
                << " and " << parsed->path << ")\n";
      exit_with(tools::kExitUsage);
    }
    devices.push_back(std::make_unique<nmt::SimulatedDevice>(std::move(device).value()));
    names.push_back(parsed->path);
    unconfigured.push_back(false);
    owners.emplace_back(*node);
  }
  if (!options.state_dir.empty()) {
    // Like a real device, each powers on with what it stored last time: 1010h-saved values
    // (CiA 301 §7.5.2.13) and the node-ID and bit rate of LSS store configuration (CiA 305).
    for (std::size_t i = 0; i < devices.size(); ++i) {
      auto saved = nmt::load_device_state(options.state_dir, owners[i]);
      if (!saved) {
        std::cerr << saved.error().message << " (remove the file to start from the device file)\n";
        exit_with(tools::exit_code_for(saved.error()));
      }
      if (*saved) nmt::restore_device_state(devices[i]->node(), std::move(**saved));
    }
  }

  auto opened = nmt::open_bus(options.bus);
  if (!opened) {
    std::cerr << "cfgmgr simulate: " << opened.error().message << '\n';
    exit_with(tools::kExitIo);
  }
  std::unique_ptr<nmt::Bus> bus = std::move(opened).value();
  nmt::TracingBus* pcap = nullptr;
  nmt::TracingBus* candump = nullptr;
  auto add_trace = [&bus](const std::string& path, auto open) -> nmt::TracingBus* {
    auto writer = open(path);
    if (!writer) {
      std::cerr << "cfgmgr simulate: " << writer.error().message << '\n';
      exit_with(tools::kExitIo);
    }
    auto traced = std::make_unique<nmt::TracingBus>(std::move(bus), std::move(writer).value());
    auto* raw = traced.get();
    bus = std::move(traced);
    return raw;
  };
  if (!options.pcap.empty()) {
    pcap = add_trace(options.pcap, [](const std::string& p) { return nmt::open_pcap(p); });
  }
  if (!options.candump.empty()) {
    candump =
        add_trace(options.candump, [](const std::string& p) { return nmt::open_candump_log(p); });
  }

  nmt::BusEventLoop loop(*bus);
  const nmt::TimePoint start = loop.now();
  std::vector<std::unique_ptr<nmt::EngineRef<nmt::SimulatedDevice>>> refs;
  for (std::size_t i = 0; i < devices.size(); ++i) {
    auto& device = *devices[i];
    nmt::EngineRef<nmt::SimulatedDevice>::EventHandler print;
    if (options.verbose) {
      // The node-ID it has now: an unconfigured device gets one by LSS while it runs.
      print = [&device, start](const nmt::SlaveEvent& e, nmt::TimePoint) {
        std::cout << seconds_since(start, e.at) << "  " << device_label(device.node()) << "  "
                  << nmt::to_string(e.kind) << ": " << e.text << '\n'
                  << std::flush;
      };
    }
    if (!options.state_dir.empty()) {
      // The state file follows every save, restore and LSS store at once, as a device's
      // memory: a run killed later keeps it.
      print = [print, &device, &options, owner = owners[i]](const nmt::SlaveEvent& e,
                                                            nmt::TimePoint at) {
        if (print) print(e, at);
        if (!nmt::changes_device_state(e.kind)) return;
        if (auto saved = nmt::save_device_state(options.state_dir, owner, device.node()); !saved) {
          std::cerr << "cfgmgr simulate: " << saved.error().message << '\n';
        }
      };
    }
    refs.push_back(std::make_unique<nmt::EngineRef<nmt::SimulatedDevice>>(device, print));
    loop.add(*refs.back());
    // What it powers on as: a node-ID LSS stored (--state) overrides the command line's.
    const auto& stored = device.node().lss_stored();
    const std::uint8_t id = stored            ? stored->node_id
                            : unconfigured[i] ? nmt::lss::kUnconfigured
                                              : device.node().node_id().value();
    if (id == nmt::lss::kUnconfigured) {
      std::cout << "unconfigured (LSS address "
                << nmt::address_digits(device.node().lss()->address()) << ")";
    } else {
      std::cout << "node " << int{id} << (stored ? " (node-ID stored by LSS)" : "");
    }
    std::cout << ": " << names[i] << '\n';
  }
  if (options.verbose) {
    loop.set_observer(
        [start](const nmt::CanFrame& f, nmt::TimePoint t, nmt::BusEventLoop::Direction d) {
          std::cout << seconds_since(start, t) << "  "
                    << (d == nmt::BusEventLoop::Direction::Received ? "rx" : "tx") << "  "
                    << nmt::to_candump(f) << '\n'
                    << std::flush;
        });
  }
  std::cout << "simulating " << tools::plural(devices.size(), "device") << " on " << bus->url()
            << (options.for_seconds ? "" : "; stop with Ctrl-C") << '\n'
            << std::flush;

  struct sigaction action {};
  action.sa_handler = on_stop_signal;
  sigemptyset(&action.sa_mask);
  struct sigaction old_int {};
  struct sigaction old_term {};
  g_running_loop.store(&loop);
  sigaction(SIGINT, &action, &old_int);
  sigaction(SIGTERM, &action, &old_term);

  // Through apply: what a device reports at power-on goes to its printer like any event.
  for (auto& ref : refs) {
    ref->apply([](nmt::SimulatedDevice& d, nmt::TimePoint now, nmt::SimulatedDevice::Output& out) {
      d.start(now, out);
    });
  }
  const cfg::Status status = options.for_seconds
                                 ? loop.run_for(ms_to_duration(*options.for_seconds * 1000.0))
                                 : loop.run();

  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  g_running_loop.store(nullptr);

  std::cout << "frames: " << loop.frames_received() << " received, " << loop.frames_sent()
            << " sent\n"
            << std::flush;
  bool trace_failed = false;
  for (auto* traced : {pcap, candump}) {
    if (!traced) continue;
    auto flushed = traced->trace().flush();
    const cfg::Status status_after = traced->trace().status();  // by value: keep it alive
    if (!flushed || !status_after) {
      const cfg::Error why = !flushed ? flushed.error() : status_after.error();
      std::cerr << "cfgmgr simulate: trace " << traced->trace().path().string() << ": "
                << why.message << '\n';
      trace_failed = true;
    }
  }
  if (!status) {
    std::cerr << "cfgmgr simulate: " << status.error().message << '\n';
    exit_with(tools::kExitIo);
  }
  if (trace_failed) exit_with(tools::kExitIo);
}

}  // namespace

void add_simulate_command(CLI::App& app) {
  auto options = std::make_shared<SimulateOptions>();
  auto* cmd = app.add_subcommand(
      "simulate",
      "Run simulated CANopen slaves built from EDS/DCF files on a bus: each sends its boot-up "
      "message, answers SDO, obeys NMT, produces heartbeat per its 1017h (or answers node "
      "guarding), saves parameters on 1010h, until Ctrl-C or --for");
  cmd->add_option("devices", options->devices,
                  "Device files, each optionally with @NODE-ID (else [DeviceComissioning] "
                  "NodeID of a DCF)")
      ->required()
      ->type_name("DEVICE.eds[@NODE-ID]");
  cmd->add_option("--bus", options->bus,
                  "Bus URL: udp://GROUP:PORT (python-can udp_multicast compatible) or "
                  "socketcan:IFNAME")
      ->capture_default_str()
      ->type_name("URL");
  cmd->add_option("--for", options->for_seconds, "Stop after this many seconds")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("-v,--verbose", options->verbose,
                "Print every frame received (rx) and sent (tx) and what each device does");
  cmd->add_option("--trace", options->pcap, "Record the traffic as pcap (Wireshark, tshark)")
      ->type_name("FILE.pcap");
  cmd->add_option("--candump", options->candump, "Record the traffic as a candump -l log")
      ->type_name("FILE.log");
  cmd->add_option("--boot-delay", options->boot_delay_ms,
                  "Fault: every device boots this many ms after start or an NMT reset")
      ->type_name("MS")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--sdo-latency", options->sdo_latency_ms,
                  "Fault: every SDO response leaves this many ms after its request")
      ->type_name("MS")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--loss", options->loss,
                  "Fault: each frame a device sends or receives is lost with this probability")
      ->type_name("RATE");
  cmd->add_option(
         "--state", options->state_dir,
         "Keep what each device stores in DIR, one file per device: the parameters "
         "saved with 1010h, the node-ID and bit rate of LSS store configuration, and the "
         "program images downloaded to 1F50h (DSP 302 §9, each in a file of its own: "
         "node-NN.programPP.bin); the next run with the same DIR powers them on with it, as a "
         "real device after a power cycle (files: node-NN.saved for DEVICE@NN, "
         "lss-VENDOR-PRODUCT-REVISION-SERIAL.saved for DEVICE@255; two DEVICE@255 with one LSS "
         "address would share a file and are refused, exit 2)")
      ->type_name("DIR");
  cmd->footer(std::string(
      "Examples:\n"
      "  cfgmgr simulate --bus udp://239.74.163.2:43113 io_module.eds@2 drive.eds@3\n"
      "  cfgmgr simulate --bus socketcan:vcan0 node4.dcf -v --candump run.log\n"
      "  cfgmgr simulate io.eds@5 --for 10 --trace run.pcap --sdo-latency 50\n"
      "  cfgmgr simulate --state /tmp/devices drive.eds@255\n"
      "    (after `cfgmgr lss set-id ADDRESS 5` the next run with the same --state boots node "
      "5)\n\n"
      "Ready: the line 'simulating N devices on BUS' on standard output says the bus is open "
      "and the devices are about to power on; a script or test that waits for it (rather than "
      "a fixed time) knows that frames it sends from then on reach them.\n\n"
      "Exit codes:\n"
      "  0  stopped by Ctrl-C/SIGTERM or --for elapsed\n"
      "  1  a device file has errors, or a device cannot be built from it (no node-ID, "
      "bad value), or a --state file is damaged\n"
      "  2  usage error (bad command line, node-ID twice, out of range, a --bus URL that does "
      "not parse, with --state two DEVICE@255 with one LSS address)\n"
      "  3  I/O error: a file cannot be read, the bus cannot be opened or fails, a trace "
      "cannot be written\n"));
  cmd->callback([options] { run_simulate(*options); });
}

}  // namespace cfgmgr
