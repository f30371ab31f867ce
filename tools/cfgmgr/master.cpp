// cfgmgr master NETWORK --bus URL: the CiA 302-2 NMT master (nmt::NmtMaster) as a program. It
// loads the network description (cfg/network.hpp), builds the master from the master's DCF or
// the derived one, gives it the nodes' configurations (NetworkSource), which it also serves as
// the configuration manager (1F20h-1F27h, in memory or --store DIR), and runs it until
// SIGINT/SIGTERM or --run-for: on a real bus through BusEventLoop, on `sim:` on the simulated
// bus with a simulated device per node. All protocol behaviour is the engine's; this file parses
// arguments, wires the pieces and prints the events.
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "../common/tool_support.hpp"
#include "cfg/config_manager.hpp"
#include "commands.hpp"
#include "master_run.hpp"
#include "report_recorder.hpp"

namespace cfgmgr {
namespace {

/// How long `sim:` without --run-for may take, in simulated seconds, for NMT start-up to end.
constexpr double kSimDefaultBoundS = 60.0;

struct MasterCliOptions : NetworkRunArgs {
  std::optional<double> run_for_s;
  std::string json_events;
  std::string store;
  bool sdo_manager = false;
  LssRunArgs lss;
  HtmlReportArgs report;
};

/// --store DIR: the configuration manager the master serves (1F20h-1F27h) and configures from
/// first, kept on disk (without it build_master gives one in memory). A damaged entry is
/// printed and left unused (cfg/config_manager.hpp).
std::shared_ptr<cfg::ConfigManager> open_store_or_exit(const std::string& directory) {
  auto opened = cfg::ConfigManager::open(directory);
  if (!opened) fail_command("master", tools::kExitIo, opened.error().message);
  tools::print_diagnostics(opened.value().problems());
  return std::make_shared<cfg::ConfigManager>(std::move(opened).value());
}

void run_master(const MasterCliOptions& options) {
  // Arguments first, files next, the bus last: a typo should not touch the bus.
  const std::optional<SimBusOptions> sim = parse_bus_url("master", options.bus);
  if (options.net == 0)
    fail_command("master", tools::kExitUsage, "--net: networks are numbered from 1");
  const auto network = load_network_or_exit(options.network, options.net, options.programs,
                                            options.dcf_path, options.defines);
  nmt::MasterOptions master_options;
  if (!options.store.empty()) master_options.manager = open_store_or_exit(options.store);
  master_options.sdo_manager.enabled = options.sdo_manager;
  apply_lss_options("master", options.lss, *network, master_options);
  const nmt::MasterConfig config =
      master_config_or_exit("master", options.network, network, options.node_id, master_options);
  nmt::NmtMaster master = build_master_or_exit(config, options.network, *network);

  tools::ReportFile json = open_report_or_exit(options.json_events);
  std::optional<tools::OutputFile> html = open_html_report_or_exit(options.report);
  EventReporter reporter(options.verbose, json.stream());
  reporter.track_programs(network);
  // --report: a lane per slave the master boots, the bus load from every frame.
  std::optional<ReportRecorder> recorder;
  RunTraces traces;
  if (html) {
    std::vector<ReportRecorder::Node> lanes;
    for (const nmt::SlaveConfig& slave : config.slaves) {
      if (!slave.slave) continue;
      const cfg::NetworkNode* node = network->find(slave.node);
      lanes.push_back({slave.node.value(), node != nullptr ? node->name : "", slave.mandatory});
    }
    const ReportBitrate bitrate = report_bitrate(options.report, sim);
    recorder.emplace(std::move(lanes), bitrate.bps, bitrate.assumed);
    traces.frames = recorder->frame_sink();
    reporter.set_observer([&recorder](const nmt::MasterEvent& e) { recorder->observe(e); });
  }
  RunLimits limits;
  limits.tool = "master";
  limits.run_for_s = options.run_for_s;
  RunOutcome outcome;
  if (sim) {
    // Without --run-for, sim: ends once NMT start-up has (master_run.hpp).
    limits.until_startup_ends = true;
    limits.bound_s = kSimDefaultBoundS + lss_bound_s(master_options);
    limits.bound_hint = " of simulated time (give --run-for to run longer)";
    outcome = run_master_on_sim(std::move(master), *network, *sim, limits, reporter, traces);
  } else {
    outcome = run_master_on_bus(std::move(master), options.bus, limits, reporter, traces);
  }
  finish_report_or_exit(json);
  const bool failed = outcome.timed_out || reporter.halted();
  if (html) {
    report::ReportData header;
    header.tool = "master";
    header.network = options.network;
    header.bus = options.bus;
    header.ok = !failed;
    header.outcome = outcome.timed_out ? "NMT start-up did not end within the run's bound (exit 4)"
                     : reporter.halted()
                         ? "NMT start-up halted: a mandatory slave failed (CiA 302-2 §3.1 f), "
                           "no slave was started (exit 4)"
                     : reporter.complete() ? "NMT start-up complete"
                                           : "NMT start-up had not ended when the run did";
    write_html_report_or_exit(
        *html, report::html_report(recorder->finish(
                   reporter.start(), reporter.start() + outcome.elapsed, std::move(header))));
  }
  if (failed) exit_with(kExitMandatoryFailed);
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
  add_network_run_options(*cmd, *options)->required();
  cmd->add_option("--run-for", options->run_for_s,
                  "Stop after this many seconds (simulated seconds on sim:). Without it sim: "
                  "stops when NMT start-up has ended (at most 60 simulated seconds) and a real "
                  "bus runs until Ctrl-C/SIGTERM")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--json-events", options->json_events,
                  "Also write every event as one JSON object a line: time_s, event "
                  "(slave_booted, boot_error, heartbeat_lost, boot_up, startup_complete, "
                  "active_master, standby, ...; of the bus itself: bus_off, restarted, "
                  "send_failed, ... with node_id 0 and the frame), node_id, text, and per event "
                  "error/"
                  "description/final, configured/no_configuration/entries/bytes, assigned, step, "
                  "state, command, "
                  "priority, connection_error, lss_address (lss_assigned, lss_unmatched, "
                  "lss_failed) and connection (row, client_node_id, client_index, "
                  "server_node_id, server_index, request_cob_id, response_cob_id); try (the "
                  "boot's try), failure (boot_error: reason, step, object, actual/expected_by/"
                  "expected, abort/abort_text, entry/entries, consumer_time_ms, boot_time_ms), "
                  "halted_by (startup_halted), nmt_startup (not_master), reason (flying master "
                  "and SDO manager kinds), outcome/error_code (lss_*), found/assigned "
                  "(lss_scan_ended), emergency (emergency, emergency_flood: error_code, "
                  "error_code_hex, error_register, manufacturer (10 hex digits), code_text, "
                  "register_text, ends_error, device_type, suppressed) and boot_emergency "
                  "(boot_error, slave_booted: the EMCY the node sent during its boot)")
      ->type_name("FILE");
  cmd->add_option("--store", options->store,
                  "Keep what tools write to 1F20h-1F27h in this store directory (created when "
                  "missing; see cfgmgr store), so that it outlives the process: a node's stored "
                  "configuration and 1F26h/1F27h take the place of the network's, and a node "
                  "with nothing stored keeps the network's")
      ->type_name("DIR");
  cmd->add_flag("--sdo-manager", options->sdo_manager,
                "Be the SDO manager too (DSP 302 section 7; also on when the master DCF has "
                "1F00h): register SDO requesting devices after their Dynamic SDO Request (6E0h), "
                "set up the SDO connections they ask for with 1F00h from the COB-IDs of 1F02h "
                "(680h-6DFh when the DCF has none) and release them (1F01h, or when the "
                "requester's heartbeat or guarding stops)");
  add_lss_options(*cmd, options->lss, /*with_period=*/true);
  add_html_report_options(*cmd, options->report, "when the master stops");
  cmd->footer(std::string(
      "Devices out of the box (no node-ID, CiA 305): with --lss the master first finds every "
      "device without node-ID (Fastscan) and gives each the node-ID of the node whose DCF has "
      "its LSS address (1018h sub 1-3, [DeviceComissioning] LSS_SerialNumber else 1018h sub 4), "
      "stored in the device, then boots the network; with --lss-period MS it also looks for "
      "such devices while it runs (a replaced drive), and boots and configures each it gave a "
      "node-ID. Events: node N: LSS: ... got node-ID N, stored / LSS: unconfigured device "
      "V:P:R:S matches no slave: left unconfigured / LSS: K unconfigured devices found.\n\n"
      "The master is the network's configuration manager (DSP 302 section 6) and serves "
      "1F20h-1F27h by SDO: 1F22h sub N reads the concise DCF it downloads to node N (the bytes "
      "cfgmgr build writes as nodeN.bin), 1F20h sub N the node's DCF file (0800 0024 when the "
      "network has none), 1F26h/1F27h the date and time it compares with 1020h. A tool may "
      "write a node's DCF (1F20h), concise DCF (1F22h) or 1F26h/1F27h, which then take the "
      "place of the network's, and start a download with 1F25h sub N (80h: all) = 'conf' (see "
      "cfgmgr store). Without --store those writes are held in memory until the master "
      "stops; with --store DIR they are kept in DIR: the write's SDO confirmation leaves once "
      "the entry is on disk (the master itself does no disk I/O; its loop writes the entry "
      "after the call), and a write the disk refused is aborted with 0800 0020.\n\n"
      "Without a master DCF, every present node is a mandatory slave that is booted and "
      "started; the expected identity comes from its DCF and 1F26h/1F27h from its "
      "configuration (rules in cfg/network.hpp). With 1F80h bit 2 set, cfgmgr master is the "
      "application that lets the master enter operational, at once.\n\n"
      "Events, one a line on stderr, seconds since the start first: node N: booted, "
      "configured (E entries, B bytes) / booted (configuration up to date) / booted, no "
      "configuration for node N (1F22h sub N empty) / reconfigured / "
      "boot error X: <CiA 302-2 Table 1 text> / heartbeat lost / node guarding lost / boot-up "
      "seen; NMT start-up complete / halted. With 1F80h bit 5 in the master DCF the master takes "
      "part in the NMT flying master negotiation (CiA 302-2 section 3.7; 1F90h sets its "
      "priority and timing) and says who is active and why: active NMT master / node N is the "
      "active NMT master / force / multiple masters / heartbeat of the active master lost. With "
      "--sdo-manager: SRD registered / refused, SDO connection established / refused / "
      "released, SRD lost, 1F11h slave failed.\n\n"
      "Examples:\n"
      "  cfgmgr master samples/network/nodelist.cpj --bus sim:\n"
      "  cfgmgr master samples/network/nodelist.cpj --bus sim:?loss=0.01 --run-for 5\n"
      "  cfgmgr master nodelist.cpj --bus socketcan:can0 --json-events events.jsonl\n"
      "  cfgmgr master master.dcf --bus udp://239.74.163.2:43113 --node-id 1\n"
      "  cfgmgr master nodelist.cpj --bus socketcan:can0 --store /var/lib/canopen/store\n"
      "  cfgmgr sdo read --bus socketcan:can0 0x7F 1F22:3 --type domain -o node3.bin\n"
      "  cfgmgr master nodelist.cpj --bus socketcan:can0 --sdo-manager\n"
      "  cfgmgr master nodelist.cpj --bus socketcan:can0 --lss --lss-period 1000\n"
      "  cfgmgr master samples/network/nodelist.cpj --bus sim: --report boot.html\n\n"
      "Exit codes:\n"
      "  0  stopped by Ctrl-C/SIGTERM or --run-for, or (sim: without --run-for) NMT start-up "
      "complete\n"
      "  1  the network description has errors (printed as FILE:LINE: error: ...), or the "
      "master cannot be built from it\n"
      "  2  usage error (bad command line, a --bus URL that does not parse, a --node-id "
      "outside 1..127 or of a slave)\n"
      "  3  I/O error: the description cannot be read, the bus cannot be opened or fails, "
      "--json-events, --report or the --store directory cannot be written\n"
      "  4  NMT start-up halted: a mandatory slave failed its boot (CiA 302-2 section 3.1 f; the "
      "others still boot to their own end, then start-up halts: no slave started, the master "
      "stays pre-operational); on sim: without --run-for also when start-up did not end "
      "within 60 s\n"));
  cmd->callback([options] { run_master(*options); });
}

}  // namespace cfgmgr
