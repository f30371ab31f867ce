// The LSS slave of CiA 305 (nmt/lss/lss.hpp has the protocol and its sources), an engine of the
// shape of nmt/engine.hpp: master requests on 7E5h in, answers on 7E4h and events out. The owner
// (the slave node, a device's firmware) acts on the events: it applies a pending node-ID at its
// next reset communication, stores the configuration when asked, switches the bit rate.
//
// Behaviour where CiA 305 leaves room (each says why):
// - Frames other than 8 data bytes on 7E5h are ignored (CiA 305 frames are 8 bytes; CANopenNode
//   drops others too).
// - Switch state selective needs its four frames in order 40h, 41h, 42h, 43h; any other value
//   or order restarts it (as lely-core). It is obeyed in LSS waiting only.
// - Configure node-ID accepts 1..127 and FFh (back to "not configured" at the next reset
//   communication, as CANopenNode); 0 and 128..254 are refused with error code 1.
// - Configure bit timing: table selector 0 only (other tables: error 1); indices the device
//   does not run at (LssSlaveOptions::bit_timing_indices) and 5 (reserved): error 1.
// - Store configuration answers at once: the owner stores synchronously when it sees the event
//   (the simulated device keeps it in memory); without LssSlaveOptions::store_supported the
//   answer is error 1.
// - Identify remote slave and identify non-configured remote slave are answered in both LSS
//   states (lely-core); inquire services and configure services in configuration only.
// - Inquire node-ID answers the active node-ID (FFh when not configured), as CANopenNode.
// - An unconfigured device that is switched back to waiting with a pending node-ID reports
//   NodeIdActivate: its owner resets communication with it (CANopenNode does so on its own).
// - Node-IDs here are raw bytes with lss::kUnconfigured (FFh), not cfg::NodeId: FFh is a legal
//   value of the active and pending node-ID and of what is stored (CiA 305: not configured), and
//   these are the very bytes configure node-ID (11h) carries and inquire node-ID (5Eh) answers;
//   configured() says whether the active one is a node-ID. The owner turns them into a
//   cfg::NodeId where it starts with one (SlaveNode).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "nmt/engine.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

struct LssSlaveOptions {
  /// The bit timing table indices (bit n: index n) the device can run at. Default: every rate
  /// of the table (0-4, 6-8), no automatic bit rate detection (9).
  std::uint16_t bit_timing_indices = 0x01DF;
  /// Whether store configuration (17h) is supported; false: answered with error code 1.
  bool store_supported = true;
};

/// What store configuration (17h) keeps in a device's non-volatile memory: the node-ID (FFh: not
/// configured) and the bit timing table index it powers on with.
struct LssStoredConfig {
  std::uint8_t node_id = lss::kUnconfigured;
  std::uint8_t bit_timing_index = 2;
  bool operator==(const LssStoredConfig&) const = default;
};

/// What the LSS slave reports to its owner.
struct LssSlaveEvent {
  enum class Kind : std::uint8_t {
    StateChanged,         ///< LSS waiting <-> configuration (`state`)
    NodeIdConfigured,     ///< configure node-ID accepted: `node_id` is pending
    BitTimingConfigured,  ///< configure bit timing accepted: `bit_timing_index` is pending
    BitTimingActivate,    ///< activate bit timing: switch to the pending rate (`switch_delay_ms`)
    StoreRequested,       ///< store `node_id` (pending) and `bit_timing_index` (pending or active)
    NodeIdActivate,  ///< an unconfigured device left configuration with pending `node_id`: boot
  };
  Kind kind = Kind::StateChanged;
  TimePoint at{};
  LssState state = LssState::Waiting;
  std::uint8_t node_id = lss::kUnconfigured;
  std::optional<std::uint8_t> bit_timing_index;
  std::uint16_t switch_delay_ms = 0;
  std::string text;  ///< one line for people
};

class LssSlave {
 public:
  using Event = LssSlaveEvent;
  using Output = Outbox<Event>;

  /// A slave with LSS address `address` and active node-ID `node_id` (FFh: not configured),
  /// in LSS waiting. `bit_timing_index` is the rate it runs at (table index, 2 = 500 kbit/s).
  LssSlave(LssAddress address, std::uint8_t node_id, LssSlaveOptions options = {},
           std::uint8_t bit_timing_index = 2);

  /// Handles LSS requests (8-byte frames on 7E5h); true when the frame was an LSS request this
  /// slave acted on or answered.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint /*now*/, Output& /*out*/) {}
  std::optional<TimePoint> next_deadline() const { return std::nullopt; }

  LssState state() const { return state_; }
  const LssAddress& address() const { return address_; }
  std::uint8_t active_node_id() const { return active_node_id_; }
  std::uint8_t pending_node_id() const { return pending_node_id_; }
  bool configured() const { return active_node_id_ != lss::kUnconfigured; }
  std::uint8_t bit_timing_index() const { return bit_timing_index_; }
  std::optional<std::uint8_t> pending_bit_timing_index() const { return pending_bit_timing_; }

  /// The owner's reset communication: the pending node-ID becomes the active one.
  void activate_pending_node_id() { active_node_id_ = pending_node_id_; }
  /// The owner switched to the pending bit rate.
  void activate_pending_bit_timing();
  /// Power-on with `node_id` (the stored one, or FFh): LSS waiting, nothing pending but it;
  /// running at `bit_timing_index` when given (the stored one).
  /// It takes no `now, out` (an exception to engine.hpp rule 5, on purpose): an LSS slave sends
  /// nothing of its own at power-on or ever, it only answers the master's requests (CiA 305:
  /// every LSS service is initiated by the master; CANopenNode's CO_LSSslave_init and lely-core's
  /// co_lss_start send nothing either), and it has nothing to time. Whatever a device says at
  /// power-on (its boot-up message) is its owner's, the SlaveNode's start(now, out).
  void start(std::uint8_t node_id, std::optional<std::uint8_t> bit_timing_index = {});

 private:
  void answer(Output& out, lss::Cs cs, std::uint32_t value = 0);
  LssSlaveEvent make_event(LssSlaveEvent::Kind kind, TimePoint now, std::string text) const;
  void fastscan(const CanFrame& frame, TimePoint now, Output& out);
  bool unconfigured() const {
    return active_node_id_ == lss::kUnconfigured && pending_node_id_ == lss::kUnconfigured;
  }

  LssAddress address_;
  LssSlaveOptions options_;
  LssState state_ = LssState::Waiting;
  std::uint8_t active_node_id_;
  std::uint8_t pending_node_id_;
  std::uint8_t bit_timing_index_;
  std::optional<std::uint8_t> pending_bit_timing_;
  std::uint8_t selective_next_ = 0;     ///< switch state selective: frames 40h.. matched so far
  std::uint8_t identify_next_ = 0;      ///< identify remote slave: frames 46h.. matched so far
  std::uint8_t fastscan_position_ = 0;  ///< Fastscan: the LSSSub this slave compares next
};
static_assert(Engine<LssSlave>);

}  // namespace nmt
