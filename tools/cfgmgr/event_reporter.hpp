// The master's events as `cfgmgr master` and `cfgmgr push` print them: one line each on stderr,
// JSON lines for --json-events, and what the exit code depends on (master_run.hpp runs them).
#pragma once

#include <functional>
#include <iosfwd>
#include <memory>
#include <set>
#include <string>

#include "cfg/network.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/master/nmt_master.hpp"
#include "program_updates.hpp"

namespace cfgmgr {

/// Prints the master's events (one line each on stderr, JSON lines to `json` when given) and
/// keeps what the exit code depends on.
class EventReporter {
 public:
  EventReporter(bool verbose, std::ostream* json) : verbose_(verbose), json_(json) {}

  /// Event times are printed as seconds since `start` (0 on sim:).
  void set_start(nmt::TimePoint start) { start_ = start; }
  nmt::TimePoint start() const { return start_; }
  /// Quiet: no event lines on stderr (a live view shows the run instead) but the EMCYs', which
  /// go to note(); JSON lines stay.
  void set_quiet(bool quiet) { quiet_ = quiet; }
  /// Events of these nodes are neither printed nor written (nodes a run leaves alone); the
  /// observer still gets them.
  void ignore_nodes(std::set<std::uint8_t> nodes) { ignored_ = std::move(nodes); }
  /// Also called with every event (after it was printed).
  void set_observer(std::function<void(const nmt::MasterEvent&)> observer) {
    observer_ = std::move(observer);
  }

  void report(const nmt::MasterEvent& e);
  /// What the event loop says about the bus itself: send failures, refused frames
  /// and the controller's state from error frames. On stderr as "bus: ..." (lost arbitration,
  /// bus errors and the warning level only with verbose), in JSON as an event named after the
  /// kind (bus_off, restarted, send_failed, ...) with node_id 0 and the frame.
  void report_bus(const nmt::BusEvent& e, nmt::TimePoint at);
  /// A line for people that is no event (a summary, a warning): on stderr, or to the handler
  /// (a live view prints it above itself).
  void note(const std::string& line);
  void set_note_handler(std::function<void(const std::string&)> handler) {
    note_handler_ = std::move(handler);
  }

  /// Follows each node's software update (DSP 302 §9) and prints "node N: program updated: ..."
  /// when one succeeds (also when quiet: a live view shows it above itself).
  void track_programs(std::shared_ptr<const cfg::Network> network) {
    programs_ = ProgramUpdates(std::move(network));
  }
  const ProgramUpdates& programs() const { return programs_; }

  bool finished() const { return finished_; }
  bool complete() const { return complete_; }
  bool halted() const { return halted_; }

 private:
  void write_json(const nmt::MasterEvent& e);

  nmt::TimePoint start_{};
  bool verbose_;
  bool quiet_ = false;
  std::ostream* json_;
  std::function<void(const nmt::MasterEvent&)> observer_;
  std::function<void(const std::string&)> note_handler_;
  ProgramUpdates programs_;
  std::set<std::uint8_t> booted_;
  std::set<std::uint8_t> ignored_;
  bool finished_ = false;
  bool complete_ = false;
  bool halted_ = false;
};

}  // namespace cfgmgr
