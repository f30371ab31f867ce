// The arguments of the cfgmgr commands that run a network (master, push, verify; build and sdo
// use some): the options they add, how their values are checked, and the report files. Each
// ends the command (command_failure.hpp) on a value it cannot take.
#pragma once

#include <CLI/CLI.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "cfg/network.hpp"
#include "network_source.hpp"
#include "nmt/master/master_options.hpp"
#include "nmt/master/nmt_master.hpp"

namespace cfgmgr {

/// Exit code when NMT start-up did not end in operation (a mandatory node failed).
inline constexpr int kExitMandatoryFailed = 4;

/// --program NODE=FILE and --program-version NODE=VERSION as given (each repeatable): they
/// override the description's NodeXProgramFile=/NodeXProgramVersion= (cfg::set_node_program).
struct ProgramOverrides {
  std::vector<std::string> files;
  std::vector<std::string> versions;
};

/// The arguments every command that runs a network takes.
struct NetworkRunArgs {
  std::string network;  ///< the description (project file or master DCF)
  std::string bus;      ///< --bus URL
  std::string node_id;  ///< --node-id as given; empty: the default
  unsigned net = 1;     ///< --net
  bool verbose = false;
  ProgramOverrides programs;
  std::vector<std::string> dcf_path;  ///< --dcf-path DIR, repeatable (cfg::NetworkOptions)
  std::vector<std::string> defines;   ///< --define NAME=VALUE
};

/// Adds --dcf-path DIR (repeatable) to `cmd`: where the files a master DCF names are looked for
/// when they do not exist as written (cfg::NetworkOptions::dcf_path).
void add_dcf_path_option(CLI::App& cmd, std::vector<std::string>& dirs);
/// The end of the error for a file a master DCF names that is nowhere: how to pass --dcf-path.
inline constexpr std::string_view kDcfPathHint = " with --dcf-path DIR";

/// Adds --define NAME=VALUE (repeatable) to `cmd`: the value of a bus.yml's `@NAME@`
/// placeholder (cfg/bus_yml.hpp), as CMake's configure_file would fill it.
void add_define_option(CLI::App& cmd, std::vector<std::string>& defines);

/// Adds NETWORK, --bus, --node-id, --net and -v to `cmd`. Returns --bus (a command may make it
/// required).
CLI::Option* add_network_run_options(CLI::App& cmd, NetworkRunArgs& args);

/// `--lss` of push and master: Execute LSS before NMT start-up's reset of all nodes (CiA 305
/// Fastscan; nmt_master.hpp), and for master `--lss-period MS`, the look for replaced devices.
struct LssRunArgs {
  bool lss = false;
  std::optional<unsigned> period_ms;  ///< --lss-period
  unsigned scan_step_ms = 10;         ///< --lss-scan-step
};
/// Adds --lss to `cmd`, and --lss-period when `with_period`.
void add_lss_options(CLI::App& cmd, LssRunArgs& args, bool with_period);
/// MasterOptions::lss from the arguments, with the network's LSS addresses (lss_addresses; its
/// notes on stderr). Ends the command with exit 2 for --lss-period without --lss.
void apply_lss_options(std::string_view tool, const LssRunArgs& args, const cfg::Network& network,
                       nmt::MasterOptions& options);
/// A bound on the simulated time Execute LSS takes for `options` (Fastscan: 133 steps per
/// device and a few more, each the scan step), to add to a run's bound.
double lss_bound_s(const nmt::MasterOptions& options);

/// The --json / --json-events file opened before any bus work ("" gives none); prints
/// "PATH: error: cannot open for writing: ..." and ends the command with exit 3 when it cannot.
tools::ReportFile open_report_or_exit(const std::string& path);
/// Writes `text` to the report file and flushes it; a write error ends the command with exit 3.
void finish_report_or_exit(tools::ReportFile& report, std::string_view text = {});

/// --report FILE.html and --report-bitrate of push and master (html_report.hpp).
struct HtmlReportArgs {
  std::string path;                          ///< empty: no report
  std::optional<std::uint32_t> bitrate_bps;  ///< --report-bitrate
};
/// Adds --report and --report-bitrate to `cmd`; `when` says when the file is written.
void add_html_report_options(CLI::App& cmd, HtmlReportArgs& args, std::string_view when);
/// The bit rate the report's bus load is taken at: --report-bitrate, else sim:'s, else 125
/// kbit/s, which `assumed` then says (the page says so).
struct ReportBitrate {
  std::uint32_t bps = 125'000;
  bool assumed = true;
};
ReportBitrate report_bitrate(const HtmlReportArgs& args, const std::optional<SimBusOptions>& sim);
/// The --report file opened before any bus work (a temporary beside it, renamed over it when
/// written: a reader never sees half a page); nullopt without --report. Prints "PATH: error:
/// cannot create: ..." and ends the command with exit 3 when it cannot.
std::optional<tools::OutputFile> open_html_report_or_exit(const HtmlReportArgs& args);
/// Writes `html` to the report and puts it in place; a write error ends the command with exit 3.
void write_html_report_or_exit(tools::OutputFile& file, std::string_view html);

/// Seconds from `start` to `at` with millisecond digits ("0.512").
std::string seconds_text(nmt::TimePoint start, nmt::TimePoint at);
nmt::Duration seconds_to_duration(double s);
/// --sdo-timeout in seconds as an SDO response timeout (whole us, positive: a 0 us timeout can
/// never be met, SdoClient::check_start and MasterOptions::validate refuse it). A value that
/// CLI::PositiveNumber lets through but that rounds to 0 us, or one beyond the clock's range,
/// ends the command with exit 2 before any bus work.
nmt::Duration sdo_timeout_or_exit(std::string_view tool, double seconds);

/// The --bus URL checked: the `sim:` options, or nullopt for a real bus whose URL parses.
/// Ends the command with exit 2 (usage) when it does not.
std::optional<SimBusOptions> parse_bus_url(std::string_view tool, const std::string& url);

/// One hex number of at most `digits` digits as a command line writes it: "1018", "0x1018" or
/// "1018h"; nullopt for anything else.
std::optional<std::uint64_t> parse_hex_argument(std::string_view text, std::size_t digits);

/// The node-IDs of an --only list ("3,5-7" -> {3, 5, 6, 7}); prints "cfgmgr TOOL: --only ..."
/// and ends the command with exit 2 on anything else.
std::set<std::uint8_t> parse_only(std::string_view tool, const std::string& text);

}  // namespace cfgmgr
