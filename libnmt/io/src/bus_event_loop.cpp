#include "nmt/io/bus_event_loop.hpp"

#include <linux/can/error.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <ctime>

namespace nmt {

TimePoint steady_now() {
  return TimePoint{
      std::chrono::duration_cast<Duration>(std::chrono::steady_clock::now().time_since_epoch())};
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
    : bus_(&bus),
      options_(options),
      clock_(std::move(clock)),
      // eventfd(2): a counter post() adds to and the loop's poll sees. Without one (out of
      // descriptors) post() still works, the loop then notices within max_wait.
      wake_fd_(::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK)) {}

BusEventLoop::~BusEventLoop() {
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

void BusEventLoop::post(Task fn) {
  {
    const std::lock_guard lock(posted_mutex_);
    posted_.push_back(std::move(fn));
  }
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    // Only EAGAIN (the counter at its maximum) can fail here, and then the loop is awake anyway.
    (void)!::write(wake_fd_, &one, sizeof one);
  }
}

std::size_t BusEventLoop::posted() const {
  const std::lock_guard lock(posted_mutex_);
  return posted_.size();
}

void BusEventLoop::run_posted() {
  // Only the functions queued now: one a function posts waits for the next pass. One at a time
  // under the lock, so an exception leaves the rest queued, in order.
  std::size_t count = 0;
  {
    const std::lock_guard lock(posted_mutex_);
    count = posted_.size();
  }
  for (; count > 0 && !stop_requested(); --count) {
    std::optional<Task> task;
    {
      const std::lock_guard lock(posted_mutex_);
      if (posted_.empty()) return;
      task.emplace(std::move(posted_.front()));
      posted_.pop_front();
    }
    (*task)();
  }
}

cfg::Result<std::optional<ReceivedFrame>> BusEventLoop::wait_for_frame(Duration wait) {
  const int bus_fd = bus_->readable_fd();
  if (bus_fd < 0 || wake_fd_ < 0) return bus_->receive(wait);
  std::array<pollfd, 2> fds{{{bus_fd, POLLIN, 0}, {wake_fd_, POLLIN, 0}}};
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(wait);
  const timespec timeout{static_cast<std::time_t>(seconds.count()),
                         static_cast<long>((wait - seconds).count() * 1000)};
  if (::ppoll(fds.data(), fds.size(), &timeout, nullptr) < 0 && errno != EINTR) {
    return cfg::Error{"cannot wait for frames on " + bus_->url() + ": " + std::strerror(errno)};
  }
  if ((fds[1].revents & POLLIN) != 0) {
    std::uint64_t count = 0;
    (void)!::read(wake_fd_, &count, sizeof count);  // reset the counter; the pass runs them all
  }
  // The bus says what it has (an error on its descriptor included).
  if (fds[0].revents != 0) return bus_->receive(Duration::zero());
  return std::optional<ReceivedFrame>{};
}

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
    transmit_.push_back(frame);
    // The loop's other engines hear it now, as the frame's place in the queue is fixed.
    if (options_.local_echo && engines_.size() > 1) pending_.push_back({frame, from});
  }
  counters_.max_queued = std::max(counters_.max_queued, transmit_.size());
  out.clear();
  return flush_transmit(now);
}

cfg::Status BusEventLoop::flush_transmit(TimePoint now) {
  // An event handler that sends (apply) lands here again: its frames wait behind ours.
  if (flushing_) return {};
  flushing_ = true;
  cfg::Status status;
  while (!transmit_.empty() && !bus_off() && (!retry_at_ || clock_() >= *retry_at_)) {
    const CanFrame frame = transmit_.front();
    auto attempt = bus_->try_send(frame);
    using S = SendResult::Status;
    if (attempt.status == S::Sent) {
      transmit_.pop_front();
      ++sent_;
      retry_delay_ = Duration::zero();
      retry_at_.reset();
      if (observer_) {
        const InCallback in_callback(in_callback_);
        observer_(frame, now, Direction::Sent);
      }
      continue;
    }
    if (attempt.status == S::InterfaceGone) {
      status = cfg::Error{bus_->url() + ": the interface is gone, nothing more can be sent (" +
                          attempt.message + "); " + std::to_string(transmit_.size()) +
                          " frame(s) not sent"};
      break;
    }
    if (attempt.status == S::Refused) {
      transmit_.pop_front();
      ++counters_.refused;
      report(BusEvent::Kind::FrameRefused, attempt.message, frame, now);
      continue;
    }
    // Back-pressure or a failure the interface may recover from: the frame stays first.
    const bool full = attempt.status == S::QueueFull;
    const Duration first = full ? options_.queue_full_retry : options_.send_failure_retry;
    const Duration most =
        full ? Duration{std::chrono::milliseconds(2)} : Duration{std::chrono::seconds(1)};
    retry_delay_ = std::clamp(retry_delay_ * 2, first, std::max(first, most));
    retry_at_ = clock_() + retry_delay_;
    if (full) {
      ++counters_.queue_full;
    } else {
      ++counters_.send_failures;
      report(BusEvent::Kind::SendFailed, attempt.message, frame, now);
    }
    break;
  }
  flushing_ = false;
  return status;
}

