// What `cfgmgr master` and `cfgmgr push` share: loading a network and building its NMT master,
// printing the master's events, and running the master on the simulated bus (`sim:`) or on a
// real one. Each command adds its own options and, for push, the report at the end.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <iosfwd>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "cfg/network.hpp"
#include "event_reporter.hpp"
#include "network_source.hpp"
#include "nmt/bus_event_loop.hpp"
#include "nmt/master_config.hpp"
#include "nmt/nmt_master.hpp"
#include "program_updates.hpp"

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
};

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

/// The network loaded, `programs` applied and cfg::check_programs run (diagnostics printed;
/// exit 1 on errors, 3 when unreadable, 2 for a malformed --program/--program-version).
std::shared_ptr<const cfg::Network> load_network_or_exit(const std::string& path, unsigned net,
                                                         const ProgramOverrides& programs = {});

/// The master of `network` with node-ID `node_id_text` (empty: the network's, else 7Fh) and
/// `options` (its configurations come from the network). It is the configuration manager
/// (1F20h-1F27h): of options.manager when given (a store directory), else of one in memory,
/// and a node with nothing stored reads the network's configuration. Ends the command with
/// exit 2 for a bad --node-id, 1 when the master cannot be built.
nmt::NmtMaster build_master(std::string_view tool, const std::string& description,
                            const std::shared_ptr<const cfg::Network>& network,
                            const std::string& node_id_text, nmt::MasterOptions options);
/// build_master in two halves, for a command that changes the typed configuration in between
/// (push: --boot-time, --no-start, --only): the master DCF read into a checked MasterConfig,
/// then the master built from it. Both end the command as build_master does.
nmt::MasterConfig master_config_or_exit(std::string_view tool, const std::string& description,
                                        const std::shared_ptr<const cfg::Network>& network,
                                        const std::string& node_id_text,
                                        nmt::MasterOptions options);
nmt::NmtMaster build_master_or_exit(const nmt::MasterConfig& config, const std::string& description,
                                    const cfg::Network& network);

/// How long a run lasts.
struct RunLimits {
  std::string_view tool;            ///< "master", "push": the prefix of messages
  std::optional<double> run_for_s;  ///< run exactly this long (bus or simulated seconds)
  bool until_startup_ends = false;  ///< stop once NMT start-up has ended
  double bound_s = 60.0;            ///< with until_startup_ends and no run_for_s: at most
  std::string_view bound_hint;      ///< appended to the "did not end" message
  /// With until_startup_ends: also wait until this is true (e.g. every optional slave tried).
  std::function<bool()> settled;
};

/// How a run ended.
struct RunOutcome {
  nmt::Duration elapsed{0};  ///< bus time it ran (simulated time on sim:)
  /// With until_startup_ends (and no run_for_s): start-up did not end within the bound (a
  /// message was printed; the command exits 4).
  bool timed_out = false;
};

/// Files that record every frame of a run (nmt/trace.hpp); empty: none. On sim: the frames
/// are stamped with simulated time (seconds from the start), on a real bus with the wall clock.
struct RunTraces {
  std::string pcap;     ///< pcap, LINKTYPE_CAN_SOCKETCAN (Wireshark, tshark)
  std::string candump;  ///< candump log (`candump -l` format: can-utils, python-can)
};

/// The simulated devices of `network` (simulated_devices), a note on stderr for each node that
/// has no DCF to simulate it from; ends the command with exit 1 when one cannot be built.
std::vector<nmt::SimulatedDevice> simulated_devices_or_exit(std::string_view tool,
                                                            const cfg::Network& network,
                                                            const SimBusOptions& sim);

/// Runs `master` with a simulated device per node of `network` on the simulated bus, in
/// simulated time, until SIGINT/SIGTERM or `limits`. With `sim.state_dir`, each device writes
/// its saved values there whenever it saves (1010h) or forgets them (1011h). Exit 3 when a trace
/// cannot be written, 1 when a device cannot be built or its saved values are damaged.
RunOutcome run_master_on_sim(nmt::NmtMaster master, const cfg::Network& network,
                             const SimBusOptions& sim, const RunLimits& limits,
                             EventReporter& reporter, const RunTraces& traces = {});

/// Runs `master` on the real bus `url` (SocketCAN, UDP) in real time, until SIGINT/SIGTERM or
/// `limits`. Exit 3 when the bus cannot be opened or fails, or a trace cannot be written.
RunOutcome run_master_on_bus(nmt::NmtMaster master, const std::string& url, const RunLimits& limits,
                             EventReporter& reporter, const RunTraces& traces = {});

}  // namespace cfgmgr
