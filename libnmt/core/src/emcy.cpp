#include "nmt/emcy.hpp"

#include <algorithm>

namespace nmt {

namespace {
constexpr std::uint32_t kCobIdInvalid = 0x80000000u;
constexpr std::uint32_t kCobIdExtended = 0x20000000u;
}  // namespace

CanFrame make_emcy(std::uint32_t cob_id, const Emergency& emcy) {
  // CiA 301 §7.2.7.3.1: byte 0-1 error code (little-endian), byte 2 error register, 3-7 vendor.
  std::array<std::uint8_t, 8> bytes{static_cast<std::uint8_t>(emcy.error_code & 0xFF),
                                    static_cast<std::uint8_t>(emcy.error_code >> 8),
                                    emcy.error_register};
  std::copy(emcy.manufacturer.begin(), emcy.manufacturer.end(), bytes.begin() + 3);
  const bool extended = (cob_id & kCobIdExtended) != 0;
  return CanFrame::make(cob_id & (extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId),
                        bytes, extended);
}

std::optional<Emergency> parse_emcy(const CanFrame& frame) {
  if (frame.rtr || frame.error || frame.dlc != 8) return std::nullopt;
  Emergency e;
  e.error_code = static_cast<std::uint16_t>(frame.data[0] | (frame.data[1] << 8));
  e.error_register = frame.data[2];
  std::copy_n(frame.data.begin() + 3, 5, e.manufacturer.begin());
  return e;
}

EmcyProducer::EmcyProducer(std::uint32_t cob_id, std::uint16_t inhibit_time_100us)
    : cob_id_(cob_id), inhibit_100us_(inhibit_time_100us) {}

bool EmcyProducer::can_send(TimePoint now) const {
  // CiA 301 §7.5.2.15: 1015h is the minimum time between two EMCY messages, in 100 µs.
  return !last_sent_ || now >= *last_sent_ + Duration(std::int64_t{inhibit_100us_} * 100);
}

CanFrame EmcyProducer::send(const Emergency& emcy, TimePoint now) {
  last_sent_ = now;
  return make_emcy(cob_id_, emcy);
}

std::optional<CanFrame> EmcyProducer::raise(const Emergency& emcy, TimePoint now, bool allowed) {
  if (!allowed || (cob_id_ & kCobIdInvalid) != 0) {
    ++dropped_;
    return std::nullopt;
  }
  if (queue_.empty() && can_send(now)) return send(emcy, now);
  if (queue_.size() >= kQueueCapacity) {
    ++dropped_;
    return std::nullopt;
  }
  queue_.push_back(emcy);
  return std::nullopt;
}

std::vector<CanFrame> EmcyProducer::on_timer(TimePoint now, bool allowed) {
  std::vector<CanFrame> out;
  if (!allowed || (cob_id_ & kCobIdInvalid) != 0) {
    dropped_ += queue_.size();
    queue_.clear();
    return out;
  }
  // With an inhibit time of 0 every queued message may go at once.
  while (!queue_.empty() && can_send(now)) {
    out.push_back(send(queue_.front(), now));
    queue_.pop_front();
    if (inhibit_100us_ != 0) break;
  }
  return out;
}

std::optional<TimePoint> EmcyProducer::deadline() const {
  if (queue_.empty()) return std::nullopt;
  if (!last_sent_) return TimePoint{0};
  return *last_sent_ + Duration(std::int64_t{inhibit_100us_} * 100);
}

void EmcyProducer::reset() {
  queue_.clear();
  last_sent_.reset();
}

}  // namespace nmt
