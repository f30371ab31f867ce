// cfgmgr scan --bus URL --eds-dir DIR -o OUT: a live network into a project that push can
// commission again (a device swap in two commands). The bus work is libnmt's NetworkScanner
// (nmt/manager/network_scanner.hpp: only SDO uploads) beside LssProcedure's find_unconfigured
// (CiA 305 Fastscan, for devices without node-ID); the matching of identities against EDS files
// and the as-found DCFs are libcfg's (cfg/device_scan.hpp). This file parses arguments, runs the
// engines on the bus and prints.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/atomic_file.hpp"
#include "cfg/bytes.hpp"
#include "cfg/device_file.hpp"
#include "cfg/device_scan.hpp"
#include "cfg/hex.hpp"
#include "commands.hpp"
#include "master_run.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_event_text.hpp"
#include "nmt/lss/lss_procedure.hpp"
#include "nmt/manager/network_scanner.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "run_args.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "scan";
/// A device was found whose EDS the library lacks (it is in the project by its identity only),
/// or no device answered at all.
constexpr int kExitIncomplete = 4;

using Scanner = nmt::NetworkScanner;

struct ScanCliOptions {
  std::string bus;
  std::string eds_dir;
  std::string output_dir;
  std::string json;
  std::string nodes;  ///< --node 3 or 3,5-7; empty: 1..127
  double sdo_timeout_s = 0.5;
  unsigned retries = 2;
  unsigned probe_retries = 0;
  std::uint32_t bitrate = 0;
  double bus_load = 0.97;
  bool no_lss = false;
  bool no_stored_eds = false;
  std::string net_name = "scanned network";
};

/// One device as the scan found it, and what became of it.
struct ScannedNode {
  Scanner::NodeFound found;
  std::optional<cfg::DeviceDescription> eds{};  ///< the EDS used (library or the device's own)
  std::string eds_source{};                     ///< its path, or "1021h of the device"
  bool revision_exact = true;
  std::string note{};  ///< the nearest-revision note, or the line saying which EDS is missing
  std::map<cfg::ObjectAddress, std::vector<std::uint8_t>> values{};
  std::size_t read = 0;
  std::size_t skipped = 0;
  nmt::Duration took{0};
  bool done = false;
};

struct ScanResults {
  std::map<std::uint8_t, ScannedNode> nodes;
  std::set<std::uint8_t> absent_ids;  ///< node-IDs nobody answered at (in the end)
  std::size_t asked = 0;
  std::vector<nmt::LssAddress> unconfigured;  ///< LSS addresses of devices without node-ID
  std::string lss_problem;                    ///< the LSS scan's failure in words, if any
  nmt::Duration elapsed{0};
};

std::string optional_hex(const std::optional<std::uint32_t>& v) {
  return v ? cfg::hex(*v, 8) : std::string("-");
}

/// A terminal gets a line per node as it is done; pipes and files get the table only.
bool progress_wanted() {
  return ::isatty(STDERR_FILENO) == 1;
}

// Chooses the EDS of a found device and the entries to read: the device's own (1021h) when it
// parses, else the library's match.
std::vector<cfg::ObjectAddress> choose_eds(ScannedNode& node, const cfg::EdsLibrary& library,
                                           cfg::Diagnostics& diagnostics) {
  const auto& found = node.found;
  if (found.stored_eds) {
    cfg::ReadOptions read_options;
    read_options.mode = cfg::ReadMode::Tolerant;
    read_options.file_name = "node " + std::to_string(found.node.value()) + " 1021h";
    const std::string text(found.stored_eds->begin(), found.stored_eds->end());
    auto read = cfg::parse_device_description(text, read_options);
    if (read.device && !read.diagnostics.has_errors()) {
      node.eds = std::move(*read.device);
      node.eds_source = "1021h of the device";
      return cfg::entries_to_scan(*node.eds);
    }
    diagnostics.add(read_options.file_name, 0, cfg::Severity::Warning,
                    "the EDS the device stores does not read without errors; the library's is "
                    "used");
  }
  if (const auto match = library.match(found.identity)) {
    node.eds = *match->eds;
    node.eds_source = match->path;
    node.revision_exact = match->revision_exact;
    node.note = match->note;
    return cfg::entries_to_scan(*node.eds);
  }
  node.note = library.missing(found.identity);
  return {};
}

