// Emergency objects (CiA 301 §7.2.7): the 8-byte EMCY message, common error codes and
// error-register bits, and a producer (an engine of the shape of nmt/engine.hpp) that honours the
// COB-ID (1014h), the inhibit time (1015h) and the NMT state.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// Emergency error codes (CiA 301 §7.2.7.3.2, Table 21); profiles and vendors add their own.
namespace emcy_code {
inline constexpr std::uint16_t kErrorReset = 0x0000;  ///< error reset or no error
inline constexpr std::uint16_t kGeneric = 0x1000;
inline constexpr std::uint16_t kSoftwareInternal = 0x6100;
inline constexpr std::uint16_t kCommunication = 0x8100;
inline constexpr std::uint16_t kCanOverrun = 0x8110;
inline constexpr std::uint16_t kCanErrorPassive = 0x8120;
inline constexpr std::uint16_t kLifeGuardOrHeartbeat = 0x8130;  ///< life guard / heartbeat error
inline constexpr std::uint16_t kRecoveredFromBusOff = 0x8140;
inline constexpr std::uint16_t kPdoLengthError = 0x8210;  ///< PDO not processed, length error
}  // namespace emcy_code

/// Bits of the error register 1001h (CiA 301 §7.5.2.2).
namespace error_register {
inline constexpr std::uint8_t kGeneric = 0x01;
inline constexpr std::uint8_t kCurrent = 0x02;
inline constexpr std::uint8_t kVoltage = 0x04;
inline constexpr std::uint8_t kTemperature = 0x08;
inline constexpr std::uint8_t kCommunication = 0x10;
inline constexpr std::uint8_t kDeviceProfile = 0x20;
inline constexpr std::uint8_t kManufacturer = 0x80;
}  // namespace error_register

/// One emergency message: error code, the error register (1001h) at the time, and five
/// manufacturer-specific bytes (CiA 301 §7.2.7.3.1).
struct Emergency {
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
  bool operator==(const Emergency&) const = default;
};

/// Default EMCY COB-ID of the pre-defined connection set: 080h + node-ID.
inline constexpr std::uint32_t kEmcyCobIdBase = 0x080;
/// The EMCY COB-ID of the pre-defined connection set for `node_id` (valid, 11-bit).
constexpr cfg::CobId default_emcy_cob_id(cfg::NodeId node_id) {
  return cfg::CobId::standard(kEmcyCobIdBase + node_id);
}

/// The 8-byte EMCY frame on the identifier of `cob_id` (the 1014h word; its validity bit is not
/// looked at).
CanFrame make_emcy(cfg::CobId cob_id, const Emergency& emcy);
/// Reads an EMCY frame (8 data bytes, no RTR); nullopt for other frames. Does not check the
/// COB-ID: the caller knows which identifiers carry EMCY.
std::optional<Emergency> parse_emcy(const CanFrame& frame);

/// Emergency producer of one node. raise() sends at once when the inhibit time allows and
/// queues otherwise; on_timer() releases queued messages. Nothing is sent while the COB-ID is
/// invalid (bit 31 of 1014h set) or the NMT state forbids EMCY (set_allowed(false); CiA 301
/// §7.3.2.2: not in stopped nor initialising): such messages are dropped and counted. Receives
/// nothing and reports no events.
class EmcyProducer {
 public:
  using Event = NoEvent;
  using Output = Outbox<Event>;

  /// At most this many messages wait for the inhibit time; more are dropped and counted.
  static constexpr std::size_t kQueueCapacity = 16;

  /// cob_id: value of 1014h. inhibit_time_100us: 1015h, in 100 µs. EMCY starts allowed.
  explicit EmcyProducer(cfg::CobId cob_id, std::uint16_t inhibit_time_100us = 0);

  void set_cob_id(cfg::CobId cob_id) { cob_id_ = cob_id; }
  cfg::CobId cob_id() const { return cob_id_; }
  void set_inhibit_time(std::uint16_t inhibit_time_100us) { inhibit_100us_ = inhibit_time_100us; }
  /// Whether the NMT state permits EMCY (services_in(state).emcy).
  void set_allowed(bool allowed) { allowed_ = allowed; }
  bool allowed() const { return allowed_; }

  /// Reports an emergency at `now`: sent into `out` at once, or queued while the inhibit time
  /// runs (both: started, engine.hpp rule 5). Could not start (dropped and counted, nothing in
  /// `out`): the error says why: EMCY not allowed in the NMT state, the COB-ID invalid, or the
  /// queue full (kQueueCapacity).
  cfg::Status raise(const Emergency& emcy, TimePoint now, Output& out);

  bool on_frame(const CanFrame& /*frame*/, TimePoint /*now*/, Output& /*out*/) { return false; }
  /// Releases queued messages whose inhibit time has passed (at most one per inhibit time);
  /// drops the queue when EMCY is no longer allowed.
  void on_timer(TimePoint now, Output& out);
  /// When on_timer() has something to release; nullopt when the queue is empty.
  std::optional<TimePoint> next_deadline() const;

  /// Forgets queued messages and the inhibit timer (reset communication).
  void reset();
  std::size_t dropped() const { return dropped_; }

 private:
  bool can_send(TimePoint now) const;
  bool blocked() const { return !allowed_ || !cob_id_.valid(); }
  void send(const Emergency& emcy, TimePoint now, Output& out);

  cfg::CobId cob_id_;
  std::uint16_t inhibit_100us_;
  bool allowed_ = true;
  std::optional<TimePoint> last_sent_;
  std::deque<Emergency> queue_;
  std::size_t dropped_ = 0;
};
static_assert(Engine<EmcyProducer>);

}  // namespace nmt
