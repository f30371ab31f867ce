// The bus of BusEventLoop tests that need exact timing: a socket on a fake clock (the loop's
// clock is the bus's `now`). Frames arrive at scripted times and wait in its queue; receive()
// hands out the first that arrived by `now`, or waits (advancing the clock) for the next one up
// to the timeout. A stall of the process is `now` moving on while arrivals pile up. Each send
// attempt (try_send, as the loop sends) is answered as a driver would: from `answers`, Sent once
// those are used up, or Failed while `fail_sends` is set.
#pragma once

#include <algorithm>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "nmt/io/bus.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

class FakeClockBus final : public Bus {
 public:
  using Status = SendResult::Status;
  struct Arrival {
    TimePoint at;
    std::string frame;  ///< candump text
    StampClock clock = StampClock::Loop;
    std::optional<TimePoint> stamp;  ///< what the driver reports, when not `at`
  };

  /// The loop sends with try_send: a call of send() is a test failure waiting to be seen.
  cfg::Status send(const CanFrame& /*frame*/) override {
    return cfg::Error{"the loop sends with try_send"};
  }
  SendResult try_send(const CanFrame& frame) override {
    attempts.emplace_back(now, to_candump(frame));
    if (fail_sends) return {Status::Failed, "transmit queue full"};
    if (!answers.empty()) {
      const Status status = answers.front();
      answers.pop_front();
      if (status != Status::Sent) return {status, "scripted " + to_candump(frame)};
    }
    sent.push_back(to_candump(frame));
    sent_at.emplace_back(now, to_candump(frame));
    return {};
  }
  cfg::Result<std::optional<ReceivedFrame>> receive(Duration timeout) override {
    ++receives;
    if (timeout > Duration::zero()) waits.push_back(timeout);
    const Duration wait = std::max(timeout, Duration::zero());
    if (!arrivals.empty() && arrivals.front().at <= now + wait) {
      now = std::max(now, arrivals.front().at);
      const Arrival a = arrivals.front();
      arrivals.pop_front();
      return std::optional<ReceivedFrame>(
          ReceivedFrame{*from_candump(a.frame), a.stamp.value_or(a.at), a.clock});
    }
    if (flood) {
      // Another frame every 100 us, for ever.
      now += Duration{100};
      return std::optional<ReceivedFrame>(ReceivedFrame{*from_candump("123#"), now});
    }
    now += wait;
    return std::optional<ReceivedFrame>{};
  }
  std::string url() const override { return "scripted:"; }

  /// `frame` (candump text) arrives at `at`, stamped with `at` on the loop's clock.
  void arrive(TimePoint at, std::string frame) {
    arrivals.push_back({at, std::move(frame), StampClock::Loop, std::nullopt});
  }
  /// The same frame every `period` in [from, to).
  void arrive_every(Duration period, TimePoint from, TimePoint to, const std::string& frame) {
    for (TimePoint t = from; t < to; t += period) arrive(t, frame);
  }

  TimePoint now{};
  bool flood = false;          ///< with no arrival due, a frame 123# every 100 us
  bool fail_sends = false;     ///< every attempt Failed ("transmit queue full")
  std::deque<Status> answers;  ///< of the next try_send calls; Sent once empty
  std::deque<Arrival> arrivals;
  std::size_t receives = 0;
  std::vector<Duration> waits;  ///< the non-zero timeouts of receive(), in order
  std::vector<std::pair<TimePoint, std::string>> attempts;  ///< every try_send, when and what
  std::vector<std::string> sent;                            ///< the frames taken, in order
  std::vector<std::pair<TimePoint, std::string>> sent_at;   ///< the same, with when
};

}  // namespace nmt
