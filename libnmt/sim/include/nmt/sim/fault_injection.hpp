// Test faults as wrappers of the engine shape (nmt/engine.hpp, rule 7): a wrapper holds an
// engine, is an nmt::Engine itself, and changes only what goes in or out of the wrapped one, so
// protocol engines carry no test knobs. Wrappers nest (a delayed, lossy device).
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <utility>
#include <vector>

#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/slave/slave_node.hpp"

namespace nmt {

/// Frames held back until their due time and released in the order held: a frame never
/// overtakes an earlier one, also when later frames are given an earlier due time.
class HeldFrames {
 public:
  void hold(const CanFrame& frame, TimePoint due) {
    if (!held_.empty() && held_.back().due > due) due = held_.back().due;
    held_.push_back({due, frame});
  }
  /// Calls `fn(frame)` for each frame due at or before `now`, in order, and forgets it.
  template <class Fn>
  void release(TimePoint now, Fn&& fn) {
    while (!held_.empty() && held_.front().due <= now) {
      fn(held_.front().frame);
      held_.pop_front();
    }
  }
  /// When the first held frame is due; nullopt when none is held.
  std::optional<TimePoint> next_due() const {
    return held_.empty() ? std::nullopt : std::optional(held_.front().due);
  }
  std::size_t size() const { return held_.size(); }
  void clear() { held_.clear(); }

 private:
  struct Held {
    TimePoint due;
    CanFrame frame;
  };
  std::deque<Held> held_;
};

/// A slow device: every frame the wrapped engine sends leaves `delay` after the call that
/// produced it, in the order produced (a frame never overtakes an earlier one, also when the
/// delay is changed in between). The wrapped engine itself runs undelayed: it sees frames and
/// time as they come, so its own timeouts run from the request, not from the delayed answer.
/// Events pass through at once.
template <Engine E>
class Delayed {
 public:
  using Event = typename E::Event;
  using Output = Outbox<Event>;

  /// Builds the wrapped engine from `args`. `delay` >= 0.
  template <class... Args>
  explicit Delayed(Duration delay, Args&&... args)
      : engine_(std::forward<Args>(args)...), delay_(delay) {}

  E& engine() { return engine_; }
  const E& engine() const { return engine_; }

  Duration delay() const { return delay_; }
  /// Applies to frames produced from now on; frames already held keep their due time.
  void set_delay(Duration delay) { delay_ = delay; }
  /// Frames produced but not yet released.
  std::size_t held() const { return held_.size(); }
  /// Drops the held frames (a power cycle loses what was not sent yet).
  void discard() { held_.clear(); }

  bool on_frame(const CanFrame& frame, TimePoint now, Output& out) {
    scratch_.clear();
    const bool mine = engine_.on_frame(frame, now, scratch_);
    hold(now, out);
    return mine;
  }
  void on_timer(TimePoint now, Output& out) {
    scratch_.clear();
    engine_.on_timer(now, scratch_);
    hold(now, out);
  }
  std::optional<TimePoint> next_deadline() const {
    return earliest(engine_.next_deadline(), held_.next_due());
  }

  /// Runs an API call of the wrapped engine, `fn(engine(), now, out)`, with its frames delayed
  /// like all others; returns what fn returns.
  template <class Fn>
  decltype(auto) apply(TimePoint now, Output& out, Fn&& fn) {
    struct Hold {
      Delayed* self;
      TimePoint now;
      Output* out;
      ~Hold() { self->hold(now, *out); }
    };
    scratch_.clear();
    Hold on_exit{this, now, &out};
    return std::forward<Fn>(fn)(engine_, now, scratch_);
  }

 private:
  // Queues what the wrapped engine produced and releases what is due.
  void hold(TimePoint now, Output& out) {
    for (const auto& frame : scratch_.frames) held_.hold(frame, now + delay_);
    for (auto& event : scratch_.events) out.report(std::move(event));
    scratch_.clear();
    held_.release(now, [&out](const CanFrame& frame) { out.send(frame); });
  }

