// The real-time event loop that drives sans-I/O protocol engines over an nmt::Bus (SocketCAN,
// UDP multicast): it waits for frames up to the engines' next deadline, feeds received frames
// and due timers to the engines and sends what they answer. The engines are the same objects
// that run on the simulated bus (SimulatedDevice, SdoServer, SdoClient, ...); only this loop
// knows about clocks and sockets.
#pragma once

#include <atomic>
#include <functional>
#include <optional>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/bus.hpp"
#include "nmt/frame.hpp"

namespace nmt {

/// A sans-I/O engine as the loop sees it: the three calls every engine of this library has.
class LoopEngine {
 public:
  virtual ~LoopEngine() = default;
  /// A frame from the bus (or from another engine of the loop) at `now`; frames to send are
  /// appended to `out`.
  virtual void on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& out) = 0;
  /// Called when now >= next_deadline().
  virtual void on_timer(TimePoint now, std::vector<CanFrame>& out) = 0;
  virtual std::optional<TimePoint> next_deadline() const = 0;
};

/// Adapts an engine that has the three calls (SimulatedDevice, SdoClient, SdoServer, ...)
/// without owning it; the engine must outlive the adapter.
template <class Engine>
class EngineRef final : public LoopEngine {
 public:
  explicit EngineRef(Engine& engine) : engine_(&engine) {}
  void on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& out) override {
    (void)engine_->on_frame(frame, now, out);
  }
  void on_timer(TimePoint now, std::vector<CanFrame>& out) override { engine_->on_timer(now, out); }
  std::optional<TimePoint> next_deadline() const override { return engine_->next_deadline(); }
  Engine& engine() { return *engine_; }

 private:
  Engine* engine_;
};

/// Microseconds of std::chrono::steady_clock, the loop's default clock.
TimePoint steady_now();

struct BusEventLoopOptions {
  /// Longest single wait for a frame, so that a stop request is noticed within this time.
  Duration max_wait = std::chrono::milliseconds(100);
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
  /// Sees every frame received from the bus and every frame sent to it, with the loop's time.
  using Observer = std::function<void(const CanFrame&, TimePoint, Direction)>;

  explicit BusEventLoop(Bus& bus, BusEventLoopOptions options = {}, Clock clock = steady_now);

  /// Adds an engine; it sees frames and timers from the next loop iteration on.
  void add(LoopEngine& engine) { engines_.push_back(&engine); }
  void set_observer(Observer observer) { observer_ = std::move(observer); }
  /// The loop's clock (the time engines are given).
  TimePoint now() const { return clock_(); }

  /// Runs until the clock reaches `until`, request_stop() is called, or the bus fails (a
  /// receive error, or a frame that could not be sent: the error names the frame).
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

 private:
  struct Pending {
    CanFrame frame;
    LoopEngine* from;  // nullptr: received from the bus
  };
  cfg::Status fire_timers(TimePoint now);
  cfg::Status deliver(const CanFrame& frame, LoopEngine* from, TimePoint now);
  cfg::Status emit(std::vector<CanFrame>& out, LoopEngine* from, TimePoint now);
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
};

}  // namespace nmt
