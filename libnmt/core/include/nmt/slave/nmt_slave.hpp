// The NMT slave state machine of CiA 301 §7.3.2, an engine of the shape of nmt/engine.hpp: NMT
// module control commands in, state transitions (its events) and the boot-up message out. The
// owner (the slave node, a real device's firmware) performs the resets the machine asks for and
// then ends initialisation.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

#include "cfg/node_id.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// NMT states, with the values the heartbeat and node-guarding messages carry (CiA 301
/// §7.2.8.3.2.1): 00 boot-up (initialising), 04 stopped, 05 operational, 7F pre-operational.
enum class NmtState : std::uint8_t {
  Initialising = 0x00,
  Stopped = 0x04,
  Operational = 0x05,
  PreOperational = 0x7F,
};
std::string_view to_string(NmtState state);  ///< "initialising", "stopped", ...
/// The state a heartbeat/guarding byte announces (bit 7, the toggle bit, is ignored);
/// nullopt for values that are no state.
std::optional<NmtState> nmt_state_from_byte(std::uint8_t byte);

/// NMT module control command specifiers (CiA 301 §7.2.8.3.1), byte 0 of a frame on COB-ID 000h.
enum class NmtCommand : std::uint8_t {
  Start = 0x01,                ///< start remote node
  Stop = 0x02,                 ///< stop remote node
  EnterPreOperational = 0x80,  ///< enter pre-operational
  ResetNode = 0x81,            ///< reset node (application and communication)
  ResetCommunication = 0x82,   ///< reset communication
};
std::string_view to_string(NmtCommand command);  ///< "start", "stop", "enter pre-operational", ...
std::optional<NmtCommand> nmt_command_from_byte(std::uint8_t byte);

/// COB-IDs of the pre-defined connection set used by NMT (CiA 301 §7.3.3).
inline constexpr std::uint32_t kNmtCobId = 0x000;
inline constexpr std::uint32_t kErrorControlCobIdBase = 0x700;

/// Whom an NMT module control command addresses: one node, or all nodes, which the frame writes
/// as node-ID 0 (CiA 301 §7.2.8.3.1). Converts implicitly from a cfg::NodeId.
class NmtTarget {
 public:
  constexpr NmtTarget(cfg::NodeId node) : node_(node) {}  // NOLINT(google-explicit-constructor)
  static constexpr NmtTarget all_nodes() { return NmtTarget(); }
  /// The target a frame's byte 1 names: 0 all nodes, 1..127 that node; nullopt above 127.
  static constexpr std::optional<NmtTarget> from_byte(std::uint8_t byte) {
    if (byte == 0) return all_nodes();
    if (const auto node = cfg::NodeId::from(byte)) return NmtTarget(*node);
    return std::nullopt;
  }
  constexpr bool all() const { return !node_.has_value(); }
  /// The one node addressed; nullopt for all nodes.
  constexpr std::optional<cfg::NodeId> node() const { return node_; }
  /// True when a node with this node-ID obeys the command (it is the target, or all nodes are).
  constexpr bool addresses(cfg::NodeId node) const { return !node_ || *node_ == node; }
  /// Byte 1 of the frame: the node-ID, 0 for all nodes.
  constexpr std::uint8_t byte() const { return node_ ? node_->value() : std::uint8_t{0}; }
  constexpr bool operator==(const NmtTarget&) const = default;

 private:
  constexpr NmtTarget() = default;
  std::optional<cfg::NodeId> node_;
};

/// The NMT module control frame `000#CCNN` (NN: the node-ID, 00 for all nodes).
CanFrame make_nmt_command(NmtCommand command, NmtTarget target);
/// A received NMT command: the command and whom it addresses.
struct NmtCommandFrame {
  NmtCommand command;
  NmtTarget target;
};
/// Parses a frame on COB-ID 000h with exactly two data bytes and a known specifier; nullopt for
/// anything else (other COB-IDs, RTR, wrong length, unknown specifier, node-ID > 127).
std::optional<NmtCommandFrame> parse_nmt_command(const CanFrame& frame);

