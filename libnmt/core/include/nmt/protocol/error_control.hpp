// NMT error control (CiA 301 §7.2.8.3.2), sans-I/O: heartbeat producer (1017h) and consumer
// (1016h), node guarding as the guarded slave answers it, and life guarding (100Ch, 100Dh).
// Each is an engine of the shape of nmt/engine.hpp: frames and the current time in, frames,
// events and the next deadline out; they never read a clock.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string_view>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/deadline_queue.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/slave/nmt_slave.hpp"

namespace nmt {

/// A heartbeat message `7xx#SS` (CiA 301 §7.2.8.3.2.2).
CanFrame make_heartbeat(cfg::NodeId node_id, NmtState state);
/// The node guarding request: an RTR frame on 700h + node-ID with DLC 1 (CiA 301 §7.2.8.3.2.1).
CanFrame make_guarding_request(cfg::NodeId node_id);

/// A received error-control message (heartbeat, boot-up or guarding reply): 700h + node-ID, one
/// data byte, no RTR. The node-ID is checked once, here: 700h (node-ID 0) and 780h-7FFh are no
/// error-control messages.
struct ErrorControlMessage {
  cfg::NodeId node_id;
  std::uint8_t byte;  ///< state in bits 0-6, toggle bit (guarding) or reserved (heartbeat) in 7
  std::optional<NmtState> state() const { return nmt_state_from_byte(byte); }
  bool toggle() const { return (byte & 0x80) != 0; }
};
/// nullopt for any other frame (other COB-IDs, node-ID outside 1..127, RTR, DLC != 1).
std::optional<ErrorControlMessage> parse_error_control(const CanFrame& frame);

/// One sub-index of 1016h: node-ID in bits 16-23, heartbeat time in ms in bits 0-15; a node-ID
/// of 0 or a time of 0 leaves the entry unused (CiA 301 §7.5.2.33).
struct HeartbeatConsumerEntry {
  /// The byte as 1016h holds it, raw on purpose: 0 and 128..255 are legal there (unused
  /// entry); node() is the checked node-ID.
  std::uint8_t node_id = 0;
  std::uint16_t time_ms = 0;
  bool active() const { return cfg::is_node_id(node_id) && time_ms != 0; }
  /// The node the entry names; nullopt for 0 and values above 127 (unused entries).
  std::optional<cfg::NodeId> node() const { return cfg::NodeId::from(node_id); }
  std::uint32_t encode() const { return (std::uint32_t{node_id} << 16) | time_ms; }
  static HeartbeatConsumerEntry decode(std::uint32_t value) {
    return {static_cast<std::uint8_t>((value >> 16) & 0xFF),
            static_cast<std::uint16_t>(value & 0xFFFF)};
  }
};

/// Heartbeat producer of one node (1017h). Starts with the boot-up message: CiA 301
/// §7.2.8.3.2.2 counts the boot-up as the first heartbeat, so the next one follows one period
/// later. A non-zero period written at run time starts the protocol at once. Heartbeats carry
/// the state set with set_state() at the time they are sent. Reports no events.
class HeartbeatProducer {
 public:
  using Event = NoEvent;
  using Output = Outbox<Event>;

  explicit HeartbeatProducer(cfg::NodeId node_id) : node_id_(node_id) {}

  /// Sets 1017h. 0 stops the producer; a change restarts the cycle with a heartbeat due `now`
  /// (next_deadline() == now: the driver calls on_timer() at once). No Output, unlike the starts
  /// of engine.hpp rule 5: this is a parameter write, made by an SDO download or a reset of the
  /// communication area, and the first heartbeat follows what that call sends (the SDO answer
  /// confirming the write, the boot-up message), not the other way round.
  void set_period(std::uint16_t period_ms, TimePoint now);
  std::uint16_t period_ms() const { return period_ms_; }
  /// The node-ID the heartbeats are sent for (700h + node-ID).
  void set_node_id(cfg::NodeId node_id) { node_id_ = node_id; }
  /// The NMT state the next heartbeats announce.
  void set_state(NmtState state) { state_ = state; }
  /// The boot-up message was sent at `now`: the next heartbeat is one period later.
  void on_boot_up(TimePoint now);
  /// Initialising: nothing is sent until the next boot-up.
  void stop() { next_.reset(); }

  /// Heartbeats are produced, not consumed: every frame returns false.
  bool on_frame(const CanFrame& /*frame*/, TimePoint /*now*/, Output& /*out*/) { return false; }
  /// Sends the heartbeat when it is due.
  void on_timer(TimePoint now, Output& out);
  /// When the next heartbeat is due; nullopt when stopped or disabled.
  std::optional<TimePoint> next_deadline() const { return next_; }