// The engines' events into `results`; `read` hands a found node's entries to the scanner (through
// the driver's apply, so its frames go out).
class Collector {
 public:
  using Read = std::function<void(cfg::NodeId, std::vector<cfg::ObjectAddress>)>;
  Collector(ScanResults& results, const cfg::EdsLibrary& library, cfg::Diagnostics& diagnostics)
      : results_(results), library_(library), diagnostics_(diagnostics) {}

  void on_event(const Scanner::Event& event, const Read& read) {
    if (const auto* absent = std::get_if<Scanner::NodeAbsent>(&event)) {
      results_.absent_ids.insert(absent->node.value());
    } else if (const auto* found = std::get_if<Scanner::NodeFound>(&event)) {
      ScannedNode& node =
          results_.nodes.insert_or_assign(found->node.value(), ScannedNode{.found = *found})
              .first->second;
      results_.absent_ids.erase(found->node.value());  // a later probe found it
      // The identity as read: the as-found DCF records it (cfg::as_found_dcf), so that the
      // project checks the device's revision, not the one of the EDS that matched.
      const auto& id = found->identity;
      if (id.device_type) node.values[{0x1000, 0}] = cfg::le32_bytes(*id.device_type);
      const std::optional<std::uint32_t>* subs[] = {&id.vendor_id, &id.product_code,
                                                    &id.revision_number};
      for (std::uint8_t sub = 1; sub <= 3; ++sub) {
        if (*subs[sub - 1]) node.values[{0x1018, sub}] = cfg::le32_bytes(**subs[sub - 1]);
      }
      auto entries = choose_eds(node, library_, diagnostics_);
      read(found->node, std::move(entries));
    } else if (const auto* entry = std::get_if<Scanner::EntryRead>(&event)) {
      if (entry->ok()) results_.nodes.at(entry->node.value()).values[entry->address] = entry->data;
    } else if (const auto* scanned = std::get_if<Scanner::NodeScanned>(&event)) {
      ScannedNode& node = results_.nodes.at(scanned->node.value());
      node.read = scanned->read;
      node.skipped = scanned->skipped;
      node.took = scanned->took;
      node.done = true;
      if (progress_) progress_line(node);
    }
  }

  void on_lss(const nmt::LssProcedureEvent& e) {
    if (e.kind == nmt::LssProcedureEvent::Kind::Done) {
      results_.unconfigured = e.addresses;
      lss_done_ = true;
    } else if (e.kind == nmt::LssProcedureEvent::Kind::Failed) {
      results_.lss_problem = nmt::describe(e);
      lss_done_ = true;
    }
  }
  bool lss_done() const { return lss_done_; }
  void set_progress(bool on) { progress_ = on; }

 private:
  void progress_line(const ScannedNode& node) {
    std::cerr << "cfgmgr scan: node " << int{node.found.node.value()} << ": "
              << (node.eds ? std::to_string(node.read) + " entries read" : "no EDS") << '\n';
  }

  ScanResults& results_;
  const cfg::EdsLibrary& library_;
  cfg::Diagnostics& diagnostics_;
  bool lss_done_ = false;
  bool progress_ = false;
};

nmt::ScanOptions scan_options(const ScanCliOptions& o, std::uint32_t bitrate) {
  nmt::ScanOptions options;
  options.sdo.timeout = sdo_timeout_or_exit(kTool, o.sdo_timeout_s);
  options.retries = o.retries;
  options.probe_retries = o.probe_retries;
  options.read_stored_eds = !o.no_stored_eds;
  options.bitrate_bps = bitrate;
  options.bus_load_limit = o.bus_load;
  return options;
}

