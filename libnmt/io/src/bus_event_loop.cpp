#include "nmt/bus_event_loop.hpp"

#include <algorithm>
#include <chrono>

namespace nmt {

TimePoint steady_now() {
  return std::chrono::duration_cast<TimePoint>(std::chrono::steady_clock::now().time_since_epoch());
}

BusEventLoop::BusEventLoop(Bus& bus, BusEventLoopOptions options, Clock clock)
    : bus_(&bus), options_(options), clock_(std::move(clock)) {}

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
  auto s = send_and_echo(&from, frames, now);
  if (!s && !failed_) failed_ = s.error();
  return s;
}

cfg::Status BusEventLoop::fire_timers(TimePoint now) {
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

cfg::Status BusEventLoop::run_until(TimePoint until) {
  if (failed_) {
    cfg::Error e = std::move(*failed_);
    failed_.reset();
    return e;
  }
  while (!stop_requested()) {
    TimePoint now = clock_();
    if (now >= until) break;
    if (auto s = fire_timers(now); !s) return s;
    if (stop_requested()) break;

    now = clock_();
    Duration wait = options_.max_wait;
    if (auto d = next_deadline()) wait = std::min(wait, std::max(Duration::zero(), *d - now));
    if (until != TimePoint::max()) wait = std::min(wait, std::max(Duration::zero(), until - now));

    auto received = bus_->receive(wait);
    if (!received) {
      return cfg::Error{"cannot receive on " + bus_->url() + ": " + received.error().message};
    }
    if (!received->has_value()) continue;
    now = clock_();
    const CanFrame& frame = received->value().frame;
    ++received_;
    if (observer_) observer_(frame, now, Direction::Received);
    if (auto s = deliver(frame, nullptr, now); !s) return s;
  }
  return {};
}

}  // namespace nmt