 private:
  cfg::NodeId node_id_;
  NmtState state_ = NmtState::PreOperational;
  std::uint16_t period_ms_ = 0;
  std::optional<TimePoint> next_;
};
static_assert(Engine<HeartbeatProducer>);

/// What a heartbeat consumer reports about a monitored node.
enum class HeartbeatEventKind : std::uint8_t {
  Timeout,       ///< heartbeat event: no heartbeat within the consumer time (CiA 301)
  Resolved,      ///< a heartbeat arrived again after a timeout
  StateChanged,  ///< the node announced a different NMT state
  BootUp,        ///< the node sent its boot-up message (monitoring waits for a heartbeat again)
};
std::string_view to_string(HeartbeatEventKind kind);

struct HeartbeatEvent {
  cfg::NodeId node_id;
  HeartbeatEventKind kind;
  std::optional<NmtState> state;  ///< the announced state (nullopt for Timeout)
  TimePoint at;
  bool operator==(const HeartbeatEvent&) const = default;
};

struct HeartbeatConsumerOptions {
  /// CiA 302-2 §4.1 (start error control): "the timer for timeout checking shall be started
  /// immediately with the process itself", so a node that never sends a heartbeat times out one
  /// consumer time after monitoring starts. false: CiA 301 behaviour, monitoring begins with the
  /// first heartbeat received.
  bool timeout_from_start = false;
};

/// Heartbeat consumer (1016h) for any number of nodes. A node that timed out reports Timeout
/// once; the next heartbeat from it reports Resolved and re-arms the timer.
class HeartbeatConsumer {
 public:
  using Event = HeartbeatEvent;
  using Output = Outbox<Event>;

  explicit HeartbeatConsumer(HeartbeatConsumerOptions options = {}) : options_(options) {}

  /// Starts (or restarts) monitoring of entry.node_id at `now`; an inactive entry stops it.
  /// Sends and reports nothing at once (a timeout is the earliest it reports), so it takes no
  /// Output (engine.hpp rule 5).
  void monitor(HeartbeatConsumerEntry entry, TimePoint now);
  void stop(cfg::NodeId node_id);
  void stop_all() {
    nodes_.clear();
    due_.clear();
  }
  bool monitors(cfg::NodeId node_id) const { return nodes_.count(node_id) != 0; }
  /// The last state a node announced, if any.
  std::optional<NmtState> last_state(cfg::NodeId node_id) const;

  /// Feeds a received frame; error-control messages of monitored nodes may produce events and
  /// return true (false for every other frame). Sends nothing.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Reports nodes whose consumer time expired at or before `now`.
  void on_timer(TimePoint now, Output& out);
  /// The earliest time a node may time out; nullopt when no timer runs.
  std::optional<TimePoint> next_deadline() const;

 private:
  struct Node {
    Duration time;
    std::optional<TimePoint> expires;  ///< nullopt: waiting for the first heartbeat, or timed out
    bool timed_out = false;
    std::optional<NmtState> state;
  };
  /// Sets node.expires, keeping due_ in step.
  void set_expires(cfg::NodeId id, Node& node, std::optional<TimePoint> expires);
  HeartbeatConsumerOptions options_;
  std::map<cfg::NodeId, Node> nodes_;
  DeadlineQueue<cfg::NodeId> due_;  ///< the nodes' `expires`, earliest first
};

/// What life guarding reports (CiA 301 §7.2.8.3.2.1).
enum class LifeGuardingEvent : std::uint8_t {
  Occurred,  ///< no guarding request within guard time × life time factor
  Resolved,  ///< a guarding request arrived again after the event
};

/// The guarded side of node guarding and life guarding. Answers each guarding request with the
/// state set with set_state() and a toggle bit that starts at 0 after initialisation and
/// alternates; life guarding starts with the first request and only when 100Ch and 100Dh are
/// both non-zero. Its events are the life guarding events.
class NodeGuardingSlave {
 public:
  using Event = LifeGuardingEvent;
  using Output = Outbox<Event>;

  explicit NodeGuardingSlave(cfg::NodeId node_id) : node_id_(node_id) {}

  /// 100Ch guard time in ms and 100Dh life time factor; life time = their product.
  void configure(std::uint16_t guard_time_ms, std::uint8_t life_time_factor);
  /// The node-ID whose requests (RTR on 700h + node-ID) are answered.
  void set_node_id(cfg::NodeId node_id) { node_id_ = node_id; }
  /// The NMT state the replies announce.
  void set_state(NmtState state) { state_ = state; }
  /// Initialisation (reset communication): toggle back to 0, life guarding inactive.
  void reset();

