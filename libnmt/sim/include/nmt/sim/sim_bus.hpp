// A simulated CAN bus on simulated time: a discrete-event scheduler plus a bus model that gives
// every frame its real length on the wire (ISO 11898-1 fields and stuff bits) and arbitrates by
// identifier. Protocol engines run on it thousands of times faster than real time, with
// deterministic fault injection (frame loss, per-frame drop/delay).
//
// How a node takes part:
//   class MyNode : public nmt::SimNode {
//     void on_frame(const CanFrame& f, TimePoint now) override { ... send(reply); }
//     void on_timer(TimePoint now) override { ... set_timer(now + 10ms); }
//   };
//   nmt::SimBus bus(500'000);
//   MyNode a, b;
//   bus.attach(a);
//   bus.attach(b);
//   bus.run_for(std::chrono::seconds(1));
// Any nmt::Engine (nmt/engine.hpp) runs unchanged inside SimEngineNode<E> (bottom of this file).
//
// Timing model. Time starts at 0. A frame sent while the bus is idle starts at the current time
// after all other events of that instant ran (so nodes sending "at once" arbitrate). It is
// delivered to every attached node except its sender at the end of its EOF field, and the bus
// is free again after the 3-bit intermission; then the queued frames arbitrate again: the frame
// whose arbitration field is lowest wins (11-bit base id first; at equal base id a standard data
// frame beats an extended one because SRR is recessive, a standard remote frame beats an
// extended one because IDE is recessive; data beats remote at equal id). Losers stay queued and
// retry when the bus is free. Each node's queue is FIFO (like a SocketCAN queue): only its oldest
// frame competes. Nodes react in zero simulated time; model processing time with set_timer().
// Not thread-safe. Internally time is kept in nanoseconds so bit times at any bit rate add up
// exactly; the TimePoint (microsecond) view is rounded down.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <queue>
#include <random>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/protocol/frame_bits.hpp"

namespace nmt {

class SimBus;

/// The arbitration priority of a frame: lower wins. Compares as the bits of the arbitration
/// field (base id, SRR/RTR, IDE, extended id, RTR) would on the wire.
std::uint64_t arbitration_key(const CanFrame& frame);

/// A participant on the simulated bus. Attach it with SimBus::attach; it must stay alive while
/// attached (its destructor detaches it). Not copyable or movable: the bus holds its address.
class SimNode {
 public:
  SimNode() = default;
  SimNode(const SimNode&) = delete;
  SimNode& operator=(const SimNode&) = delete;
  virtual ~SimNode();

  /// A frame sent by another node finished (end of EOF) at `now`.
  virtual void on_frame(const CanFrame& frame, TimePoint now) = 0;
  /// The deadline set with set_timer() came. The timer is cleared before the call.
  virtual void on_timer(TimePoint now) = 0;

  /// The bus this node is attached to, or nullptr.
  SimBus* bus() const { return bus_; }

 protected:
  /// Queues a frame for transmission (FIFO per node). Ignored when not attached.
  void send(const CanFrame& frame);
  /// Asks for on_timer() at `deadline` (replacing any earlier request); a deadline in the past
  /// fires at the current time; nullopt cancels. Ignored when not attached.
  void set_timer(std::optional<TimePoint> deadline);
  /// Current simulated time (0 when not attached).
  TimePoint now() const;

 private:
  friend class SimBus;
  SimBus* bus_ = nullptr;
  std::size_t slot_ = 0;
};

/// What the fault filter decides for one frame.
struct FrameFate {
  enum class Kind { Deliver, Drop, Delay };
  Kind kind = Kind::Deliver;
  Duration delay{0};  ///< Delay: delivered this much after its end of frame

  static FrameFate deliver() { return {}; }
  static FrameFate drop() { return {Kind::Drop, Duration{0}}; }
  static FrameFate delayed(Duration d) { return {Kind::Delay, d}; }
};

/// Counters since construction or reset_statistics().
struct SimBusStats {
  std::uint64_t frames = 0;          ///< frames that completed transmission (dropped included)
  std::uint64_t frames_dropped = 0;  ///< lost by the loss rate or dropped by the filter
  std::uint64_t bits = 0;            ///< sum of FrameBits::total() of those frames
  std::int64_t busy_ns = 0;          ///< time the bus carried frames (intermission included)
  std::int64_t elapsed_ns = 0;       ///< simulated time covered
  /// busy / elapsed, 0..1 (0 when no time elapsed).
  double load() const {
    return elapsed_ns > 0 ? static_cast<double>(busy_ns) / static_cast<double>(elapsed_ns) : 0.0;
  }
};

/// The scheduler and the bus. Owns nothing it is given: nodes and callbacks' captures must
/// outlive their attachment.
class SimBus {
 public:
  using Observer = std::function<void(const CanFrame&, TimePoint)>;
  using Filter = std::function<FrameFate(const CanFrame&, TimePoint)>;

  /// A bus at `bitrate_bps` bit/s (1 ... 1e9; 0 is taken as 1).
  explicit SimBus(std::uint32_t bitrate_bps = 1'000'000);
  ~SimBus();
  SimBus(const SimBus&) = delete;
  SimBus& operator=(const SimBus&) = delete;

