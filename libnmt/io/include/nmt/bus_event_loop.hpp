// The real-time event loop that drives nmt::Engine objects (nmt/engine.hpp) over an nmt::Bus
// (SocketCAN, UDP multicast): it waits for frames up to the engines' next deadline, feeds
// received frames and due timers to the engines and sends what they answer. The engines are
// the same objects that run on the simulated bus; only this loop knows about clocks and
// sockets. EngineRef<E> is the one adapter from any engine to the loop.
//
// Time. Engines judge by when frames arrived, not by when the loop got round to reading them
// (issue 22): a received frame is given to the engines at its receive stamp (ReceivedFrame:
// the kernel's, for the SocketCAN and UDP drivers), moved onto the loop's clock by
// arrival_on_loop_clock(). Frames and timers are merged on that one time line: for each frame
// still queued in the socket, in arrival order, the timers due at or before its stamp fire
// first (at the stamp), then the frame is delivered; only when the queue is empty do the timers
// due up to now fire. So after a stall of the process (a scheduler hiccup, SIGSTOP, a debugger)
// a heartbeat that arrived in time counts as in time, and a real loss (no frame before the
// deadline) is still seen. The time given to engines never goes back (engine.hpp rule 1).
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <stdexcept>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/bus.hpp"
#include "nmt/engine.hpp"
#include "nmt/frame.hpp"

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
  template <class Fn>
  decltype(auto) apply(Fn&& fn);

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

struct BusEventLoopOptions {
  /// Longest single wait for a frame, so that a stop request is noticed within this time.
  Duration max_wait = std::chrono::milliseconds(100);
  /// Most frames read from the queue in one pass before the loop checks for a stop request and
  /// for the end of run_until() again. Timers cannot starve under a flood whatever this is:
  /// each frame is preceded by the timers due by its stamp. What a flood the process cannot
  /// keep up with does delay is the time: engines are then given the arrival times of frames
  /// that waited in the socket, at most the receive buffer's worth behind the clock (beyond
  /// that the kernel drops frames: SocketCanBus::receive_overflows()). The timers due after the
  /// last of them fire once the queue is empty.
  std::size_t max_frames_per_pass = 1024;
  /// Deliver every frame an engine sends to the loop's other engines as well: on a CAN bus
  /// every node hears every frame, but drivers do not hand our own frames back to us.
  bool local_echo = true;
};

/// Drives engines over one bus. Not thread-safe, except request_stop(). Owns neither the bus
/// nor the engines; both must outlive the loop's use of them.
class BusEventLoop {
 public:
  using Clock = std::function<TimePoint()>;
  enum class Direction { Received, Sent };
  /// Sees every frame received from the bus (at its arrival time) and every frame sent to it
  /// (at the time of the engine call that sent it), as engines see them.
  using Observer = std::function<void(const CanFrame&, TimePoint, Direction)>;

  explicit BusEventLoop(Bus& bus, BusEventLoopOptions options = {}, Clock clock = steady_now);

  /// Adds an engine; it sees frames and timers from the next loop iteration on.
  void add(LoopEngine& engine) {
    engine.loop_ = this;
    engines_.push_back(&engine);
  }
  void set_observer(Observer observer) { observer_ = std::move(observer); }
  /// The time engines are given: inside a callback of the loop (an event handler, the
  /// observer, EngineRef::apply from either) the time of the frame or timer being handled,
  /// else the loop's clock.
  TimePoint now() const { return in_callback_ ? last_given_ : std::max(clock_(), last_given_); }

  /// Runs until the clock reaches `until`, request_stop() is called, or the bus fails (a
  /// receive error, or a frame that could not be sent: the error names the frame). Each pass
  /// first reads every frame already queued (see "Time" above), so a stall of the caller
  /// between two run*() calls is no different from one inside.
  cfg::Status run_until(TimePoint until);
  cfg::Status run_for(Duration duration) { return run_until(now() + duration); }
  /// Runs until request_stop() or a bus failure.
  cfg::Status run() { return run_until(TimePoint::max()); }
  /// Makes run*() return within options.max_wait. Async-signal-safe (a lock-free atomic
  /// store), so a SIGINT handler may call it. The request stays until clear_stop().
  void request_stop() { stop_.store(true, std::memory_order_relaxed); }
  void clear_stop() { stop_.store(false, std::memory_order_relaxed); }
  bool stop_requested() const { return stop_.load(std::memory_order_relaxed); }

  std::uint64_t frames_received() const { return received_; }
  std::uint64_t frames_sent() const { return sent_; }

  /// Sends frames `from` produced outside a loop callback (EngineRef::apply) at once and
  /// delivers them to the loop's other engines. A failure is also kept for the next run*().
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
};

template <Engine E>
template <class Fn>
decltype(auto) EngineRef<E>::apply(Fn&& fn) {
  if (loop() == nullptr) throw std::logic_error("EngineRef::apply before BusEventLoop::add");
  struct Flush {
    EngineRef* self;
    Output out;
    TimePoint now;
    ~Flush() {
      (void)self->loop()->send_now(*self, out.frames, now);
      self->report(out, now);
    }
  } flush_on_exit{this, {}, loop()->now()};
  return std::forward<Fn>(fn)(*engine_, flush_on_exit.now, flush_on_exit.out);
}

}  // namespace nmt