  /// Only an RTR on 700h + node-ID is a guarding request (returns true): it is answered, and
  /// Resolved is reported when life guarding recovers. Other frames return false.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Reports Occurred once when the life time expired at or before `now`.
  void on_timer(TimePoint now, Output& out);
  /// When life guarding expires; nullopt while inactive or already expired.
  std::optional<TimePoint> next_deadline() const;
  bool toggle() const { return toggle_; }

 private:
  Duration life_time() const;

  cfg::NodeId node_id_;
  NmtState state_ = NmtState::PreOperational;
  std::uint16_t guard_time_ms_ = 0;
  std::uint8_t life_time_factor_ = 0;
  bool toggle_ = false;
  std::optional<TimePoint> last_request_;
  bool expired_ = false;
};
static_assert(Engine<NodeGuardingSlave>);

/// What the guarding master reports about a guarded node.
enum class NodeGuardingEventKind : std::uint8_t {
  Timeout,       ///< node guarding event: life_time_factor requests without a valid reply
  Resolved,      ///< a valid reply arrived again after a Timeout
  StateChanged,  ///< the node answered with a different NMT state
};
std::string_view to_string(NodeGuardingEventKind kind);

struct NodeGuardingEvent {
  cfg::NodeId node_id;
  NodeGuardingEventKind kind;
  std::optional<NmtState> state;  ///< the state in the reply (nullopt for Timeout)
  TimePoint at;
  bool operator==(const NodeGuardingEvent&) const = default;
};

/// The guarding side of node guarding, as an NMT master runs it (CiA 301 §7.2.8.3.2.1; CiA 302-2
/// §4.1 starts it when a node has no heartbeat and 1F81h bytes 2-3 give a guard time). Sends a
/// request every guard time; the reply must arrive before the next request and its toggle bit
/// must alternate, starting at 0. A request without a valid reply counts as missed; after
/// life_time_factor missed requests in a row, Timeout is reported once. A reply whose toggle bit
/// did not alternate counts as missed and resynchronises the expected toggle.
class NodeGuardingMaster {
 public:
  using Event = NodeGuardingEvent;
  using Output = Outbox<Event>;

  /// Starts (or restarts) guarding `node_id` (engine.hpp rule 5): the first request goes into
  /// `out` at once, the next one guard_time_ms later. A guard time or life time factor of 0
  /// guards nothing (CiA 302-2 §6.3): the call returns why, changes nothing and sends nothing.
  cfg::Status start(cfg::NodeId node_id, std::uint16_t guard_time_ms, std::uint8_t life_time_factor,
                    TimePoint now, Output& out);
  /// The same as a parameter write (engine.hpp rule 5, like HeartbeatProducer::set_period):
  /// `node_id` is guarded from now on and its first request is due at `now`, so it leaves at
  /// the next on_timer, after what the caller sends in the same call (the NMT master starts a
  /// slave before its first guarding request, CiA 302-2 §3.4 part 3). Refuses what start refuses.
  cfg::Status guard(cfg::NodeId node_id, std::uint16_t guard_time_ms, std::uint8_t life_time_factor,
                    TimePoint now);
  void stop(cfg::NodeId node_id);
  bool guards(cfg::NodeId node_id) const { return nodes_.count(node_id) != 0; }

  /// Feeds a received frame; a reply of a guarded node that awaits one returns true and may
  /// produce events. Other frames return false.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Sends due requests and reports nodes that reached their life time.
  void on_timer(TimePoint now, Output& out);
  /// The next request time of any node; nullopt when none is guarded.
  std::optional<TimePoint> next_deadline() const;

 private:
  struct Node {
    Duration guard_time;
    std::uint8_t life_time_factor = 0;
    TimePoint next_request;
    bool awaiting_reply = false;
    bool expected_toggle = false;
    std::uint8_t missed = 0;
    bool timed_out = false;
    std::optional<NmtState> state;
  };
  /// Sends the node's request when it is due, counting the unanswered one before it.
  void send_due(cfg::NodeId id, Node& node, TimePoint now, Output& out);
  std::map<cfg::NodeId, Node> nodes_;
  DeadlineQueue<cfg::NodeId> due_;  ///< the nodes' `next_request`, earliest first
};

static_assert(Engine<HeartbeatConsumer>);
static_assert(Engine<NodeGuardingMaster>);

}  // namespace nmt
