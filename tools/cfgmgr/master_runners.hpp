// Running a built NMT master until its run ends: on the simulated bus with a simulated device
// per node (sim_runner.cpp) or on a real bus (bus_runner.cpp), its events to an EventReporter.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/network.hpp"
#include "event_reporter.hpp"
#include "network_source.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace cfgmgr {

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
  /// A real bus's transmit and error-frame counters at the end (nullopt on sim:, which has no
  /// controller).
  std::optional<nmt::BusCounters> bus{};
};

/// Files that record every frame of a run (nmt/io/trace.hpp); empty: none. On sim: the frames
/// are stamped with simulated time (seconds from the start), on a real bus with the wall clock.
struct RunTraces {
  std::string pcap;     ///< pcap, LINKTYPE_CAN_SOCKETCAN (Wireshark, tshark)
  std::string candump;  ///< candump log (`candump -l` format: can-utils, python-can)
  /// Also called with every frame of the run (error frames included) at the engines' time, the
  /// clock of the master's events (--report's bus load); none when empty.
  std::function<void(const nmt::CanFrame&, nmt::TimePoint)> frames;
};

/// The simulated devices of `network` (simulated_devices; `owners` gets each one's node-ID), a
/// note on stderr for each node that has no DCF or device= file to simulate it from; ends the
/// command with exit 1 when one cannot be built.
std::vector<nmt::SimulatedDevice> simulated_devices_or_exit(
    std::string_view tool, const cfg::Network& network, const SimBusOptions& sim,
    std::vector<cfg::NodeId>* owners = nullptr);

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
