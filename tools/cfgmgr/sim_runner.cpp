// The master on the simulated bus (master_runners.hpp).
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "master_runners.hpp"
#include "nmt/io/trace.hpp"
#include "nmt/master/master_host.hpp"
#include "nmt/sim/device_state.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "run_args.hpp"
#include "run_support.hpp"

namespace cfgmgr {

using namespace run_support;

std::vector<nmt::SimulatedDevice> simulated_devices_or_exit(std::string_view tool,
                                                            const cfg::Network& network,
                                                            const SimBusOptions& sim,
                                                            std::vector<cfg::NodeId>* owners) {
  std::vector<cfg::NodeId> skipped;
  auto built = simulated_devices(network, sim, &skipped, owners);
  if (!built) {
    exit_with(tools::kExitInputErrors, built.error().message);
  }
  for (const cfg::NodeId node : skipped) {
    std::cerr << command_prefix(tool) << "note: node " << int{node.value()}
              << " has no DCF (a concise DCF only): not simulated (give its EDS with "
                 "sim:?device=FILE@"
              << int{node.value()} << ")\n";
  }
  return std::move(built).value();
}

RunOutcome run_master_on_sim(nmt::NmtMaster master, const cfg::Network& network,
                             const SimBusOptions& sim, const RunLimits& limits,
                             EventReporter& reporter, const RunTraces& traces) {
  // The node of each device: its state file's, whatever node-ID LSS gives the device.
  std::vector<cfg::NodeId> owners;
  std::vector<nmt::SimulatedDevice> built =
      simulated_devices_or_exit(limits.tool, network, sim, &owners);
  OpenTraces trace_files = open_traces(limits.tool, traces);
  nmt::SimBus bus(sim.bitrate_bps);
  bus.set_loss_rate(sim.loss, sim.seed);
  std::vector<nmt::TraceWriter*> writers;
  for (auto& w : trace_files.writers) {
    writers.push_back(w.get());
    bus.add_observer(nmt::trace_observer(*w));
  }
  if (traces.frames) bus.add_observer(traces.frames);
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  bool state_failed = false;
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
        if (!state_failed) reporter.note(command_prefix(limits.tool) + saved.error().message);
        state_failed = true;
      }
    });
  }
  nmt::SimEngineNode<nmt::NmtMaster> node(std::move(master));
  bus.attach(node);
  // On sim: entries are written at once, after the master's call (simulated time stands still).
  nmt::MasterHost host(
      node.engine(), [&node](const nmt::MasterHost::Call& call) { node.apply(call); },
      note_failed_writes(reporter, limits.tool));
  node.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint) {
    reporter.report(e);
    host.on_event(e);
  });

  std::cerr << command_prefix(limits.tool) << "node-ID " << int{node.engine().node_id().value()}
            << ", " << tools::plural(devices.size(), "simulated device") << " on sim: at "
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
  // A flood whose window is still open is said now, not lost with the run (emcy_consumer.hpp).
  node.apply(
      [](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.end_emergency_windows(now, out); });
  const bool late = timed_out(limits, reporter);
  close_traces(limits.tool, writers);
  if (state_failed) exit_with(tools::kExitIo);
  const auto stats = bus.statistics();
  reporter.note(command_prefix(limits.tool) + seconds_text(nmt::TimePoint{}, bus.now()) +
                " s simulated, " + std::to_string(stats.frames) + " frames, bus load " +
                std::to_string(std::lround(stats.load() * 100.0)) + "%");
  return {bus.now() - nmt::TimePoint{}, late};
}

}  // namespace cfgmgr
