#include "nmt/sim_bus.hpp"

#include <algorithm>
#include <array>

namespace nmt {

namespace {

constexpr std::size_t kNoSender = static_cast<std::size_t>(-1);

// The bus model computes the length of every frame it carries, so this is its hot path: the
// frame is packed into bytes and CRC and stuffing advance a byte at a time through tables. The
// bit-at-a-time can_crc15() and count_stuff_bits() below define the results; the tests compare
// the two.

// CRC-15 register after shifting in the byte `i` (aligned with the register's top bits).
constexpr std::array<std::uint16_t, 256> make_crc15_table() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    auto crc = static_cast<std::uint16_t>(i << 7);
    for (int bit = 0; bit < 8; ++bit) {
      crc = static_cast<std::uint16_t>((crc & 0x4000) != 0 ? ((crc << 1) ^ 0x4599) & 0x7FFF
                                                           : (crc << 1) & 0x7FFF);
    }
    table[i] = crc;
  }
  return table;
}
constexpr auto kCrc15Table = make_crc15_table();

// Stuffing as a state machine over runs: state 0 = no bit yet, 1 + previous * 4 + (run - 1)
// for a run of 1..4 equal bits (a run of 5 is cut by a stuff bit at once).
struct StuffStep {
  std::uint8_t next;
  std::uint8_t stuffed;
};
constexpr StuffStep stuff_bit(std::uint8_t state, unsigned bit) {
  int previous = state == 0 ? -1 : (state - 1) / 4;
  unsigned run = state == 0 ? 0 : (state - 1) % 4 + 1;
  std::uint8_t stuffed = 0;
  if (static_cast<int>(bit) == previous) {
    ++run;
  } else {
    previous = static_cast<int>(bit);
    run = 1;
  }
  if (run == 5) {
    stuffed = 1;
    previous = 1 - previous;
    run = 1;
  }
  return {static_cast<std::uint8_t>(1 + previous * 4 + static_cast<int>(run) - 1), stuffed};
}
constexpr std::array<std::array<StuffStep, 256>, 9> make_stuff_table() {
  std::array<std::array<StuffStep, 256>, 9> table{};
  for (std::uint8_t state = 0; state < 9; ++state) {
    for (unsigned byte = 0; byte < 256; ++byte) {
      StuffStep acc{state, 0};
      for (int i = 7; i >= 0; --i) {
        auto step = stuff_bit(acc.next, byte >> i & 1U);
        acc = {step.next, static_cast<std::uint8_t>(acc.stuffed + step.stuffed)};
      }
      table[state][byte] = acc;
    }
  }
  return table;
}
constexpr auto kStuffTable = make_stuff_table();

// The bits of a frame from SOF to the end of the CRC sequence, fed MSB first.
class FrameBitStream {
 public:
  void put(std::uint32_t value, unsigned width) {  // width <= 24
    acc_ = acc_ << width | (value & ((1U << width) - 1));
    pending_ += width;
    total_ += width;
    while (pending_ >= 8) {
      pending_ -= 8;
      consume(static_cast<std::uint8_t>(acc_ >> pending_));
    }
  }
  // Ends the bits the CRC covers and returns the CRC of them.
  std::uint16_t finish_crc() {
    for (unsigned i = pending_; i-- > 0;) {
      const bool next = (acc_ >> i & 1U) != ((crc_ >> 14 & 1U) != 0);
      crc_ = static_cast<std::uint16_t>(crc_ << 1 & 0x7FFF);
      if (next) crc_ ^= 0x4599;
    }
    crc_done_ = true;
    return crc_;
  }
  // Stuff bits of everything put so far.
  unsigned finish_stuffing() {
    for (unsigned i = pending_; i-- > 0;) {
      const auto step = stuff_bit(stuff_state_, acc_ >> i & 1U);
      stuff_state_ = step.next;
      stuffed_ += step.stuffed;
    }
    pending_ = 0;
    return stuffed_;
  }
  unsigned size() const { return total_; }

