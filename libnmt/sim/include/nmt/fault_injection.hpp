// Test faults as wrappers of the engine shape (nmt/engine.hpp, rule 7): a wrapper holds an
// engine, is an nmt::Engine itself, and changes only what goes in or out of the wrapped one, so
// protocol engines carry no test knobs. Wrappers nest (a delayed, lossy device).
#pragma once

#include <deque>
#include <optional>
#include <utility>

#include "nmt/engine.hpp"
#include "nmt/frame.hpp"

namespace nmt {

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
    return earliest(engine_.next_deadline(),
                    held_.empty() ? std::nullopt : std::optional(held_.front().due));
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
  struct Held {
    TimePoint due;
    CanFrame frame;
  };

  // Queues what the wrapped engine produced and releases what is due.
  void hold(TimePoint now, Output& out) {
    for (const auto& frame : scratch_.frames) {
      TimePoint due = now + delay_;
      if (!held_.empty() && held_.back().due > due) due = held_.back().due;
      held_.push_back({due, frame});
    }
    for (auto& event : scratch_.events) out.report(std::move(event));
    scratch_.clear();
    while (!held_.empty() && held_.front().due <= now) {
      out.send(held_.front().frame);
      held_.pop_front();
    }
  }

  E engine_;
  Duration delay_;
  std::deque<Held> held_;
  Output scratch_;
};

}  // namespace nmt