// On sim: the devices of the URL's device= files (and unconfigured=), in simulated time.
void run_on_sim(const ScanCliOptions& o, const SimBusOptions& sim,
                const std::vector<cfg::NodeId>& ids, Collector& collector, ScanResults& results) {
  if (sim.device_files.empty()) {
    fail_command(kTool, tools::kExitUsage,
                 "--bus " + o.bus +
                     ": sim: has no device to scan without a network; name them with "
                     "sim:?device=FILE@NODES");
  }
  std::vector<nmt::SimulatedDevice> built = simulated_devices_or_exit(kTool, cfg::Network{}, sim);
  nmt::SimBus bus(sim.bitrate_bps);
  bus.set_loss_rate(sim.loss, sim.seed);
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  for (auto& device : built) {
    devices.push_back(
        std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(std::move(device)));
    bus.attach(*devices.back());
    devices.back()->apply(
        [](nmt::SimulatedDevice& d, nmt::TimePoint now, auto& out) { d.start(now, out); });
  }
  // The devices' boot-ups first, as on a machine that is running.
  bus.run_for(std::chrono::milliseconds(10));
  const nmt::TimePoint began = bus.now();
  nmt::SimEngineNode<Scanner> scanner(scan_options(o, sim.bitrate_bps));
  bus.attach(scanner);
  scanner.set_event_handler([&](const Scanner::Event& e, nmt::TimePoint) {
    collector.on_event(e, [&](cfg::NodeId node, std::vector<cfg::ObjectAddress> entries) {
      scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) {
        (void)s.read(node, std::move(entries), now, out);
      });
    });
  });
  std::unique_ptr<nmt::SimEngineNode<nmt::LssProcedure>> lss;
  if (!o.no_lss) {
    lss = std::make_unique<nmt::SimEngineNode<nmt::LssProcedure>>(nmt::LssMasterOptions{});
    bus.attach(*lss);
    lss->set_event_handler(
        [&](const nmt::LssProcedureEvent& e, nmt::TimePoint) { collector.on_lss(e); });
    lss->apply([](nmt::LssProcedure& p, nmt::TimePoint now, auto& out) {
      (void)p.find_unconfigured(now, out);
    });
  }
  scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) { s.start(ids, now, out); });
  bus.run_until([&] { return scanner.engine().finished() && (o.no_lss || collector.lss_done()); },
                bus.now() + std::chrono::hours(24));
  results.elapsed = bus.now() - began;
}

// On a real bus (socketcan:, udp://) in real time.
void run_on_bus(const ScanCliOptions& o, const std::vector<cfg::NodeId>& ids, Collector& collector,
                ScanResults& results) {
  auto opened = nmt::open_bus(o.bus);
  if (!opened) fail_command(kTool, tools::kExitIo, opened.error().message);
  std::unique_ptr<nmt::Bus> bus = std::move(opened).value();
  nmt::BusEventLoop loop(*bus);
  Scanner scanner(scan_options(o, o.bitrate));
  nmt::EngineRef<Scanner> ref(scanner);
  nmt::LssProcedure procedure{nmt::LssMasterOptions{}};
  nmt::EngineRef<nmt::LssProcedure> lss(procedure);
  auto done = [&] { return scanner.finished() && (o.no_lss || collector.lss_done()); };
  ref.set_event_handler([&](const Scanner::Event& e, nmt::TimePoint) {
    collector.on_event(e, [&](cfg::NodeId node, std::vector<cfg::ObjectAddress> entries) {
      ref.apply([&](Scanner& s, nmt::TimePoint now, auto& out) {
        (void)s.read(node, std::move(entries), now, out);
      });
    });
    if (done()) loop.request_stop();
  });
  lss.set_event_handler([&](const nmt::LssProcedureEvent& e, nmt::TimePoint) {
    collector.on_lss(e);
    if (done()) loop.request_stop();
  });
  loop.add(ref);
  if (!o.no_lss) loop.add(lss);
  const nmt::TimePoint began = loop.now();
  if (!o.no_lss) {
    lss.apply([](nmt::LssProcedure& p, nmt::TimePoint now, auto& out) {
      (void)p.find_unconfigured(now, out);
    });
  }
  ref.apply([&](Scanner& s, nmt::TimePoint now, auto& out) { s.start(ids, now, out); });
  // Every upload and LSS step ends (answer, abort or timeout): the loop stops by itself; the
  // bound only guards against a clock that does not advance.
  cfg::Status status = done() ? cfg::Status{} : loop.run_for(std::chrono::hours(24));
  loop.clear_stop();
  if (status) status = loop.run_until_sent(std::chrono::seconds(1));
  if (!status) fail_command(kTool, tools::kExitIo, status.error().message);
  results.elapsed = loop.now() - began;
}

std::string json_identity(const cfg::DeviceIdentity& id) {
  auto number = [](const std::optional<std::uint32_t>& v) {
    return v ? std::to_string(*v) : std::string("null");
  };
  return "{\"device_type\": " + number(id.device_type) +
         ", \"vendor_id\": " + number(id.vendor_id) +
         ", \"product_code\": " + number(id.product_code) +
         ", \"revision\": " + number(id.revision_number) +
         ", \"serial_number\": " + number(id.serial_number) + "}";
}

