#include "nmt/sim/sim_bus.hpp"

#include <algorithm>
#include <array>

namespace nmt {

namespace {

constexpr std::size_t kNoSender = static_cast<std::size_t>(-1);

}  // namespace

std::uint64_t arbitration_key(const CanFrame& frame) {
  // Bit 31..21: base id; bit 20: RTR (standard) or SRR (extended, recessive); bit 19: IDE;
  // bits 18..1: id extension; bit 0: RTR (extended). A lower key wins: dominant bits are 0.
  const std::uint64_t rtr = frame.rtr ? 1 : 0;
  if (frame.extended) {
    return (std::uint64_t{frame.id >> 18 & 0x7FF} << 21) | (1ULL << 20) | (1ULL << 19) |
           (std::uint64_t{frame.id & 0x3FFFF} << 1) | rtr;
  }
  return (std::uint64_t{frame.id & 0x7FF} << 21) | (rtr << 20);
}

// ------------------------------------------------------------------------------- SimNode ---

SimNode::~SimNode() {
  if (bus_) bus_->detach(*this);
}

void SimNode::send(const CanFrame& frame) {
  if (bus_) bus_->enqueue_frame(slot_, frame);
}

void SimNode::set_timer(std::optional<TimePoint> deadline) {
  if (bus_) bus_->arm_timer(slot_, deadline);
}

TimePoint SimNode::now() const {
  return bus_ ? bus_->now() : TimePoint{};
}

// -------------------------------------------------------------------------------- SimBus ---

SimBus::SimBus(std::uint32_t bitrate_bps)
    : bitrate_bps_(std::clamp<std::uint32_t>(bitrate_bps, 1, 1'000'000'000)) {}

SimBus::~SimBus() {
  for (auto& slot : slots_) {
    if (slot.node) slot.node->bus_ = nullptr;
  }
}

std::int64_t SimBus::bits_to_ns(std::uint64_t bits) const {
  return static_cast<std::int64_t>(bits * 1'000'000'000ULL / bitrate_bps_);
}

void SimBus::attach(SimNode& node) {
  if (node.bus_ == this) return;
  if (node.bus_) node.bus_->detach(node);
  std::size_t slot;
  if (!free_slots_.empty()) {
    slot = free_slots_.back();
    free_slots_.pop_back();
  } else {
    slot = slots_.size();
    slots_.emplace_back();
  }
  slots_[slot].node = &node;
  node.bus_ = this;
  node.slot_ = slot;
}

void SimBus::detach(SimNode& node) {
  if (node.bus_ != this) return;
  auto& slot = slots_[node.slot_];
  slot.node = nullptr;
  slot.queue.clear();
  slot.queue_head = 0;
  arm_timer(node.slot_, std::nullopt);
  if (transmitting_ && current_sender_ == node.slot_) current_sender_ = kNoSender;
  free_slots_.push_back(node.slot_);
  node.bus_ = nullptr;
}

void SimBus::send(SimNode& node, const CanFrame& frame) {
  if (node.bus_ == this) enqueue_frame(node.slot_, frame);
}

void SimBus::set_timer(SimNode& node, std::optional<TimePoint> deadline) {
  if (node.bus_ == this) arm_timer(node.slot_, deadline);
}

void SimBus::push(std::int64_t at_ns, std::uint8_t phase, EventKind kind, std::size_t slot,
                  std::uint64_t generation) {
  events_.push(Event{std::max(at_ns, now_ns_), phase, seq_++, kind, slot, generation});
  ++live_events_;
}

void SimBus::arm_timer(std::size_t slot, std::optional<TimePoint> deadline) {
  auto& s = slots_[slot];
  ++s.timer_generation;  // any queued timer event of this slot is now stale
  if (s.timer_armed) {
    s.timer_armed = false;
    --live_events_;
  }
  if (!deadline || !s.node) return;
  s.timer_armed = true;
  // Deadlines beyond the representable range never fire within a run.
  const auto us = deadline->time_since_epoch().count();
  const std::int64_t at = us > INT64_MAX / 1000 ? INT64_MAX : us * 1000;
  push(at, 0, EventKind::Timer, slot, s.timer_generation);
}

std::size_t SimBus::frames_queued(const SimNode& node) const {
  if (node.bus_ != this) return 0;
  const Slot& s = slots_[node.slot_];
  return s.queue.size() - s.queue_head + (transmitting_ && current_sender_ == node.slot_ ? 1 : 0);
}

void SimBus::enqueue_frame(std::size_t slot, const CanFrame& frame) {
  slots_[slot].queue.push_back(frame);
  if (!transmitting_ && !arbitration_pending_) {
    arbitration_pending_ = true;
    push(now_ns_, 1, EventKind::Arbitrate);
  }
}

void SimBus::schedule_at(TimePoint at, std::function<void(TimePoint)> fn) {
  std::size_t index;
  if (!free_calls_.empty()) {
    index = free_calls_.back();
    free_calls_.pop_back();
    calls_[index] = std::move(fn);
  } else {
    index = calls_.size();
    calls_.push_back(std::move(fn));
  }
  const auto us = at.time_since_epoch().count();
  push(us > INT64_MAX / 1000 ? INT64_MAX : us * 1000, 0, EventKind::Call, index);
}

std::size_t SimBus::add_observer(Observer observer) {
  const auto handle = next_observer_++;
  observers_.emplace_back(handle, std::move(observer));
  return handle;
}

void SimBus::remove_observer(std::size_t handle) {
  // Cleared, not erased: the observer list may be iterated right now.
  for (auto& [h, fn] : observers_) {
    if (h == handle) fn = nullptr;
  }
}

void SimBus::set_loss_rate(double rate, std::uint64_t seed) {
  loss_rate_ = std::clamp(rate, 0.0, 1.0);
  rng_.seed(seed);
}

void SimBus::advance_to(std::int64_t t_ns) {
  if (t_ns > now_ns_) now_ns_ = t_ns;
}

bool SimBus::stale(const Event& e) const {
  return e.kind == EventKind::Timer && (slots_[e.slot].timer_generation != e.generation);
}

void SimBus::drop_stale() {
  while (!events_.empty() && stale(events_.top())) events_.pop();
}

bool SimBus::step() {
  drop_stale();
  if (events_.empty()) return false;
  const Event e = events_.top();
  events_.pop();
  --live_events_;
  advance_to(e.at_ns);
  ++events_processed_;
  dispatch(e);
  return true;
}

void SimBus::run_until(TimePoint t) {
  const auto us = t.time_since_epoch().count();
  const std::int64_t t_ns = us > INT64_MAX / 1000 ? INT64_MAX : us * 1000;
  for (;;) {
    drop_stale();
    if (events_.empty() || events_.top().at_ns > t_ns) break;
    step();
  }
  advance_to(t_ns);
}

bool SimBus::run_until_idle(TimePoint limit) {
  const auto us = limit.time_since_epoch().count();
  const std::int64_t limit_ns = us > INT64_MAX / 1000 ? INT64_MAX : us * 1000;
  for (;;) {
    drop_stale();
    if (events_.empty()) return true;
    if (events_.top().at_ns > limit_ns) return false;
    step();
  }
}

bool SimBus::run_until(const std::function<bool()>& done, TimePoint limit) {
  const auto us = limit.time_since_epoch().count();
  const std::int64_t limit_ns = us > INT64_MAX / 1000 ? INT64_MAX : us * 1000;
  for (;;) {
    if (done()) return true;
    drop_stale();
    if (events_.empty() || events_.top().at_ns > limit_ns) return false;
    step();
  }
}

void SimBus::dispatch(const Event& e) {
  switch (e.kind) {
    case EventKind::Timer: {
      auto& slot = slots_[e.slot];
      slot.timer_armed = false;
      if (slot.node) slot.node->on_timer(now());
      break;
    }
    case EventKind::Call: {
      auto fn = std::move(calls_[e.slot]);
      calls_[e.slot] = nullptr;
      free_calls_.push_back(e.slot);
      if (fn) fn(now());
      break;
    }
    case EventKind::EndOfFrame:
      end_of_frame();
      break;
    case EventKind::Arbitrate:
      arbitrate();
      break;
    case EventKind::DelayedDelivery: {
      auto delayed = std::move(delayed_[e.slot]);
      delayed_[e.slot].reset();
      free_delayed_.push_back(e.slot);
      if (delayed) deliver(delayed->frame, delayed->sender);
      break;
    }
  }
}

void SimBus::arbitrate() {
  arbitration_pending_ = false;
  transmitting_ = false;
  // Only the oldest frame of each node competes; the lowest arbitration field wins, ties (two
  // nodes sending the same identifier) go to the node attached first.
  std::size_t winner = kNoSender;
  std::uint64_t best = 0;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    const auto& s = slots_[i];
    if (!s.node || s.queue_head == s.queue.size()) continue;
    const auto k = arbitration_key(s.queue[s.queue_head]);
    if (winner == kNoSender || k < best) {
      winner = i;
      best = k;
    }
  }
  if (winner == kNoSender) return;  // bus idle
  auto& s = slots_[winner];
  current_ = s.queue[s.queue_head++];
  if (s.queue_head == s.queue.size()) {
    s.queue.clear();
    s.queue_head = 0;
  }
  current_sender_ = winner;
  current_start_ns_ = now_ns_;
  current_bits_ = frame_bits(current_);
  transmitting_ = true;
  push(current_start_ns_ + bits_to_ns(current_bits_.until_eof()), 0, EventKind::EndOfFrame);
}

void SimBus::end_of_frame() {
  const auto total_ns = bits_to_ns(current_bits_.total());
  stats_.frames++;
  stats_.bits += current_bits_.total();
  stats_.busy_ns += total_ns;
  // The bus stays busy through the intermission; then the next arbitration.
  arbitration_pending_ = true;
  push(current_start_ns_ + total_ns, 1, EventKind::Arbitrate);

  bool lost = false;
  if (loss_rate_ > 0.0) {
    // 53 random bits as a double in [0, 1): the same on every standard library.
    const double u = static_cast<double>(rng_() >> 11) * 0x1.0p-53;
    lost = u < loss_rate_;
  }
  FrameFate fate = lost ? FrameFate::drop() : FrameFate::deliver();
  if (!lost && filter_) fate = filter_(current_, now());
  switch (fate.kind) {
    case FrameFate::Kind::Drop:
      stats_.frames_dropped++;
      break;
    case FrameFate::Kind::Delay:
      if (fate.delay.count() > 0) {
        std::size_t index;
        if (!free_delayed_.empty()) {
          index = free_delayed_.back();
          free_delayed_.pop_back();
        } else {
          index = delayed_.size();
          delayed_.emplace_back();
        }
        delayed_[index] = Delayed{current_, current_sender_};
        push(now_ns_ + fate.delay.count() * 1000, 0, EventKind::DelayedDelivery, index);
        break;
      }
      [[fallthrough]];
    case FrameFate::Kind::Deliver: {
      const CanFrame frame = current_;  // a callback may start the next frame's bookkeeping
      deliver(frame, current_sender_);
      break;
    }
  }
}

void SimBus::deliver(const CanFrame& frame, std::size_t sender) {
  const auto t = now();
  // Indexes, not iterators: callbacks may attach and detach nodes.
  const std::size_t n = slots_.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (i == sender || !slots_[i].node) continue;
    slots_[i].node->on_frame(frame, t);
  }
  const std::size_t m = observers_.size();
  for (std::size_t i = 0; i < m; ++i) {
    if (observers_[i].second) {
      auto fn = observers_[i].second;  // survives remove_observer() from inside the call
      fn(frame, t);
    }
  }
}

SimBusStats SimBus::statistics() const {
  SimBusStats s = stats_;
  s.elapsed_ns = now_ns_ - stats_start_ns_;
  return s;
}

void SimBus::reset_statistics() {
  stats_ = {};
  stats_start_ns_ = now_ns_;
}

}  // namespace nmt