  // --- nodes -----------------------------------------------------------------------------
  /// Attaches a node (no effect if already attached here; a node on another bus moves).
  void attach(SimNode& node);
  /// Detaches a node: its queued frames and timer are discarded; a frame it is transmitting
  /// completes. Safe to call from inside callbacks.
  void detach(SimNode& node);

  /// Same as SimNode::send / set_timer, for code holding the node.
  void send(SimNode& node, const CanFrame& frame);
  void set_timer(SimNode& node, std::optional<TimePoint> deadline);

  /// Runs `fn(now)` at `at` (or now, if in the past), after timers already due then.
  void schedule_at(TimePoint at, std::function<void(TimePoint)> fn);

  /// Observers see every frame receivers see (after the fault filter), at its delivery time.
  /// Returns a handle for remove_observer.
  std::size_t add_observer(Observer observer);
  void remove_observer(std::size_t handle);

  // --- fault injection ---------------------------------------------------------------------
  /// Each frame is lost (occupies the bus, reaches nobody) with probability `rate` (0..1),
  /// drawn from a PRNG seeded with `seed`: the same seed gives the same losses.
  void set_loss_rate(double rate, std::uint64_t seed = 1);
  /// Decides per frame (at its end of frame) to deliver, drop or delay it; applied after the
  /// loss rate. Pass {} to remove.
  void set_filter(Filter filter) { filter_ = std::move(filter); }

  // --- running -----------------------------------------------------------------------------
  TimePoint now() const { return TimePoint{Duration{now_ns_ / 1000}}; }
  std::int64_t now_ns() const { return now_ns_; }
  std::uint32_t bitrate_bps() const { return bitrate_bps_; }
  /// Duration of `bits` bit times, in nanoseconds.
  std::int64_t bits_to_ns(std::uint64_t bits) const;

  /// Processes every event up to and including `t`, then sets the time to `t` (never back).
  void run_until(TimePoint t);
  void run_for(Duration d) { run_until(now() + d); }
  /// Processes events until none is left or the next one is after `limit`. True when idle
  /// (no timer, no scheduled call, no frame queued or on the bus).
  bool run_until_idle(TimePoint limit = TimePoint::max());
  /// Processes events one at a time until `done()` is true (checked before each event) or the
  /// next event is after `limit` / none is left. True when `done()` became true.
  bool run_until(const std::function<bool()>& done, TimePoint limit = TimePoint::max());
  /// Processes the earliest event. False when there is none.
  bool step();
  /// True when nothing is scheduled: no timer, no call, no frame queued or on the bus.
  bool idle() const { return live_events_ == 0; }
  /// Frames `node` sent that have not completed transmission yet, the one on the wire
  /// included (0 for a node not attached here): e.g. to let a node's last frames reach the bus
  /// before a run ends.
  std::size_t frames_queued(const SimNode& node) const;

  // --- statistics ----------------------------------------------------------------------------
  SimBusStats statistics() const;
  void reset_statistics();
  /// Events processed since construction (timers, deliveries, arbitrations, calls).
  std::uint64_t events_processed() const { return events_processed_; }

 private:
  friend class SimNode;
  enum class EventKind : std::uint8_t { Timer, Call, EndOfFrame, Arbitrate, DelayedDelivery };
  struct Event {
    std::int64_t at_ns;
    std::uint8_t phase;  // 0: timers, calls, deliveries; 1: arbitration after them
    std::uint64_t seq;
    EventKind kind;
    std::size_t slot;          // Timer: node slot; Call/DelayedDelivery: payload slot
    std::uint64_t generation;  // Timer: matches Slot::timer_generation when still valid
    bool operator>(const Event& o) const {
      if (at_ns != o.at_ns) return at_ns > o.at_ns;
      if (phase != o.phase) return phase > o.phase;
      return seq > o.seq;
    }
  };
  struct Slot {
    SimNode* node = nullptr;
    std::vector<CanFrame> queue;  // FIFO, front at queue_head
    std::size_t queue_head = 0;
    std::uint64_t timer_generation = 0;
    bool timer_armed = false;
  };
  struct Delayed {
    CanFrame frame;
    std::size_t sender;
  };

  void push(std::int64_t at_ns, std::uint8_t phase, EventKind kind, std::size_t slot = 0,
            std::uint64_t generation = 0);
  void enqueue_frame(std::size_t slot, const CanFrame& frame);
  void arm_timer(std::size_t slot, std::optional<TimePoint> deadline);
  void dispatch(const Event& e);
  void arbitrate();
  void end_of_frame();
  void deliver(const CanFrame& frame, std::size_t sender);
  void advance_to(std::int64_t t_ns);
  bool stale(const Event& e) const;
  void drop_stale();