void BusEventLoop::report(BusEvent::Kind kind, std::string text, const CanFrame& frame,
                          TimePoint now) {
  if (!bus_event_handler_) return;
  const InCallback in_callback(in_callback_);
  bus_event_handler_(BusEvent{kind, std::move(text), frame}, now);
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

TimePoint BusEventLoop::engine_time(TimePoint clock) const {
  Duration paused = paused_;
  if (bus_off_since_ && clock > *bus_off_since_) paused += clock - *bus_off_since_;
  return clock - paused;
}

TimePoint BusEventLoop::now() const {
  return in_callback_ ? last_given_ : std::max(engine_time(clock_()), last_given_);
}

BusCounters BusEventLoop::counters() const {
  BusCounters c = counters_;
  c.queued = transmit_.size();
  return c;
}

cfg::Status BusEventLoop::handle_received(const ReceivedFrame& received) {
  // A stamp on the loop's clock moves with it onto the engines' time (bus-off cut out); a
  // realtime stamp keeps its age against the engines' now.
  ReceivedFrame stamped = received;
  if (stamped.clock == StampClock::Loop) stamped.timestamp = engine_time(stamped.timestamp);
  const TimePoint at =
      arrival_on_loop_clock(stamped, engine_time(clock_()), wall_clock_now(), last_given_);
  // One time line: what was due before the frame arrived happens first, at the frame's time
  // (the engines check their own due times, engine.hpp rule 3). A timer due at the very moment
  // of arrival fires first too: the frame came no earlier than the deadline.
  if (auto s = fire_timers(at); !s) return s;
  ++received_;
  if (observer_) {
    const InCallback in_callback(in_callback_);
    observer_(received.frame, at, Direction::Received);
  }
  if (received.frame.error) {
    handle_error_frame(received.frame, give(at));
    return flush_transmit(at);  // the controller may be back
  }
  return deliver(received.frame, nullptr, at);
}

void BusEventLoop::handle_error_frame(const CanFrame& frame, TimePoint now) {
  // linux/can/error.h: the class bits are in the id (CAN_ERR_MASK), details in the data bytes;
  // data[1] says the controller's state for CAN_ERR_CRTL.
  ++counters_.error_frames;
  const std::uint32_t cls = frame.id;
  const std::uint8_t ctrl = frame.dlc > 1 ? frame.data[1] : 0;
  using K = BusEvent::Kind;
  if ((cls & CAN_ERR_LOSTARB) != 0) {
    ++counters_.lost_arbitration;
    report(K::LostArbitration, "a frame lost arbitration", frame, now);
  }
  if ((cls & CAN_ERR_CRTL) != 0) {
    if ((ctrl & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) != 0) {
      ++counters_.controller_overflows;
      report(K::ControllerOverflow,
             std::string("the controller's ") +
                 ((ctrl & CAN_ERR_CRTL_RX_OVERFLOW) != 0 ? "receive" : "transmit") +
                 " buffer overflowed",
             frame, now);
    }
    if ((ctrl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) != 0) {
      ++counters_.error_warning;
      report(K::ErrorWarning, "error counters at the warning level", frame, now);
    }
    if ((ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) != 0) {
      ++counters_.error_passive;
      report(K::ErrorPassive, "the controller is error passive", frame, now);
    }
  }
  if ((cls & (CAN_ERR_PROT | CAN_ERR_TRX | CAN_ERR_ACK | CAN_ERR_BUSERROR | CAN_ERR_TX_TIMEOUT)) !=
      0) {
    ++counters_.bus_errors;
    const char* text =
        (cls & CAN_ERR_ACK) != 0 ? "no acknowledgement (is anyone else on the bus?)"
        : (cls & CAN_ERR_TX_TIMEOUT) != 0
            ? "a frame could not be sent in time (bus busy, or no node acknowledges)"
            : "bus error (a protocol or transceiver fault: check the cabling, the 120 ohm "
              "termination at both ends and that every node uses the same bit rate)";
    report(K::BusError, text, frame, now);
  }
  if ((cls & CAN_ERR_BUSOFF) != 0 && !bus_off_since_) {
    ++counters_.bus_off;
    bus_off_since_ = clock_();
    report(K::BusOff, "the controller is bus-off: sending stops until it is back", frame, now);
  }
  const bool active = (cls & CAN_ERR_CRTL) != 0 && (ctrl & CAN_ERR_CRTL_ACTIVE) != 0;
  if (((cls & CAN_ERR_RESTARTED) != 0 || active) && bus_off_since_) {
    const Duration off = std::max(Duration::zero(), clock_() - *bus_off_since_);
    paused_ += off;
    counters_.bus_off_time += off;
    bus_off_since_.reset();
    ++counters_.restarted;
    retry_at_.reset();
    report(K::Restarted,
           "the controller is back after " + std::to_string(off.count() / 1000) +
               " ms of bus-off; sending resumes",
           frame, now);
  } else if ((cls & CAN_ERR_RESTARTED) != 0) {
    ++counters_.restarted;
    report(K::Restarted, "the controller restarted", frame, now);
  }
}

std::string_view to_string(BusEvent::Kind kind) {
  switch (kind) {
    case BusEvent::Kind::SendFailed:
      return "send_failed";
    case BusEvent::Kind::FrameRefused:
      return "frame_refused";
    case BusEvent::Kind::ErrorWarning:
      return "error_warning";
    case BusEvent::Kind::ErrorPassive:
      return "error_passive";
    case BusEvent::Kind::BusOff:
      return "bus_off";
    case BusEvent::Kind::Restarted:
      return "restarted";
    case BusEvent::Kind::LostArbitration:
      return "lost_arbitration";
    case BusEvent::Kind::ControllerOverflow:
      return "controller_overflow";
    case BusEvent::Kind::BusError:
      return "bus_error";
  }
  return "unknown";
}

cfg::Status BusEventLoop::run_until_sent(Duration limit) {
  until_sent_ = true;
  auto status = run_until(clock_() + limit);
  until_sent_ = false;
  return status;
}

cfg::Status BusEventLoop::run_until(TimePoint until) {
  if (failed_) {
    cfg::Error e = std::move(*failed_);
    failed_.reset();
    return e;
  }
  while (!stop_requested()) {
    run_posted();
    if (stop_requested()) break;
    // `now` is read before the queue is looked at: everything that arrived up to `now` is in
    // the queue by then, so once it is read out, the timers due up to `now` may fire. A stall
    // of the process anywhere in this pass leaves its frames in the queue for the next pass.
    const TimePoint clock = clock_();
    if (clock >= until) break;
    const TimePoint now = engine_time(clock);
    if (auto s = flush_transmit(std::max(now, last_given_)); !s) return s;
    if (until_sent_ && transmit_.empty()) break;
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
    // During bus-off the engines' time stands still, so no timer comes due (see "Transmit").
    if (auto s = fire_timers(now); !s) return s;
    if (stop_requested()) break;

    // Wait for the next frame, up to the engines' next deadline or the next send retry.
    const TimePoint t = clock_();
    if (t >= until) break;
    Duration wait = options_.max_wait;
    if (auto d = next_deadline()) {
      wait = std::min(wait, std::max(Duration::zero(), *d - engine_time(t)));
    }
    if (!transmit_.empty() && !bus_off()) {
      wait =
          retry_at_ ? std::min(wait, std::max(Duration::zero(), *retry_at_ - t)) : Duration::zero();
    }
    if (until != TimePoint::max()) wait = std::min(wait, until - t);
    if (wait <= Duration::zero()) continue;
    auto received = wait_for_frame(wait);
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
