// The real-time event loop that drives nmt::Engine objects (nmt/engine.hpp) over an nmt::Bus
// (SocketCAN, UDP multicast): it waits for frames up to the engines' next deadline, feeds
// received frames and due timers to the engines and sends what they answer. The engines are
// the same objects that run on the simulated bus; only this loop knows about clocks and
// sockets. EngineRef<E> is the one adapter from any engine to the loop.
//
// Time. Engines judge by when frames arrived, not by when the loop got round to reading them
// (a timeout must not fire because the process was stopped): a received frame is given to the
// engines at its receive stamp (ReceivedFrame: the kernel's, for the SocketCAN and UDP drivers),
// moved onto the loop's clock by arrival_on_loop_clock(). Frames and timers are merged on that one
// time line: for each frame still queued in the socket, in arrival order, the timers due at or
// before its stamp fire first (at the stamp), then the frame is delivered; only when the queue is
// empty do the timers due up to now fire. So after a stall of the process (a scheduler hiccup,
// SIGSTOP, a debugger) a heartbeat that arrived in time counts as in time, and a real loss (no
// frame before the deadline) is still seen. The time given to engines never goes back (engine.hpp
// rule 1).
//
// Transmit: the path survives a real controller. Frames the engines send
// join one ordered transmit queue and go out in that order. A full transmit queue (ENOBUFS,
// EAGAIN) is back-pressure: the frame stays first in the queue and is retried after a short
// backoff while the loop keeps receiving and firing timers; nothing is dropped, the loop goes
// on. Another send failure is reported (BusEvent::SendFailed, counted) and retried with a longer
// backoff. A frame the driver can never send (invalid for it) is reported and dropped. Only an
// interface that vanished or went down (ENODEV, ENXIO, ENETDOWN) ends run*(), with a message
// saying so. CAN error frames are not delivered to the engines (they are the controller's
// reports, not CANopen messages); they are counted (BusCounters) and reported (BusEvent). On
// bus-off the loop stops sending until an error frame says the controller is back (restarted,
// or error active), then sends the queue in order. The rule for time during bus-off: the
// engines' clock stands still. The controller neither sends nor receives then, so no engine
// can have seen or missed anything: a heartbeat consumer's timer, an SDO timeout or a boot
// timer is not charged with the bus-off time, and the engines' time goes on from where it
// stopped (now() is the loop's clock less the bus-off time). run_until() keeps to the clock
// itself, so a bounded run ends during a bus-off too.
//
// Threads. The loop and its engines belong to the thread that
// runs it. Another thread (a UI, an RPC server) calls into them with post(fn): fn is queued
// under a mutex and the loop is woken (an eventfd it waits on together with the bus's
// descriptor, Bus::readable_fd()); it runs fn on its own thread between two engine calls, at the
// start of its next pass, in the order the functions were posted. fn reaches an engine with
// EngineRef::apply (the engine's `now` and Output, frames sent at once), or directly
// EngineRef::post(fn), which does both.
#pragma once

#include <algorithm>
#include <atomic>
#include <concepts>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

class BusEventLoop;

/// An engine as the loop sees it, with its event type erased. Implemented by EngineRef; the
/// loop calls these in this order for each frame or timer: on_frame/on_timer, sends the frames,
/// then report_events.
class LoopEngine {
 public:
  LoopEngine() = default;
  LoopEngine(const LoopEngine&) = delete;
  LoopEngine& operator=(const LoopEngine&) = delete;
  virtual ~LoopEngine() = default;
  /// A frame from the bus (or from another engine of the loop) at `now`; frames to send are
  /// appended to `frames`. True when it was addressed to the engine.
  virtual bool on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& frames) = 0;
  /// Called when now >= next_deadline().
  virtual void on_timer(TimePoint now, std::vector<CanFrame>& frames) = 0;
  virtual std::optional<TimePoint> next_deadline() const = 0;
  /// Hands the events of the last call to the application.
  virtual void report_events(TimePoint now) = 0;

 protected:
  /// The loop this engine was added to (nullptr before BusEventLoop::add).
  BusEventLoop* loop() const { return loop_; }

 private:
  friend class BusEventLoop;
  BusEventLoop* loop_ = nullptr;
};