std::string json_report(const ScanResults& r, const std::string& output_dir) {
  char seconds[32];
  std::snprintf(seconds, sizeof seconds, "%.6f", static_cast<double>(r.elapsed.count()) / 1e6);
  std::string out = "{\"output\": " + tools::json_string(output_dir) +
                    ", \"elapsed_s\": " + seconds + ", \"asked\": " + std::to_string(r.asked) +
                    ", \"absent\": " + std::to_string(r.absent_ids.size()) + ", \"nodes\": [";
  bool first = true;
  for (const auto& [id, n] : r.nodes) {
    std::snprintf(seconds, sizeof seconds, "%.6f", static_cast<double>(n.took.count()) / 1e6);
    out += std::string(first ? "" : ", ") + "{\"node_id\": " + std::to_string(id) +
           ", \"identity\": " + json_identity(n.found.identity) +
           ", \"eds\": " + (n.eds ? tools::json_string(n.eds_source) : std::string("null")) +
           ", \"revision_exact\": " + (n.eds && n.revision_exact ? "true" : "false") +
           ", \"note\": " + tools::json_string(n.note) +
           ", \"dcf\": " + tools::json_string(cfg::scan_dcf_file_name(n.found.node)) +
           ", \"entries_read\": " + std::to_string(n.read) +
           ", \"entries_skipped\": " + std::to_string(n.skipped + n.found.skipped) +
           ", \"seconds\": " + seconds + "}";
    first = false;
  }
  out += "], \"unconfigured\": [";
  for (std::size_t i = 0; i < r.unconfigured.size(); ++i) {
    const auto& a = r.unconfigured[i];
    out += std::string(i ? ", " : "") + "{\"vendor_id\": " + std::to_string(a.vendor_id) +
           ", \"product_code\": " + std::to_string(a.product_code) +
           ", \"revision\": " + std::to_string(a.revision) +
           ", \"serial\": " + std::to_string(a.serial) + "}";
  }
  out += "], \"lss_problem\": " +
         (r.lss_problem.empty() ? std::string("null") : tools::json_string(r.lss_problem));
  return out + "}\n";
}

void print_table(const ScanResults& r) {
  std::printf("%-5s %-10s %-10s %-10s %-10s %-8s %-8s %s\n", "node", "type", "vendor", "product",
              "revision", "read", "skipped", "EDS");
  for (const auto& [id, n] : r.nodes) {
    const auto& i = n.found.identity;
    std::printf("%-5d %-10s %-10s %-10s %-10s %-8zu %-8zu %s\n", int{id},
                optional_hex(i.device_type).c_str(), optional_hex(i.vendor_id).c_str(),
                optional_hex(i.product_code).c_str(), optional_hex(i.revision_number).c_str(),
                n.read, n.skipped + n.found.skipped, n.eds ? n.eds_source.c_str() : "(none)");
  }
  std::fflush(stdout);
}

// The project files, all made before any is written: OUT/nodeN.dcf and OUT/nodelist.cpj (last,
// so that a project file never names a DCF that is not there yet).
std::vector<std::pair<std::string, std::string>> project_files(const ScanResults& r,
                                                               const std::string& net_name,
                                                               cfg::Diagnostics& diagnostics) {
  std::vector<std::pair<std::string, std::string>> files;
  std::vector<cfg::ScanProjectNode> listed;
  for (const auto& [id, n] : r.nodes) {
    const std::string name = cfg::scan_dcf_file_name(n.found.node);
    const cfg::DeviceDescription dcf =
        n.eds ? cfg::as_found_dcf(*n.eds, n.found.node, n.values, diagnostics)
              : cfg::identity_only_dcf(n.found.node, n.found.identity);
    files.emplace_back(name, cfg::write_device_description(dcf, {}));
    listed.push_back({.node = n.found.node, .dcf_file = name, .name = {}});
  }
  files.emplace_back("nodelist.cpj", cfg::scan_project(net_name, std::move(listed)));
  return files;
}

void write_files_or_exit(const std::string& dir,
                         const std::vector<std::pair<std::string, std::string>>& files) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec)
    fail_command(kTool, tools::kExitIo, dir + ": cannot create the directory: " + ec.message());
  for (const auto& [name, text] : files) {
    // Each file replaced whole (rename over the old one), never half-written.
    const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(text.data()),
                                              text.size());
    if (auto written = cfg::write_file_atomically(dir, name, bytes); !written) {
      fail_command(kTool, tools::kExitIo, written.error().message);
    }
  }
}

