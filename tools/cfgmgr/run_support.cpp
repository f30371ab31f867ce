// What both runners share (run_support.hpp).
#include "run_support.hpp"

#include <csignal>
#include <sstream>
#include <utility>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"

namespace cfgmgr::run_support {

std::atomic<bool> g_stop{false};
std::atomic<nmt::BusEventLoop*> g_running_loop{nullptr};

namespace {
extern "C" void on_master_stop_signal(int) {
  g_stop.store(true);
  if (auto* loop = g_running_loop.load()) loop->request_stop();
}
}  // namespace

StopSignals::StopSignals() {
  struct sigaction action {};
  action.sa_handler = on_master_stop_signal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, &old_int_);
  sigaction(SIGTERM, &action, &old_term_);
}

StopSignals::~StopSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

nmt::MasterHost::Done note_failed_writes(EventReporter& reporter, std::string_view tool) {
  return [&reporter, tool](const cfg::Status& done) {
    if (!done) reporter.note(command_prefix(tool) + "error: " + done.error().message);
  };
}

namespace {
std::unique_ptr<nmt::TraceWriter> open_or_exit(
    std::string_view tool, cfg::Result<std::unique_ptr<nmt::TraceWriter>> opened) {
  if (!opened) fail_command(tool, tools::kExitIo, opened.error().message);
  return std::move(opened).value();
}
}  // namespace

OpenTraces open_traces(std::string_view tool, const RunTraces& traces) {
  OpenTraces out;
  if (!traces.pcap.empty()) out.writers.push_back(open_or_exit(tool, nmt::open_pcap(traces.pcap)));
  if (!traces.candump.empty()) {
    out.writers.push_back(open_or_exit(tool, nmt::open_candump_log(traces.candump)));
  }
  return out;
}

void close_traces(std::string_view tool, const std::vector<nmt::TraceWriter*>& writers) {
  for (nmt::TraceWriter* w : writers) {
    if (auto flushed = w->flush(); !flushed) {
      fail_command(tool, tools::kExitIo,
                   "trace " + w->path().string() + ": " + flushed.error().message);
    }
  }
}

bool ended(const RunLimits& limits, const EventReporter& reporter) {
  return reporter.finished() && (!limits.settled || limits.settled());
}

bool timed_out(const RunLimits& limits, EventReporter& reporter) {
  if (!limits.until_startup_ends || limits.run_for_s || ended(limits, reporter) || g_stop.load()) {
    return false;
  }
  std::ostringstream text;
  text << command_prefix(limits.tool) << "NMT start-up did not end within " << limits.bound_s
       << " s" << limits.bound_hint;
  reporter.note(text.str());
  return true;
}

}  // namespace cfgmgr::run_support