/// The event-loop driver of any nmt::Engine, without owning it (the engine must outlive the
/// adapter, the adapter the loop's use of it). Events go to the handler (dropped when there is
/// none).
template <Engine E>
class EngineRef final : public LoopEngine {
 public:
  using Event = typename E::Event;
  using Output = typename E::Output;
  /// Called with each event and the loop's time, after the frames of the same call were sent.
  /// It may use apply().
  using EventHandler = std::function<void(const Event&, TimePoint)>;

  explicit EngineRef(E& engine, EventHandler handler = {})
      : engine_(&engine), handler_(std::move(handler)) {}
  E& engine() { return *engine_; }
  void set_event_handler(EventHandler handler) { handler_ = std::move(handler); }

  /// Runs an API call of the engine, `fn(engine(), now, out)` at the loop's time, and sends the
  /// frames it put into `out` at once (the loop's other engines see them too), then reports its
  /// events. Returns what fn returns. The engine must have been added to a loop (else
  /// std::logic_error); a frame the bus refuses makes the loop's next run*() return that error.
  /// An exception of fn or of the handler reaches the caller (fn's frames and events are
  /// delivered first).
  template <class Fn>
  std::invoke_result_t<Fn, E&, TimePoint, typename E::Output&> apply(Fn&& fn);
  /// Thread-safe: BusEventLoop::post() of apply(fn), for another thread (a UI, an RPC server)
  /// that calls into the engine while the loop runs; fn's result is dropped (hand it back
  /// through a std::promise or a queue of the caller's). The EngineRef must have been added to
  /// a loop before (else std::logic_error) and outlive the posted call.
  template <class Fn>
  void post(Fn fn);

  bool on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& frames) override {
    const bool mine = engine_->on_frame(frame, now, out_);
    take_frames(frames);
    return mine;
  }
  void on_timer(TimePoint now, std::vector<CanFrame>& frames) override {
    engine_->on_timer(now, out_);
    take_frames(frames);
  }
  std::optional<TimePoint> next_deadline() const override { return engine_->next_deadline(); }
  void report_events(TimePoint now) override { report(out_, now); }

 private:
  void take_frames(std::vector<CanFrame>& frames) {
    frames.insert(frames.end(), out_.frames.begin(), out_.frames.end());
    out_.frames.clear();
  }
  void report(Output& out, TimePoint now) {
    if (out.events.empty()) return;
    auto events = std::move(out.events);  // the handler may call apply()
    out.events.clear();
    if (handler_) {
      for (const auto& e : events) handler_(e, now);
    }
  }
  E* engine_;
  EventHandler handler_;
  Output out_;
};

/// Microseconds of std::chrono::steady_clock, the loop's default clock.
TimePoint steady_now();

/// Where a received frame sits on the loop's clock. A StampClock::Realtime stamp keeps its age:
/// it is moved by the offset between the wall clock and the loop's clock, read together as
/// `realtime_now` and `loop_now` (a step of the wall clock between reception and this call
/// shifts it by that step, hence the clamp). A StampClock::Loop stamp is taken as it is. The
/// result is clamped into [not_before, loop_now]: a frame cannot have arrived after the loop
/// read it, and the time given to engines never goes back (`not_before`, the last time given,
/// wins when the two disagree).
TimePoint arrival_on_loop_clock(const ReceivedFrame& received, TimePoint loop_now,
                                TimePoint realtime_now, TimePoint not_before);