 private:
  void consume(std::uint8_t byte) {
    if (!crc_done_) {
      crc_ = static_cast<std::uint16_t>(((crc_ << 8) & 0x7FFF) ^
                                        kCrc15Table[((crc_ >> 7) ^ byte) & 0xFF]);
    }
    const auto step = kStuffTable[stuff_state_][byte];
    stuff_state_ = step.next;
    stuffed_ += step.stuffed;
  }

  std::uint64_t acc_ = 0;
  unsigned pending_ = 0;  // low bits of acc_ not consumed yet (< 8 between calls)
  unsigned total_ = 0;
  std::uint16_t crc_ = 0;
  bool crc_done_ = false;
  std::uint8_t stuff_state_ = 0;
  unsigned stuffed_ = 0;
};

}  // namespace

// ISO 11898-1, CRC field: CRC-15, generator x^15+x^14+x^10+x^8+x^7+x^4+x^3+1 (0x4599), over SOF,
// arbitration, control and data fields.
std::uint16_t can_crc15(std::span<const std::uint8_t> bits) {
  std::uint16_t crc = 0;
  for (auto bit : bits) {
    const bool next = (bit != 0) != ((crc >> 14 & 1U) != 0);
    crc = static_cast<std::uint16_t>(crc << 1 & 0x7FFF);
    if (next) crc ^= 0x4599;
  }
  return crc;
}

unsigned count_stuff_bits(std::span<const std::uint8_t> bits) {
  unsigned stuffed = 0;
  unsigned run = 0;
  int previous = -1;
  for (auto b : bits) {
    const int bit = b != 0 ? 1 : 0;
    if (bit == previous) {
      ++run;
    } else {
      previous = bit;
      run = 1;
    }
    if (run == 5) {
      ++stuffed;
      previous = 1 - bit;  // the stuff bit starts the next run
      run = 1;
    }
  }
  return stuffed;
}

FrameBits frame_bits(const CanFrame& frame) {
  FrameBits bits;
  if (frame.error) {
    // Active error flag (6 dominant bits) and error delimiter (8 recessive bits).
    bits.stuffed_region = 14;
    bits.trailer = 0;
    return bits;
  }
  const unsigned dlc = std::min<unsigned>(frame.dlc, 8);
  const unsigned data_bytes = frame.rtr ? 0 : dlc;
  FrameBitStream w;
  w.put(0, 1);  // SOF
  if (frame.extended) {
    w.put(frame.id >> 18 & 0x7FF, 11);  // base identifier
    w.put(1, 1);                        // SRR (recessive)
    w.put(1, 1);                        // IDE (recessive: extended)
    w.put(frame.id & 0x3FFFF, 18);      // identifier extension
    w.put(frame.rtr ? 1 : 0, 1);        // RTR
    w.put(0, 2);                        // r1, r0
  } else {
    w.put(frame.id & 0x7FF, 11);
    w.put(frame.rtr ? 1 : 0, 1);  // RTR
    w.put(0, 1);                  // IDE (dominant: standard)
    w.put(0, 1);                  // r0
  }
  w.put(dlc, 4);
  for (unsigned i = 0; i < data_bytes; ++i) w.put(frame.data[i], 8);
  w.put(w.finish_crc(), 15);
  bits.stuffed_region = w.size();
  bits.stuff_bits = w.finish_stuffing();
  return bits;
}

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
  return bus_ ? bus_->now() : TimePoint{0};
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
  const auto us = deadline->count();
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
  const auto us = at.count();
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
  const auto us = t.count();
  const std::int64_t t_ns = us > INT64_MAX / 1000 ? INT64_MAX : us * 1000;
  for (;;) {
    drop_stale();
    if (events_.empty() || events_.top().at_ns > t_ns) break;
    step();
  }
  advance_to(t_ns);
}

bool SimBus::run_until_idle(TimePoint limit) {
  const auto us = limit.count();
  const std::int64_t limit_ns = us > INT64_MAX / 1000 ? INT64_MAX : us * 1000;
  for (;;) {
    drop_stale();
    if (events_.empty()) return true;
    if (events_.top().at_ns > limit_ns) return false;
    step();
  }
}

bool SimBus::run_until(const std::function<bool()>& done, TimePoint limit) {
  const auto us = limit.count();
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
