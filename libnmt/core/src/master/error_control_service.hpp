// The NMT master's error control (CiA 302-2 §4.1, CiA 301 §7.2.8.3.2): one heartbeat consumer
// and one node guarding master for every node the master watches, and, per node, who wants it
// watched. Two parts of the master watch nodes: the master itself (boot NMT slave's start error
// control, §4.1; request node guarding, §6.5) and the SDO manager (registered SRDs, DSP 302
// §7.2.1, and the slaves of SRDs with Req EC, §7.2.2). A node stays watched while any of them
// wants it: the master stopping its error control of a slave (after a boot error, at a boot-up)
// does not end the manager's watch, whose loss the manager reports in 1F11h (DSP 302 §7.2.3).
// An engine (engine.hpp); private to the library.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/error_control.hpp"

namespace nmt {

/// Who wants a node watched (the owner tags of ErrorControlService).
enum class Watcher : std::uint8_t {
  Master,  ///< the NMT master: start error control (§4.1), request node guarding (§6.5)
  Manager  ///< the SDO manager: SRDs (DSP 302 §7.2.1), slaves for Req EC (§7.2.2)
};

/// A set of watchers.
struct Watchers {
  bool master = false;
  bool manager = false;

  bool has(Watcher w) const { return w == Watcher::Master ? master : manager; }
  void set(Watcher w, bool on) { (w == Watcher::Master ? master : manager) = on; }
  bool any() const { return master || manager; }
  bool operator==(const Watchers&) const = default;
};

/// The two protocols of error control (CiA 301 §7.2.8.3.2).
enum class ErrorControlProtocol : std::uint8_t { Heartbeat, Guarding };

/// What the service reports: a node's error control event and its end, with the watchers that
/// wanted the node watched by that protocol when it happened (each of them learns it).
struct ErrorControlEvent {
  enum class Kind : std::uint8_t {
    Lost,     ///< heartbeat event (no heartbeat within the consumer time), node guarding event
    Resolved  ///< the heartbeat or the guarding reply came again
  };
  cfg::NodeId node;
  Kind kind;
  ErrorControlProtocol protocol;
  Watchers watchers;
  TimePoint at;
  bool operator==(const ErrorControlEvent&) const = default;
};

class ErrorControlService {
 public:
  using Event = ErrorControlEvent;
  using Output = Outbox<Event>;

  /// Heartbeat consumption of `node` for `watcher` with consumer time `time` (1016h), counted
  /// from `now` (§4.1: "the timer for timeout checking shall be started immediately"): a
  /// (re)start of the node's consumer. A parameter write (engine.hpp rule 5): nothing at once.
  void monitor(cfg::NodeId node, Watcher watcher, Duration time, TimePoint now);
  /// Node guarding of `node` for `watcher` (1F81h guard time and retry factor): a (re)start,
  /// its first request due at `now` (NodeGuardingMaster::guard). A guard time or factor of 0
  /// guards nothing (§6.3): the call returns why and changes nothing.
  cfg::Status guard(cfg::NodeId node, Watcher watcher, std::uint16_t guard_time_ms,
                    std::uint8_t life_time_factor, TimePoint now);
  /// `watcher` wants `node` watched as it is watched now: true when another watcher watches it
  /// already (it joins, nothing restarts); false when nobody does (nothing changes: start it
  /// with monitor or guard).
  bool join(cfg::NodeId node, Watcher watcher);
  /// `watcher` no longer wants `node` watched; the node's protocols stop when nobody else does.
  void stop(cfg::NodeId node, Watcher watcher);
  /// The same for node guarding alone (request node guarding's stop, §6.5 Table 31).
  void stop_guarding(cfg::NodeId node, Watcher watcher);

  bool watches(cfg::NodeId node) const { return watchers(node).any(); }
  bool guards(cfg::NodeId node) const { return guarding_.guards(node); }
  bool monitors(cfg::NodeId node) const { return heartbeats_.monitors(node); }
  /// Who wants `node` watched, by either protocol.
  Watchers watchers(cfg::NodeId node) const;

  /// Heartbeats and guarding replies: a Resolved event when one ends a loss. True for error
  /// control messages of watched nodes that an engine took.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Heartbeat events and node guarding (its due requests, its events), in that order.
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;
  /// Node guarding alone: its requests (and events) due at `now`. The master calls it at the end
  /// of each call, so that a guarding started in the call sends its first request after the
  /// call's NMT commands and SDO requests: a slave that boot starts is started before its first
  /// guarding request (CiA 302-2 §3.4 part 3 e before g-l).
  void send_due_requests(TimePoint now, Output& out);

 private:
  void guarding_timer(TimePoint now, Output& out);
  void report(cfg::NodeId node, ErrorControlEvent::Kind kind, ErrorControlProtocol protocol,
              TimePoint at, Output& out) const;

  HeartbeatConsumer heartbeats_{HeartbeatConsumerOptions{.timeout_from_start = true}};
  NodeGuardingMaster guarding_;
  /// Per node-ID (index 0 unused): who wants it watched by heartbeat, by guarding.
  std::array<Watchers, 128> heartbeat_watchers_{};
  std::array<Watchers, 128> guarding_watchers_{};
  /// Scratch outputs of the two engines, cleared before each use (no allocation once grown).
  Outbox<HeartbeatEvent> heartbeat_out_;
  Outbox<NodeGuardingEvent> guarding_out_;
};

static_assert(Engine<ErrorControlService>);

}  // namespace nmt