/// What the loop reports about the bus itself (BusEventLoop::set_bus_event_handler): sends it
/// retries, frames it cannot send, and the CAN controller's state from error frames (the
/// CAN_ERR_* classes of linux/can/error.h, as SocketCanBus delivers them and the UDP bus
/// carries them).
struct BusEvent {
  enum class Kind : std::uint8_t {
    SendFailed,          ///< a send failed (not a full queue); the frame is retried (text: why)
    FrameRefused,        ///< the driver can never send `frame`: it is dropped (text: why)
    ErrorWarning,        ///< the controller's error counters reached the warning level
    ErrorPassive,        ///< the controller is error passive
    BusOff,              ///< the controller is bus-off: the loop stops sending
    Restarted,           ///< the controller is back (restarted, or error active): sending resumes
    LostArbitration,     ///< a frame of ours lost arbitration (the controller retransmits it)
    ControllerOverflow,  ///< the controller's receive or transmit buffer overflowed
    BusError,  ///< a protocol violation, missing ACK, transceiver problem or transmit timeout
  };
  Kind kind;
  std::string text;
  CanFrame frame;  ///< the frame not sent (SendFailed, FrameRefused) or the error frame
};
std::string_view to_string(BusEvent::Kind kind);

/// Counters of the loop's transmit path and of the error frames it read.
struct BusCounters {
  std::uint64_t queue_full = 0;     ///< send attempts that met a full transmit queue (retried)
  std::uint64_t send_failures = 0;  ///< other failed attempts (reported, retried)
  std::uint64_t refused = 0;        ///< frames the driver can never send (reported, dropped)
  std::size_t queued = 0;           ///< frames waiting in the loop's transmit queue now
  std::size_t max_queued = 0;       ///< the most that ever waited there
  std::uint64_t error_frames = 0;   ///< CAN error frames read (each counted below by class)
  std::uint64_t error_warning = 0;
  std::uint64_t error_passive = 0;
  std::uint64_t bus_off = 0;
  std::uint64_t restarted = 0;
  std::uint64_t lost_arbitration = 0;
  std::uint64_t controller_overflows = 0;
  std::uint64_t bus_errors = 0;
  Duration bus_off_time{0};  ///< time spent in bus-off (periods that ended)
};

struct BusEventLoopOptions {
  /// Longest single wait for a frame, so that a stop request is noticed within this time.
  Duration max_wait = std::chrono::milliseconds(100);
  /// Most frames read from the queue in one pass before the loop checks for the end of
  /// run_until() and retries its transmit queue again (a stop request ends a pass at once). Timers
  /// cannot starve under a flood whatever this is: each frame is preceded by the timers due by its
  /// stamp. What a flood the process cannot keep up with does delay is the time: engines are then
  /// given the arrival times of frames that waited in the socket, at most the receive buffer's
  /// worth behind the clock (beyond that the kernel drops frames:
  /// SocketCanBus::receive_overflows()). The timers due after the last of them fire once the queue
  /// is empty.
  std::size_t max_frames_per_pass = 1024;
  /// Deliver every frame an engine sends to the loop's other engines as well: on a CAN bus
  /// every node hears every frame, but drivers do not hand our own frames back to us.
  bool local_echo = true;
  /// Retry delays of the transmit queue: after a full transmit queue from `queue_full_retry`
  /// doubling up to 2 ms (ENOBUFS does not wake poll(): measured, socketcan_bus.cpp); after
  /// another send failure from `send_failure_retry` doubling up to 1 s.
  Duration queue_full_retry = std::chrono::microseconds(50);
  Duration send_failure_retry = std::chrono::milliseconds(10);
};

/// Drives engines over one bus. Not thread-safe, except post() and request_stop(). Owns neither
/// the bus nor the engines; both must outlive the loop's use of them.
class BusEventLoop {
 public:
  /// A function post() runs on the loop's thread: any callable of no arguments, move-only ones
  /// too (a lambda that owns a std::promise).
  class Task {
   public:
    template <class F>
    requires std::invocable<F&> &&(!std::same_as<std::decay_t<F>, Task>)
        Task(F fn)  // NOLINT(google-explicit-constructor): post([..] { .. })
        : fn_(std::make_unique<Holder<F>>(std::move(fn))) {}
    void operator()() { fn_->run(); }