  E engine_;
  Duration delay_;
  HeldFrames held_;
  Output scratch_;
};

// --- faults of a slave node ---------------------------------------------------------------------

/// An SDO abort the device answers for chosen objects instead of doing the access.
struct InjectedAbort {
  std::uint16_t index = 0;
  std::optional<std::uint8_t> sub_index;  ///< nullopt: every sub-index of `index`
  SdoAbort code = SdoAbort::General;
  bool on_read = true;
  bool on_write = true;
};

/// An emergency the device raises at a time (SlaveNode::raise_emergency, through its
/// EmcyProducer: 1014h, 1015h and the NMT state apply).
struct ScheduledEmergency {
  TimePoint at{};
  std::uint16_t error_code = 0;
  /// Bits set in 1001h with it (the generic bit follows any code but 0000h, CiA 301 §7.5.2.2).
  std::uint8_t error_register_bits = 0;
};

/// Faults a slave node can be given. All default to a well-behaved node.
struct DeviceFaults {
  /// The node is not on the bus at all: no boot-up, no answers, no heartbeat.
  bool absent = false;
  /// Initialisation takes this long: the boot-up message follows power-on or an NMT reset
  /// after this delay (late boot).
  Duration boot_delay{0};
  /// Wrong identity: these values replace 1000h and 1018h sub 1-4 after every reset (the entry
  /// is added when the device file lacks it).
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  std::optional<std::uint32_t> revision_number;
  std::optional<std::uint32_t> serial_number;
  /// SDO accesses answered with an abort (checked after the dictionary's own checks, before
  /// the node's).
  std::vector<InjectedAbort> sdo_aborts;
  /// Every SDO response leaves this long after its request (slow device). The node's SDO
  /// server timeout is lengthened by as much, so that it still runs from the response.
  Duration sdo_latency{0};
  /// Each frame the node receives, and each it sends, is lost with this probability (0..1),
  /// drawn from a PRNG seeded with `loss_seed`. For loss on the whole bus use
  /// SimBus::set_loss_rate.
  double frame_loss_rate = 0.0;
  std::uint64_t loss_seed = 1;
  /// The node power-cycles when it receives its Nth SDO request frame (N >= 1, counted from
  /// construction or set_faults()), without answering it: a reboot in the middle of a
  /// configuration or program download. Fires once.
  std::optional<std::uint32_t> reboot_at_sdo_request;
  /// From this time on no heartbeat is produced (the node otherwise keeps working).
  std::optional<TimePoint> heartbeat_stops_at;
  /// Node guarding requests (RTR) are never answered.
  bool ignore_guarding = false;
  /// Emergencies raised at their times, in time order (each once; one due while the node is
  /// initialising or absent is dropped, as SlaveNode drops it).
  std::vector<ScheduledEmergency> emergencies;
};

/// A SlaveNode with faults: an nmt::Engine reporting the node's events, plus a Fault event when
/// a reboot is injected. Owns the node. Movable (the dictionary hooks it adds refer to state
/// on the heap).
class FaultInjectedSlave {
 public:
  using Event = SlaveEvent;
  using Output = Outbox<Event>;

  /// `node` must not be null.
  explicit FaultInjectedSlave(std::unique_ptr<SlaveNode> node, DeviceFaults faults = {});
  FaultInjectedSlave(FaultInjectedSlave&&) noexcept;
  FaultInjectedSlave& operator=(FaultInjectedSlave&&) noexcept;
  ~FaultInjectedSlave();

  // --- engine (nmt/engine.hpp) ---------------------------------------------------------------
  /// Power-on (or power cycle) at `now`; the boot-up follows after faults().boot_delay.
  void start(TimePoint now, Output& out);
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;
  /// SlaveNode::raise_emergency through the faults (nothing while absent; loss applies).
  void raise_emergency(std::uint16_t error_code, std::uint8_t error_register_bits, TimePoint now,
                       Output& out);

  // --- the node and its faults --------------------------------------------------------------
  /// The node, to observe it (state, dictionary, stored values, programs) and drive its API.
  SlaveNode& node() { return *node_; }
  const SlaveNode& node() const { return *node_; }
  /// The node's options as given (the SDO server timeout without the latency fault's share).
  const SlaveNodeOptions& options() const;
  /// SlaveNode::set_options, keeping the latency fault's share of the SDO server timeout.
  void set_options(SlaveNodeOptions options);

  const DeviceFaults& faults() const;
  /// Replaces the faults. Latency, loss, guarding and heartbeat faults take effect at once (a
  /// response waiting out the old latency is dropped), identity and boot delay at the next
  /// reset; after changing `absent`, start() again.
  void set_faults(DeviceFaults faults);
  /// SDO request frames received since construction or set_faults().
  std::uint64_t sdo_requests() const;

 private:
  struct State;
  void after_reset(TimePoint now);
  void apply_identity();
  void apply_sdo_timeout();
  void pass(Output& inner, bool drop_heartbeat, TimePoint now, Output& out);
  void release_sdo_responses(TimePoint now, Output& out);

  std::unique_ptr<SlaveNode> node_;
  std::unique_ptr<State> state_;
};
static_assert(Engine<FaultInjectedSlave>);

}  // namespace nmt
