// "Execute LSS" of the NMT master's boot (DSP 302 §4 figure 1 step 3, before the reset of all
// nodes; CiA 302-2 §3.1 c: the master runs the LSS master services where node-IDs must be set)
// and the later look for devices that appear unconfigured (a replaced device), as one engine of
// the shape of nmt/engine.hpp. Private to the library. The LSS protocol (CiA 305) is the
// LssProcedure's (nmt/lss/lss_procedure.hpp: its scan, built from nmt/lss/lss_master.hpp's
// services, the sources in nmt/lss/lss.hpp); this engine decides which node-ID a found device gets
// and what the master hears of it. The choices are listed in docs/master.md ("Execute LSS").
//
// It talks to the NMT master only through ExecuteLssPort: "which slave has this LSS address",
// "the start-up pass ended" (the master goes on with its reset of all nodes), and "may I use
// the bus now" (only the active master sends LSS requests). Its events are the master's own
// (MasterEvent: LssAssigned, LssUnmatched, LssFailed, LssScanEnded).
//
//   start(now, out)   the start-up pass: one LssProcedure::scan (every unconfigured device:
//                     configure node-ID, store, switch back to waiting), then port.pass_ended();
//                     the scan first selects the slaves' known addresses (port.known_addresses:
//                     switch state selective, 4 requests and one answer each) and searches bit
//                     by bit only for the devices left over
//   watch(now)        afterwards, every `period`: identify non-configured remote slave (4Ch, one
//                     frame and one Fastscan step of silence when there is nobody), and a scan
//                     only when a device answered
//   stop()            everything forgotten (the master's start-up begins again)
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "cfg/node_id.hpp"
#include "nmt/engine.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_procedure.hpp"
#include "nmt/master/nmt_master.hpp"

namespace nmt {

/// What Execute LSS needs of the NMT master that holds it.
class ExecuteLssPort {
 public:
  using Output = Outbox<MasterEvent>;
  virtual ~ExecuteLssPort() = default;

  /// The slave (node-ID in 1F81h) whose LSS address is `address`; nullopt: none.
  virtual std::optional<cfg::NodeId> slave_with(const LssAddress& address) const = 0;
  /// The LSS addresses of the slaves that have one and are not known to run (1F82h), in
  /// node-ID order: each scan selects these first (switch state selective) and searches bit by
  /// bit only for devices left over.
  virtual std::vector<LssAddress> known_addresses() const = 0;
  /// The start-up pass ended: NMT start-up goes on (reset of all nodes, boots).
  virtual void pass_ended(TimePoint now, Output& out) = 0;
  /// False while this device is not the active master (a standby flying master): no look.
  virtual bool may_look() const = 0;
};

class ExecuteLssProcess {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;

  enum class Phase : std::uint8_t {
    Off,      ///< not started, or stopped
    Startup,  ///< the start-up pass: a scan, then port.pass_ended()
    Idle,     ///< between looks (watch(); nothing due without a period)
    Probe,    ///< identify non-configured remote slave (4Ch) sent
    Scan,     ///< a look found someone: a scan
  };

  ExecuteLssProcess(ExecuteLssPort& port, LssMasterOptions timing, Duration period)
      : port_(port), lss_(timing), period_(period) {}
  ExecuteLssProcess(const ExecuteLssProcess&) = delete;
  ExecuteLssProcess& operator=(const ExecuteLssProcess&) = delete;

  /// The start-up pass (see the top). A pass or look that runs is abandoned first.
  void start(TimePoint now, Output& out);
  /// After start-up: look every `period` from `now` (nothing with a period of 0).
  void watch(TimePoint now);
  /// Off; a running LSS service is abandoned (its answers are ignored).
  void stop();

  /// LSS answers (7E4h) while a pass or look runs; true when taken.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  Phase phase() const { return phase_; }

 private:
  void begin_scan(TimePoint now, Output& out);
  void forward(TimePoint now, Output& out);
  void handle(const LssProcedureEvent& e, TimePoint now, Output& out);
  void scan_ended(const LssProcedureEvent& e, TimePoint now, Output& out);
  std::optional<cfg::NodeId> choose(const LssAddress& address);

  ExecuteLssPort& port_;
  LssProcedure lss_;
  Duration period_;
  Phase phase_ = Phase::Off;
  std::optional<TimePoint> next_look_;
  LssProcedure::Output lss_out_;  ///< scratch output of lss_
  /// This scan: the node-ID chosen for each address found (its LssFailed names the slave).
  std::map<LssAddress, cfg::NodeId> chosen_;
  std::uint32_t assigned_ = 0;
  /// Unmatched addresses reported while watching: each once (the start-up pass reports all).
  std::set<LssAddress> reported_;
};

static_assert(Engine<ExecuteLssProcess>);

}  // namespace nmt
