// What the two runners (sim_runner.cpp, bus_runner.cpp) share: the stop signals, the trace
// files, the end of a run, and the note of a failed store write. Private to the runners.
#pragma once

#include <csignal>

#include <atomic>
#include <memory>
#include <string_view>
#include <vector>

#include "event_reporter.hpp"
#include "master_runners.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/trace.hpp"
#include "nmt/master/master_host.hpp"

namespace cfgmgr::run_support {

/// Set by SIGINT/SIGTERM; the running real-time loop (when set) is told at once.
extern std::atomic<bool> g_stop;
extern std::atomic<nmt::BusEventLoop*> g_running_loop;

/// Installs the SIGINT/SIGTERM handlers for the lifetime of the object.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

/// The master's driver duties (nmt/master/master_host.hpp): --store DIR's entries written, and
/// start-up let enter operational at once (this program is the application, with nothing of its own
/// to do first). This says a failed write on stderr; the master aborts the download.
nmt::MasterHost::Done note_failed_writes(EventReporter& reporter, std::string_view tool);

/// The trace files of a run, open.
struct OpenTraces {
  std::vector<std::unique_ptr<nmt::TraceWriter>> writers;
};
/// Opens the files `traces` names; exit 3 when one cannot be created.
OpenTraces open_traces(std::string_view tool, const RunTraces& traces);
/// The traces complete on disk; exit 3 when one failed during the run or now.
void close_traces(std::string_view tool, const std::vector<nmt::TraceWriter*>& writers);

/// Start-up ended and, when the limits say so, the run settled.
bool ended(const RunLimits& limits, const EventReporter& reporter);
/// With until_startup_ends, a start-up that did not end within the bound is a failed run: says
/// so and returns true.
bool timed_out(const RunLimits& limits, EventReporter& reporter);

}  // namespace cfgmgr::run_support
