// The arguments of the commands that run a network (run_args.hpp).
#include "run_args.hpp"

#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/integer_literal.hpp"
#include "nmt/io/bus.hpp"

namespace cfgmgr {

CLI::Option* add_network_run_options(CLI::App& cmd, NetworkRunArgs& args) {
  cmd.add_option("network", args.network,
                 "CiA 306-3 project file (nodelist.cpj; DCF paths relative to it) or a "
                 "master DCF (CANopenManager=1) whose 1F20h/1F22h name node files with "
                 "DownloadFile= or UploadFile= (lely dcfgen's master.dcf)")
      ->required()
      ->type_name("NETWORK");
  add_dcf_path_option(cmd, args.dcf_path);
  auto* bus =
      cmd.add_option("--bus", args.bus,
                     "Bus URL: socketcan:IFNAME, udp://GROUP:PORT (python-can "
                     "udp_multicast compatible), or sim: for the simulated bus with a "
                     "simulated device per node built from the network's DCFs, in "
                     "simulated time (sim:?bitrate=500000&latency_ms=1&loss=0.01&seed=N&state=DIR, "
                     "and &unconfigured=3,5-7; state=DIR keeps what each device saved with 1010h "
                     "between runs; the devices of the unconfigured= nodes power on without "
                     "node-ID and wait for LSS, CiA 305; &device=FILE@2-7, repeatable: the "
                     "devices at those node-IDs are built from the EDS/DCF FILE, also where the "
                     "network has only a concise DCF, as dcfgen's master.dcf gives; "
                     "&emcy=NODE@MS:CODE[:REGISTER], repeatable: the device at NODE raises the "
                     "emergency with error code CODE (hex, e.g. 8130) and error register bits "
                     "REGISTER (hex) MS ms of simulated time after the start, CiA 301 §7.2.7)")
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
  add_define_option(cmd, args.defines);
  return bus;
}

void add_dcf_path_option(CLI::App& cmd, std::vector<std::string>& dirs) {
  cmd.add_option("--dcf-path", dirs,
                 "Where the files a master DCF names in 1F20h/1F22h/1F58h are, when they are not "
                 "where it says (lely's dcfgen writes the absolute paths of the machine that ran "
                 "it, its dcf_path): each file is looked for by its name in DIR, then beside the "
                 "master DCF (a warning); repeatable")
      ->type_name("DIR");
}

void add_define_option(CLI::App& cmd, std::vector<std::string>& defines) {
  cmd.add_option("--define", defines,
                 "A bus.yml's @NAME@ placeholder (ros2_canopen's CMake fills them with "
                 "configure_file, e.g. @BUS_CONFIG_PATH@) is VALUE; repeatable")
      ->allow_extra_args(false)
      ->type_name("NAME=VALUE");
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
                 "With --lss: how long each Fastscan request (and identify non-configured "
                 "remote slave) waits for answers, in ms (above the devices' answer time; "
                 "raise it for devices behind a slow link)")
      ->capture_default_str()
      ->type_name("MS")
      ->check(CLI::Range(1U, 10000U));
  if (!with_period) return;
  cmd.add_option("--lss-period", args.period_ms,
                 "With --lss: after start-up, look for devices without node-ID (a replaced "
                 "device) every MS milliseconds, and give them their node-ID; the master then "
                 "boots and configures them. Each look is one LSS frame (4Ch, about 0.25 ms of "
                 "bus time at 500 kbit/s: 0.025 % of the bus at 1000 ms) and one scan step of "
                 "waiting for answers; only when a device answers, the missing nodes' devices are "
                 "selected by their LSS addresses (8 requests and 4 answers each) and the rest "
                 "found by Fastscan (about 135 requests and as many answers per device, one "
                 "scan step each; a device that matches no node costs that at every look). "
                 "Default: no looks")
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
  for (const auto& note : notes) std::cerr << command_prefix(tool) << "note: " << note << '\n';
}

double lss_bound_s(const nmt::MasterOptions& options) {
  if (!options.lss.enabled) return 0;
  // The worst case, in which every device on the bus (taken as at most one per known address
  // and one more) matches no node: per known address its selection unanswered (one timeout),
  // then its reset and 4 confirmations (5 steps, lss_master.hpp), answered by every
  // unconfigured device up to the serial number (4 N^2 answers); then per device the bit-by-bit
  // Fastscan (1 + 4 x 33 steps), configure and store (two timeouts at most), and the probes past
  // a device left alone; the last, silent Fastscan reset. Its answers: every device not yet
  // found answers about 100 queries of each search (devices of one product share the upper
  // parts of their addresses), about 70 N^2 frames (BENCHMARKS.md, bench_lss_fastscan). Frames
  // of 135 bits at most at the bit rate (125 kbit/s when unknown). When the devices match their
  // nodes, the scan takes a small part of this (BENCHMARKS.md, bench_push --lss).
  const double step_s = std::chrono::duration<double>(options.lss.timing.scan_step).count();
  const double answer_s = std::chrono::duration<double>(options.lss.timing.timeout).count();
  const double devices = static_cast<double>(options.lss.addresses.size()) + 1;
  const double frame_s = 135.0 / (options.pacing.bitrate != 0 ? options.pacing.bitrate : 125'000);
  return devices * (145 * step_s + 3 * answer_s) + devices * devices * 74 * frame_s + 1;
}

tools::ReportFile open_report_or_exit(const std::string& path) {
  auto opened = tools::ReportFile::open(path);
  if (!opened) {
    exit_with(tools::kExitIo, opened.error().message);
  }
  return std::move(*opened);
}

void finish_report_or_exit(tools::ReportFile& report, std::string_view text) {
  if (auto written = report.finish(text); !written) {
    exit_with(tools::kExitIo, written.error().message);
  }
}

void add_html_report_options(CLI::App& cmd, HtmlReportArgs& args, std::string_view when) {
  cmd.add_option("--report", args.path,
                 "Write a page for people to FILE.html, " + std::string(when) +
                     ": one self-contained HTML file (inline SVG and CSS; no script, nothing "
                     "fetched) with a timeline per node over bus time (boot-up, identity, "
                     "program and configuration download with its entries, start; errors, "
                     "retries and EMCYs marked), the bus load with error frames, and the result "
                     "table. Written whole or not at all (a temporary file renamed over FILE)")
      ->type_name("FILE.html");
  cmd.add_option("--report-bitrate", args.bitrate_bps,
                 "The bus's bit rate for the report's bus load; default: sim:'s bitrate=, on a "
                 "real bus 125000 (the page says it was assumed)")
      ->type_name("BPS")
      ->check(CLI::Range(1U, 1'000'000'000U));
}

ReportBitrate report_bitrate(const HtmlReportArgs& args, const std::optional<SimBusOptions>& sim) {
  if (args.bitrate_bps) return {*args.bitrate_bps, false};
  if (sim) return {sim->bitrate_bps, false};
  return {};
}

std::optional<tools::OutputFile> open_html_report_or_exit(const HtmlReportArgs& args) {
  if (args.path.empty()) return std::nullopt;
  auto opened = tools::OutputFile::open(args.path);
  if (!opened) exit_with(tools::kExitIo, opened.error().message);
  return std::move(*opened);
}

void write_html_report_or_exit(tools::OutputFile& file, std::string_view html) {
  if (auto written = file.write(html); !written) exit_with(tools::kExitIo, written.error().message);
  if (auto committed = file.commit(); !committed) {
    exit_with(tools::kExitIo, committed.error().message);
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

}  // namespace cfgmgr
