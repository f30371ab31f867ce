#include "nmt/protocol/emcy.hpp"

#include <algorithm>
#include <string>
#include <string_view>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"

namespace nmt {

CanFrame make_emcy(cfg::CobId cob_id, const Emergency& emcy) {
  // CiA 301 §7.2.7.3.1: byte 0-1 error code (little-endian), byte 2 error register, 3-7 vendor.
  std::array<std::uint8_t, 8> bytes{};
  cfg::store_le(emcy.error_code, bytes, 2);
  bytes[2] = emcy.error_register;
  std::copy(emcy.manufacturer.begin(), emcy.manufacturer.end(), bytes.begin() + 3);
  const cfg::CanId id = cob_id.can_id();
  return CanFrame::make(id.id, bytes, id.extended);
}

std::optional<Emergency> parse_emcy(const CanFrame& frame) {
  if (frame.rtr || frame.error || frame.dlc != 8) return std::nullopt;
  Emergency e;
  e.error_code = cfg::load_le16(frame.data);
  e.error_register = frame.data[2];
  std::copy_n(frame.data.begin() + 3, 5, e.manufacturer.begin());
  return e;
}

EmcyProducer::EmcyProducer(cfg::CobId cob_id, std::uint16_t inhibit_time_100us)
    : cob_id_(cob_id), inhibit_100us_(inhibit_time_100us) {}

bool EmcyProducer::can_send(TimePoint now) const {
  // CiA 301 §7.5.2.15: 1015h is the minimum time between two EMCY messages, in 100 µs.
  return !last_sent_ || now >= *last_sent_ + Duration(std::int64_t{inhibit_100us_} * 100);
}

void EmcyProducer::send(const Emergency& emcy, TimePoint now, Output& out) {
  last_sent_ = now;
  out.send(make_emcy(cob_id_, emcy));
}

cfg::Status EmcyProducer::raise(const Emergency& emcy, TimePoint now, Output& out) {
  const auto refused = [&](std::string_view why) {
    ++dropped_;
    return cfg::Error{"EMCY " + cfg::hex_digits(emcy.error_code, 4) +
                      "h not sent: " + std::string(why)};
  };
  // CiA 301 §7.3.2.2: no EMCY in stopped (nor initialising).
  if (!allowed_) return refused("the NMT state does not allow EMCY");
  // CiA 301 §7.5.2.14: 1014h bit 31 set, the EMCY does not exist.
  if (!cob_id_.valid()) return refused("the EMCY COB-ID (1014h) is invalid");
  if (queue_.empty() && can_send(now)) {
    send(emcy, now, out);
    return {};
  }
  if (queue_.size() >= kQueueCapacity) {
    return refused(std::to_string(kQueueCapacity) +
                   " messages already wait for the inhibit time (1015h)");
  }
  queue_.push_back(emcy);
  return {};
}

void EmcyProducer::on_timer(TimePoint now, Output& out) {
  if (blocked()) {
    dropped_ += queue_.size();
    queue_.clear();
    return;
  }
  // With an inhibit time of 0 every queued message may go at once.
  while (!queue_.empty() && can_send(now)) {
    send(queue_.front(), now, out);
    queue_.pop_front();
    if (inhibit_100us_ != 0) break;
  }
}

std::optional<TimePoint> EmcyProducer::next_deadline() const {
  if (queue_.empty()) return std::nullopt;
  if (!last_sent_) return TimePoint{};
  return *last_sent_ + Duration(std::int64_t{inhibit_100us_} * 100);
}

void EmcyProducer::reset() {
  queue_.clear();
  last_sent_.reset();
}

}  // namespace nmt