  std::uint32_t bitrate_bps_;
  std::int64_t now_ns_ = 0;
  std::uint64_t seq_ = 0;
  std::uint64_t events_processed_ = 0;
  std::uint64_t live_events_ = 0;  // queued events that are not stale timers
  std::priority_queue<Event, std::vector<Event>, std::greater<>> events_;
  std::vector<Slot> slots_;
  std::vector<std::size_t> free_slots_;
  std::vector<std::pair<std::size_t, Observer>> observers_;
  std::size_t next_observer_ = 0;
  std::vector<std::function<void(TimePoint)>> calls_;
  std::vector<std::size_t> free_calls_;
  std::vector<std::optional<Delayed>> delayed_;
  std::vector<std::size_t> free_delayed_;
  Filter filter_;
  double loss_rate_ = 0.0;
  std::mt19937_64 rng_{1};

  // The frame on the wire.
  bool arbitration_pending_ = false;
  bool transmitting_ = false;
  CanFrame current_{};
  std::size_t current_sender_ = 0;
  std::int64_t current_start_ns_ = 0;
  FrameBits current_bits_{};

  SimBusStats stats_{};
  std::int64_t stats_start_ns_ = 0;
};

/// The simulated-bus driver of any nmt::Engine (nmt/engine.hpp): feeds it the bus's frames and
/// timers, sends what it produces at once, keeps the node's timer on the engine's
/// next_deadline() and hands its events to the event handler (dropped when there is none).
template <Engine E>
class SimEngineNode : public SimNode {
 public:
  using Event = typename E::Event;
  using Output = typename E::Output;
  /// Called with each event and the time of the call that produced it, after that call's
  /// frames were queued. It may use apply().
  using EventHandler = std::function<void(const Event&, TimePoint)>;

  /// Builds the engine from `args`.
  template <class... Args>
  explicit SimEngineNode(Args&&... args) : engine_(std::forward<Args>(args)...) {}

  E& engine() { return engine_; }
  const E& engine() const { return engine_; }
  void set_event_handler(EventHandler handler) { handler_ = std::move(handler); }

  /// Runs an API call of the engine, `fn(engine(), now, out)` at the bus's current time, then
  /// sends the frames it put into `out` at once, re-arms the timer and reports its events.
  /// Returns what fn returns. Attach the node first (unattached, frames are dropped). An
  /// exception of fn or of the handler reaches the caller (fn's frames and events are
  /// delivered first).
  template <class Fn>
  std::invoke_result_t<Fn, E&, TimePoint, Output&> apply(Fn&& fn) {
    // The outermost call reuses one Output; a nested one (from the event handler) its own.
    Output nested;
    Output& out = out_.frames.empty() && !in_handler_ ? out_ : nested;
    const TimePoint at = now();
    return call_then_flush(
        [&]() -> decltype(auto) { return std::forward<Fn>(fn)(engine_, at, out); },
        [&] { flush(out, at); });
  }

  void on_frame(const CanFrame& frame, TimePoint now) override {
    (void)engine_.on_frame(frame, now, out_);
    flush(out_, now);
  }
  void on_timer(TimePoint now) override {
    engine_.on_timer(now, out_);
    flush(out_, now);
  }

 private:
  void flush(Output& out, TimePoint now) {
    for (const auto& f : out.frames) send(f);
    out.frames.clear();
    set_timer(engine_.next_deadline());
    if (out.events.empty()) return;
    if (in_handler_) {
      // apply() from inside the handler: reported after the events being handed out.
      for (auto& e : out.events) deferred_.push_back(std::move(e));
      out.events.clear();
      return;
    }
    in_handler_ = true;
    pending_.swap(out.events);  // keeps both buffers' capacity
    try {
      while (!pending_.empty()) {
        for (const auto& e : pending_) {
          if (handler_) handler_(e, now);
        }
        pending_.clear();
        pending_.swap(deferred_);
      }
    } catch (...) {
      // The handler threw: the events after it are dropped, the next call reports afresh.
      pending_.clear();
      deferred_.clear();
      in_handler_ = false;
      throw;
    }
    in_handler_ = false;
  }
  E engine_;
  EventHandler handler_;
  Output out_;                   // reused by on_frame/on_timer and the outermost apply()
  std::vector<Event> pending_;   // events being handed to the handler
  std::vector<Event> deferred_;  // events of apply() calls the handler made
  bool in_handler_ = false;
};

/// A node made of callbacks, for tests and scripts. send()/set_timer() are public here.
class FunctionNode : public SimNode {
 public:
  using FrameFn = std::function<void(FunctionNode&, const CanFrame&, TimePoint)>;
  using TimerFn = std::function<void(FunctionNode&, TimePoint)>;
  explicit FunctionNode(FrameFn on_frame_fn = {}, TimerFn on_timer_fn = {})
      : on_frame_(std::move(on_frame_fn)), on_timer_(std::move(on_timer_fn)) {}

  void on_frame(const CanFrame& frame, TimePoint t) override {
    if (on_frame_) on_frame_(*this, frame, t);
  }
  void on_timer(TimePoint t) override {
    if (on_timer_) on_timer_(*this, t);
  }
  using SimNode::now;
  using SimNode::send;
  using SimNode::set_timer;

 private:
  FrameFn on_frame_;
  TimerFn on_timer_;
};

}  // namespace nmt
