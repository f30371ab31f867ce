// The master on a real bus (master_runners.hpp).
#include <iostream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "master_runners.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/entry_persister.hpp"
#include "nmt/io/trace.hpp"
#include "nmt/master/master_host.hpp"
#include "run_args.hpp"
#include "run_support.hpp"

namespace cfgmgr {

using namespace run_support;

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
  nmt::MasterHost host(
      master, [&ref](const nmt::MasterHost::Call& call) { ref.apply(call); },
      note_failed_writes(reporter, limits.tool));
  // --store DIR: entries are written on a worker thread, so an fsync does not stall the loop;
  // the SDO confirmation leaves once the entry is durable (nmt/io/entry_persister.hpp).
  nmt::EntryPersister persister(ref, host);
  ref.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint) {
    reporter.report(e);
    host.on_event(e);
    if (limits.until_startup_ends && !limits.run_for_s && ended(limits, reporter)) {
      loop.request_stop();
    }
  });
  if (traces.frames) {
    loop.set_observer([&traces](const nmt::CanFrame& frame, nmt::TimePoint at,
                                nmt::BusEventLoop::Direction) { traces.frames(frame, at); });
  }
  loop.set_bus_event_handler(
      [&reporter](const nmt::BusEvent& e, nmt::TimePoint at) { reporter.report_bus(e, at); });
  const bool forever = !limits.run_for_s && !limits.until_startup_ends;
  std::cerr << command_prefix(limits.tool) << "node-ID " << int{master.node_id().value()} << " on "
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
  // A flood whose window is still open is said now, not lost with the run (emcy_consumer.hpp).
  ref.apply(
      [](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.end_emergency_windows(now, out); });
  if (const std::string counters = bus_counters_text(loop.counters()); !counters.empty()) {
    reporter.note(command_prefix(limits.tool) + "bus: " + counters);
  }
  std::vector<nmt::TraceWriter*> writers;
  writers.reserve(tracing.size());
  for (auto* t : tracing) writers.push_back(&t->trace());
  close_traces(limits.tool, writers);
  return {loop.now() - began, timed_out(limits, reporter), loop.counters()};
}

}  // namespace cfgmgr