   private:
    struct Callable {
      virtual ~Callable() = default;
      virtual void run() = 0;
    };
    template <class F>
    struct Holder final : Callable {
      explicit Holder(F f) : fn(std::move(f)) {}
      void run() override { (void)fn(); }
      F fn;
    };
    std::unique_ptr<Callable> fn_;
  };
  using Clock = std::function<TimePoint()>;
  enum class Direction { Received, Sent };
  /// Sees every frame received from the bus (at its arrival time) and every frame sent to it
  /// (at the time of the engine call that sent it), as engines see them.
  using Observer = std::function<void(const CanFrame&, TimePoint, Direction)>;

  explicit BusEventLoop(Bus& bus, BusEventLoopOptions options = {}, Clock clock = steady_now);
  BusEventLoop(const BusEventLoop&) = delete;
  BusEventLoop& operator=(const BusEventLoop&) = delete;
  ~BusEventLoop();

  /// Adds an engine; it sees frames and timers from the next loop iteration on.
  void add(LoopEngine& engine) {
    engine.loop_ = this;
    engines_.push_back(&engine);
  }
  void set_observer(Observer observer) { observer_ = std::move(observer); }
  using BusEventHandler = std::function<void(const BusEvent&, TimePoint)>;
  /// Sees send failures, refused frames and the controller's state changes (BusEvent).
  void set_bus_event_handler(BusEventHandler handler) { bus_event_handler_ = std::move(handler); }
  /// The time engines are given: inside a callback of the loop (an event handler, the
  /// observer, EngineRef::apply from either) the time of the frame or timer being handled,
  /// else the loop's clock less the time spent in bus-off (see "Transmit" above).
  TimePoint now() const;
  /// The loop's clock itself (bus-off time included): what run_until() keeps to.
  TimePoint clock() const { return clock_(); }

  /// Runs until the loop's clock (the Clock itself, bus-off time included) reaches `until`,
  /// request_stop() is called, or the bus fails: a receive error, or the interface is gone
  /// (a send found it vanished or down: the error says so). Each pass first reads every frame
  /// already queued (see "Time" above), so a stall of the caller between two run*() calls is
  /// no different from one inside.
  cfg::Status run_until(TimePoint until);
  cfg::Status run_for(Duration duration) { return run_until(clock_() + duration); }
  /// Runs until request_stop() or a bus failure.
  cfg::Status run() { return run_until(TimePoint::max()); }
  /// Runs (receiving, firing timers) until the transmit queue is empty, at most `limit`, or
  /// as run_until() ends. Frames still queued when the loop is destroyed are never sent, so a
  /// program calls this before it ends, after its last run (clear_stop() first if it requested
  /// the stop itself).
  cfg::Status run_until_sent(Duration limit);
  /// Makes run*() return within options.max_wait. Async-signal-safe (a lock-free atomic
  /// store), so a SIGINT handler may call it. The request stays until clear_stop().
  void request_stop() { stop_.store(true, std::memory_order_relaxed); }
  /// Thread-safe: queues `fn` to run on the thread that runs the loop, between two engine calls
  /// (at the start of the loop's next pass, after the frames and timers of the current one), and
  /// wakes the loop. Functions run once each, in the order they were posted (so in each thread's
  /// order); one posted from inside a posted function runs in the next pass. Functions posted
  /// while no run*() is running wait for the next one. An exception fn throws leaves run*()
  /// (the functions after it stay queued). Inside fn the loop is the caller's to use:
  /// EngineRef::apply, request_stop(), counters(). Not async-signal-safe (it locks a mutex).
  void post(Task fn);
  /// Functions posted and not yet run.
  std::size_t posted() const;
  void clear_stop() { stop_.store(false, std::memory_order_relaxed); }
  bool stop_requested() const { return stop_.load(std::memory_order_relaxed); }

  std::uint64_t frames_received() const { return received_; }
  /// Frames the bus took (the transmit queue's frames are not yet counted).
  std::uint64_t frames_sent() const { return sent_; }
  BusCounters counters() const;
  /// Whether the last error frame said bus-off (and none since said the controller is back).
  bool bus_off() const { return bus_off_since_.has_value(); }

