#include "nmt/bus_event_loop.hpp"

#include <algorithm>
#include <chrono>

namespace nmt {

TimePoint steady_now() {
  return std::chrono::duration_cast<TimePoint>(std::chrono::steady_clock::now().time_since_epoch());
}

TimePoint arrival_on_loop_clock(const ReceivedFrame& received, TimePoint loop_now,
                                TimePoint realtime_now, TimePoint not_before) {
  TimePoint at = received.timestamp;
  if (received.clock == StampClock::Realtime) {
    // The frame's age on the wall clock is its age on ours: the kernel stamps with
    // CLOCK_REALTIME (socket(7), SO_TIMESTAMPNS), the loop runs on a monotonic clock.
    at = loop_now - std::max(Duration::zero(), realtime_now - received.timestamp);
  }
  return std::max(not_before, std::min(at, loop_now));
}

namespace {
// Marks the loop as inside a callback for now(), restoring the previous mark on exit.
class InCallback {
 public:
  explicit InCallback(bool& flag) : flag_(flag), was_(flag) { flag_ = true; }
  InCallback(const InCallback&) = delete;
  InCallback& operator=(const InCallback&) = delete;
  ~InCallback() { flag_ = was_; }

 private:
  bool& flag_;
  bool was_;
};
}  // namespace

BusEventLoop::BusEventLoop(Bus& bus, BusEventLoopOptions options, Clock clock)
    : bus_(&bus), options_(options), clock_(std::move(clock)) {}

TimePoint BusEventLoop::give(TimePoint now) {
  last_given_ = std::max(last_given_, now);
  return last_given_;
}

std::optional<TimePoint> BusEventLoop::next_deadline() const {
  std::optional<TimePoint> due;
  for (const LoopEngine* e : engines_) due = earliest(due, e->next_deadline());
  return due;
}

cfg::Status BusEventLoop::emit(std::vector<CanFrame>& out, LoopEngine* from, TimePoint now) {
  for (const auto& frame : out) {
    if (auto sent = bus_->send(frame); !sent) {
      return cfg::Error{"cannot send " + to_candump(frame) + " on " + bus_->url() + ": " +
                        sent.error().message};
    }
    ++sent_;
    if (observer_) observer_(frame, now, Direction::Sent);
    if (options_.local_echo && engines_.size() > 1) pending_.push_back({frame, from});
  }
  out.clear();
  return {};
}

cfg::Status BusEventLoop::deliver(const CanFrame& frame, LoopEngine* from, TimePoint now) {
  const InCallback in_callback(in_callback_);
  now = give(now);
  // Breadth-first: answers to this frame are delivered after every engine has seen it, as on
  // a bus where all nodes receive a frame at the same moment.
  pending_.push_back({frame, from});
  delivering_ = true;
  std::vector<CanFrame> out;
  cfg::Status status;
  for (std::size_t i = 0; i < pending_.size() && status; ++i) {
    const Pending p = pending_[i];
    for (LoopEngine* e : engines_) {
      if (e == p.from) continue;
      (void)e->on_frame(p.frame, now, out);
      status = emit(out, e, now);
      if (!status) break;
      e->report_events(now);
    }
  }
  delivering_ = false;
  pending_.clear();
  return status;
}

cfg::Status BusEventLoop::send_and_echo(LoopEngine* from, std::vector<CanFrame>& frames,
                                        TimePoint now) {
  // Inside deliver() the echoes join the frames it is working through.
  if (delivering_) return emit(frames, from, now);
  pending_.clear();
  if (auto s = emit(frames, from, now); !s) return s;
  // What this engine sent reaches the others now.
  std::vector<Pending> echoed;
  echoed.swap(pending_);
  for (const auto& p : echoed) {
    if (auto s = deliver(p.frame, p.from, now); !s) return s;
  }
  return {};
}

cfg::Status BusEventLoop::send_now(LoopEngine& from, std::vector<CanFrame>& frames, TimePoint now) {
  const InCallback in_callback(in_callback_);
  now = give(now);
  auto s = send_and_echo(&from, frames, now);
  if (!s && !failed_) failed_ = s.error();
  return s;
}

cfg::Status BusEventLoop::fire_timers(TimePoint now) {
  const InCallback in_callback(in_callback_);
  now = give(now);
  std::vector<CanFrame> out;
  // Each engine fires at most once per pass, so an engine whose deadline does not move cannot
  // starve the bus.
  for (LoopEngine* e : engines_) {
    auto d = e->next_deadline();
    if (!d || *d > now) continue;
    e->on_timer(now, out);
    auto s = send_and_echo(e, out, now);
    e->report_events(now);
    if (!s) return s;
  }
  return {};
}

cfg::Status BusEventLoop::handle_received(const ReceivedFrame& received) {
  const TimePoint at = arrival_on_loop_clock(received, clock_(), wall_clock_now(), last_given_);
  // One time line: what was due before the frame arrived happens first, at the frame's time
  // (the engines check their own due times, engine.hpp rule 3). A timer due at the very moment
  // of arrival fires first too: the frame came no earlier than the deadline.
  if (auto s = fire_timers(at); !s) return s;
  ++received_;
  if (observer_) {
    const InCallback in_callback(in_callback_);
    observer_(received.frame, at, Direction::Received);
  }
  return deliver(received.frame, nullptr, at);
}

cfg::Status BusEventLoop::run_until(TimePoint until) {
  if (failed_) {
    cfg::Error e = std::move(*failed_);
    failed_.reset();
    return e;
  }
  while (!stop_requested()) {
    // `now` is read before the queue is looked at: everything that arrived up to `now` is in
    // the queue by then, so once it is read out, the timers due up to `now` may fire. A stall
    // of the process anywhere in this pass leaves its frames in the queue for the next pass.
    const TimePoint now = clock_();
    if (now >= until) break;
    std::size_t read = 0;
    bool empty = false;
    while (read < options_.max_frames_per_pass && !stop_requested()) {
      auto received = bus_->receive(Duration::zero());
      if (!received) {
        return cfg::Error{"cannot receive on " + bus_->url() + ": " + received.error().message};
      }
      if (!received->has_value()) {
        empty = true;
        break;
      }
      ++read;
      if (auto s = handle_received(**received); !s) return s;
    }
    if (!empty) continue;  // more queued (or a stop request): check and read on
    if (auto s = fire_timers(now); !s) return s;
    if (stop_requested()) break;

    // Wait for the next frame, up to the engines' next deadline.
    const TimePoint t = clock_();
    if (t >= until) break;
    Duration wait = options_.max_wait;
    if (auto d = next_deadline()) wait = std::min(wait, std::max(Duration::zero(), *d - t));
    if (until != TimePoint::max()) wait = std::min(wait, until - t);
    if (wait <= Duration::zero()) continue;
    auto received = bus_->receive(wait);
    if (!received) {
      return cfg::Error{"cannot receive on " + bus_->url() + ": " + received.error().message};
    }
    if (received->has_value()) {
      if (auto s = handle_received(**received); !s) return s;
    }
  }
  return {};
}

}  // namespace nmt