void run_scan(const ScanCliOptions& o) {
  const std::optional<SimBusOptions> sim = parse_bus_url(kTool, o.bus);
  std::vector<cfg::NodeId> ids;
  if (o.nodes.empty()) {
    for (unsigned n = 1; n <= 127; ++n)
      ids.push_back(*cfg::NodeId::from(static_cast<std::uint8_t>(n)));
  } else {
    auto listed = nmt::parse_node_list(o.nodes);
    if (!listed) fail_command(kTool, tools::kExitUsage, "--node " + listed.error().message);
    for (const std::uint8_t n : *listed) ids.push_back(*cfg::NodeId::from(n));
  }
  {
    std::error_code ec;
    const auto status = std::filesystem::status(o.output_dir, ec);
    if (std::filesystem::exists(status) && !std::filesystem::is_directory(status)) {
      fail_command(kTool, tools::kExitUsage, "-o " + o.output_dir + ": exists and is no directory");
    }
  }
  tools::ReportFile json = open_report_or_exit(o.json);

  // The vendor library: files that do not parse are named with their diagnostics and skipped.
  cfg::Diagnostics library_diagnostics;
  cfg::EdsLibrary library;
  if (!o.eds_dir.empty()) {
    if (!std::filesystem::is_directory(o.eds_dir)) {
      fail_command(kTool, tools::kExitIo, o.eds_dir + ": --eds-dir: not a directory");
    }
    library = cfg::EdsLibrary::load(o.eds_dir, library_diagnostics);
  }
  tools::print_diagnostics(library_diagnostics);
  if (library_diagnostics.has_errors()) exit_with(tools::kExitIo);

  ScanResults results;
  results.asked = ids.size();
  cfg::Diagnostics scan_diagnostics;
  Collector collector(results, library, scan_diagnostics);
  collector.set_progress(progress_wanted());
  if (sim) {
    run_on_sim(o, *sim, ids, collector, results);
  } else {
    run_on_bus(o, ids, collector, results);
  }

  cfg::Diagnostics write_diagnostics;
  const auto files = project_files(results, o.net_name, write_diagnostics);
  tools::print_diagnostics(scan_diagnostics);
  tools::print_diagnostics(write_diagnostics);
  if (!results.nodes.empty()) write_files_or_exit(o.output_dir, files);

  print_table(results);
  bool complete = !results.nodes.empty();
  for (const auto& [id, n] : results.nodes) {
    if (!n.eds) {
      complete = false;
      std::cerr << "cfgmgr scan: node " << int{id} << ": " << n.note
                << " (in the project by its identity only: push leaves it as it is)\n";
    } else if (!n.revision_exact) {
      std::cerr << "cfgmgr scan: node " << int{id} << ": " << n.note << '\n';
    }
  }
  for (const auto& a : results.unconfigured) {
    std::cerr << "cfgmgr scan: a device without node-ID, LSS address " << nmt::address_digits(a)
              << ": not in the project (give it a node-ID with cfgmgr lss set-id "
              << nmt::address_digits(a) << " NODE-ID, then scan again)\n";
  }
  if (!results.lss_problem.empty()) {
    std::cerr << "cfgmgr scan: warning: the LSS scan for devices without node-ID: "
              << results.lss_problem << '\n';
  }
  std::cerr << "cfgmgr scan: " << tools::plural(results.nodes.size(), "device") << " of "
            << results.asked << " node-IDs asked, "
            << seconds_text(nmt::TimePoint{}, nmt::TimePoint{} + results.elapsed) << " s"
            << (results.nodes.empty() ? "; nothing written"
                                      : "; project in " + o.output_dir + "/nodelist.cpj")
            << '\n';
  if (json.stream() != nullptr) finish_report_or_exit(json, json_report(results, o.output_dir));
  if (!complete) exit_with(kExitIncomplete);
}

}  // namespace