  /// Sends frames `from` produced outside a loop callback (EngineRef::apply) at once (queued
  /// behind earlier ones, see "Transmit") and delivers them to the loop's other engines. Fails
  /// only when the interface is gone; that failure is also kept for the next run*().
  cfg::Status send_now(LoopEngine& from, std::vector<CanFrame>& frames, TimePoint now);

 private:
  struct Pending {
    CanFrame frame;
    LoopEngine* from;  // nullptr: received from the bus
  };
  cfg::Status fire_timers(TimePoint now);
  cfg::Status handle_received(const ReceivedFrame& received);
  /// Records `now` as the time given to engines; returns it, never less than the last one.
  TimePoint give(TimePoint now);
  cfg::Status deliver(const CanFrame& frame, LoopEngine* from, TimePoint now);
  cfg::Status emit(std::vector<CanFrame>& out, LoopEngine* from, TimePoint now);
  cfg::Status send_and_echo(LoopEngine* from, std::vector<CanFrame>& frames, TimePoint now);
  std::optional<TimePoint> next_deadline() const;
  /// Sends what the transmit queue holds, in order, until the bus pushes back.
  cfg::Status flush_transmit(TimePoint now);
  void handle_error_frame(const CanFrame& frame, TimePoint now);
  void report(BusEvent::Kind kind, std::string text, const CanFrame& frame, TimePoint now);
  /// The engines' time at the loop's clock reading `clock`: bus-off time is cut out.
  TimePoint engine_time(TimePoint clock) const;
  /// Runs the posted functions queued now (post()).
  void run_posted();
  /// Waits up to `wait` for a frame: on the bus's descriptor and the wake-up eventfd together
  /// when the bus has one (else in Bus::receive). nullopt also when woken by post().
  cfg::Result<std::optional<ReceivedFrame>> wait_for_frame(Duration wait);

  Bus* bus_;
  BusEventLoopOptions options_;
  Clock clock_;
  std::vector<LoopEngine*> engines_;
  Observer observer_;
  std::atomic<bool> stop_{false};
  static_assert(std::atomic<bool>::is_always_lock_free);
  std::vector<Pending> pending_;
  std::uint64_t received_ = 0;
  std::uint64_t sent_ = 0;
  bool delivering_ = false;                  // inside deliver(): pending_ is being worked through
  bool in_callback_ = false;                 // inside an engine call, handler or observer
  TimePoint last_given_ = TimePoint::min();  // the latest time given to an engine
  std::optional<cfg::Error> failed_;         // a send_now failure for the next run*()
  BusEventHandler bus_event_handler_;
  std::deque<CanFrame> transmit_;      // frames not yet taken by the bus, in order
  bool flushing_ = false;              // inside flush_transmit()
  bool until_sent_ = false;            // inside run_until_sent(): end once transmit_ is empty
  std::optional<TimePoint> retry_at_;  // the clock reading before which no send is tried
  Duration retry_delay_{0};
  BusCounters counters_;
  std::optional<TimePoint> bus_off_since_;  // the clock reading when bus-off began
  Duration paused_{0};                      // bus-off time of the periods that ended
  mutable std::mutex posted_mutex_;         // guards posted_
  std::deque<Task> posted_;                 // post()ed functions not yet run, in order
  int wake_fd_ = -1;                        // eventfd post() writes; -1: none could be made
};

template <Engine E>
template <class Fn>
std::invoke_result_t<Fn, E&, TimePoint, typename E::Output&> EngineRef<E>::apply(Fn&& fn) {
  if (loop() == nullptr) throw std::logic_error("EngineRef::apply before BusEventLoop::add");
  Output out;
  const TimePoint now = loop()->now();
  return call_then_flush(
      [&]() -> decltype(auto) { return std::forward<Fn>(fn)(*engine_, now, out); },
      [&] {
        (void)loop()->send_now(*this, out.frames, now);
        report(out, now);
      });
}

template <Engine E>
template <class Fn>
void EngineRef<E>::post(Fn fn) {
  if (loop() == nullptr) throw std::logic_error("EngineRef::post before BusEventLoop::add");
  loop()->post([this, fn = std::move(fn)]() mutable { (void)apply(fn); });
}

}  // namespace nmt