/// The boot-up message `7xx#00` (CiA 301 §7.2.8.3.2.4).
CanFrame make_boot_up(cfg::NodeId node_id);

/// Which communication services a node runs in a state (CiA 301 §7.3.2.2, Table 51). In
/// initialising a node only sends its boot-up message.
struct NmtServices {
  bool sdo = false;            ///< SDO server and client
  bool pdo = false;            ///< receive and transmit PDOs
  bool emcy = false;           ///< emergency producer
  bool sync_time = false;      ///< SYNC and TIME
  bool error_control = false;  ///< heartbeat, node guarding, life guarding
  bool nmt = false;            ///< NMT module control commands are obeyed
};
NmtServices services_in(NmtState state);

/// What initialisation has to restore before the node boots again (CiA 301 §7.3.2.2.1):
/// reset application restores the whole dictionary (then communication), reset communication only
/// the communication area 1000h-1FFFh. Power-on counts as reset application.
enum class ResetScope : std::uint8_t { Application, Communication };
std::string_view to_string(ResetScope scope);

/// A state change caused by an NMT command: the NMT slave's event. `reset` is set when the node
/// went to initialising.
struct NmtTransition {
  NmtState from;
  NmtState to;
  NmtCommand command;
  std::optional<ResetScope> reset;
  bool operator==(const NmtTransition&) const = default;
};

/// The NMT slave state machine of one node. Starts in Initialising (power-on); the owner restores
/// its parameters for `pending_reset()` and calls `finish_initialisation()`, which sends the
/// boot-up message and enters pre-operational. Commands received while initialising are ignored:
/// the node is not on the bus yet. Nothing in it is timed (next_deadline() is always nullopt).
class NmtSlave {
 public:
  using Event = NmtTransition;
  using Output = Outbox<Event>;
  using Transition = NmtTransition;

  explicit NmtSlave(cfg::NodeId node_id);

  cfg::NodeId node_id() const { return node_id_; }
  NmtState state() const { return state_; }
  NmtServices services() const { return services_in(state_); }
  /// The reset the owner must perform before finish_initialisation(); nullopt outside
  /// initialising.
  std::optional<ResetScope> pending_reset() const { return pending_reset_; }

  /// Feeds a frame. An NMT command for this node or for all nodes is reported as a transition
  /// (a command that does not change the state, e.g. start while operational, is still reported,
  /// with from == to) and returns true; every other frame returns false. Sends nothing.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint /*now*/, Output& /*out*/) {}
  std::optional<TimePoint> next_deadline() const { return std::nullopt; }

  /// Ends initialisation: enters pre-operational and sends the boot-up message.
  /// Only valid while initialising (asserted).
  void finish_initialisation(TimePoint now, Output& out);

  /// A state change the node makes on its own, not by NMT command: the communication error
  /// behaviour of 1029h, or a self-starting device going operational. Not into or out of
  /// initialising (asserted): resets go through on_frame()/start().
  void set_state(NmtState state);

  /// Power failure / hardware reset: back to initialising with a reset-application pending.
  /// The start of engine.hpp rule 5 in its shape, though it sends and reports nothing at once:
  /// initialisation comes first, and the owner ends it with finish_initialisation(), which
  /// sends the boot-up message.
  void start(TimePoint now, Output& out);

  /// Changes the node-ID used from the next initialisation on (e.g. LSS configured a new one;
  /// CiA 301 applies a new node-ID at reset communication).
  void set_node_id(cfg::NodeId node_id);

 private:
  cfg::NodeId node_id_;
  cfg::NodeId pending_node_id_;
  NmtState state_ = NmtState::Initialising;
  std::optional<ResetScope> pending_reset_ = ResetScope::Application;
};
static_assert(Engine<NmtSlave>);

}  // namespace nmt