void add_scan_command(CLI::App& app) {
  auto o = std::make_shared<ScanCliOptions>();
  auto* cmd = app.add_subcommand(
      "scan",
      "Read a live network into a project: every device's identity (1000h, 1018h), matched "
      "against EDS files, and the values of its read-write entries as OUT/nodeN.dcf with "
      "OUT/nodelist.cpj, which cfgmgr push commissions onto replacement devices; only reads "
      "(SDO uploads, LSS Fastscan), no write, no NMT command");
  cmd->add_option("--bus", o->bus,
                  "Bus URL: socketcan:IFNAME, udp://GROUP:PORT, or sim:?device=FILE@NODES "
                  "(simulated devices built from EDS/DCF files, in simulated time)")
      ->required()
      ->type_name("URL");
  cmd->add_option("--eds-dir", o->eds_dir,
                  "A directory of EDS files (a vendor library, searched recursively for *.eds; "
                  "files that do not read are skipped with their diagnostics). A device that "
                  "stores its EDS in 1021h gets that one")
      ->type_name("DIR");
  cmd->add_option("-o,--output", o->output_dir,
                  "The project's directory: nodelist.cpj and nodeN.dcf are written there, each "
                  "file replaced whole (created when missing)")
      ->required()
      ->type_name("OUT");
  cmd->add_option("--node", o->nodes,
                  "Scan only these node-IDs, e.g. 3 or 3,5-7 (a backup before a firmware update)")
      ->type_name("NODES");
  cmd->add_option("--json", o->json,
                  "Also write the result as JSON: output, elapsed_s, asked, absent, nodes "
                  "[{node_id, identity {device_type, vendor_id, product_code, revision, "
                  "serial_number}, eds, revision_exact, note, dcf, entries_read, "
                  "entries_skipped, seconds}], unconfigured [{vendor_id, product_code, "
                  "revision, serial}], lss_problem")
      ->type_name("FILE");
  cmd->add_option("--sdo-timeout", o->sdo_timeout_s,
                  "Timeout of each SDO response, in seconds: what the absent node-IDs cost, "
                  "once for all of them")
      ->capture_default_str()
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--retries", o->retries,
                  "How often an upload that timed out is repeated, to a device that answered "
                  "before (or whose heartbeat was seen)")
      ->capture_default_str()
      ->type_name("N");
  cmd->add_option("--probe-retries", o->probe_retries,
                  "How often the probe (1000h) of a node-ID without heartbeat is repeated "
                  "after a timeout: each costs one more timeout in all, and on a lossy bus finds "
                  "a device without heartbeat whose probe or answer was lost")
      ->capture_default_str()
      ->type_name("N");
  cmd->add_option("--bitrate", o->bitrate,
                  "The bus bit rate (bit/s) on a real bus: the requests are paced to --bus-load "
                  "of it (sim: knows its own)")
      ->type_name("BPS");
  cmd->add_option("--bus-load", o->bus_load,
                  "The share of the bus the scan's requests, their answers and the other "
                  "frames may take, with a known bit rate")
      ->capture_default_str()
      ->check(CLI::Range(0.05, 1.0))
      ->type_name("SHARE");
  cmd->add_flag("--no-lss", o->no_lss, "Do not look for devices without node-ID (LSS Fastscan)");
  cmd->add_flag("--no-stored-eds", o->no_stored_eds,
                "Do not read the EDS a device stores (1021h/1022h); use the library only");
  cmd->add_option("--net-name", o->net_name, "NetName of the project's [Topology]")
      ->capture_default_str()
      ->type_name("NAME");
  cmd->footer(std::string(
      "Every node-ID (or those of --node) is asked for 1000h at once: the absent ones cost one "
      "SDO timeout in all. A device that answers is asked for 1018h sub 1-4 and, where it has "
      "them, 1022h/1021h (its own EDS); its identity is matched against the EDS files "
      "(vendor-ID and product code equal; the revision exact, else the nearest, which is "
      "said), and every entry the EDS lets one read and write is read (not 1010h/1011h, not "
      "DOMAINs). nodeN.dcf is the EDS as a DCF for node N with ParameterValue= what the device "
      "holds, except COB-IDs that follow from the node-ID and equal their default. An entry "
      "the device refuses is skipped and counted. A device without a matching EDS is in the "
      "project with its identity only: push checks it and writes nothing. The serial number "
      "is in --json only: a replacement has another.\n\n"
      "Examples:\n"
      "  cfgmgr scan --bus socketcan:can0 --eds-dir /opt/eds -o backup --json backup/scan.json\n"
      "  cfgmgr push backup/nodelist.cpj --bus socketcan:can0   # onto the replacement\n"
      "  cfgmgr scan --bus socketcan:can0 --eds-dir /opt/eds --node 3 -o before-update\n"
      "  cfgmgr verify backup/nodelist.cpj --bus socketcan:can0  # later: what changed\n"
      "  cfgmgr scan --bus 'sim:?device=samples/network/io_module_node2.dcf@2' -o out\n\n"
      "Exit codes:\n"
      "  0  every device found has its EDS and DCF in the project\n"
      "  2  usage error (bad command line, a --bus URL that does not parse, -o naming a file)\n"
      "  3  I/O error: the bus cannot be opened or fails, a file cannot be written\n"
      "  4  a device has no matching EDS (it is in the project by its identity only), or no "
      "device answered (nothing written)\n"));
  cmd->callback([o] { run_scan(*o); });
}

}  // namespace cfgmgr
