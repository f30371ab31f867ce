// CAN frames as protocol code sees them, and the candump text form used in tests and traces.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "cfg/cob_id.hpp"

namespace nmt {

/// The clock protocol engines see (engine.hpp rule 1): time since an epoch the driver chooses
/// (simulated time on the virtual bus, a monotonic clock on real buses). Only a tag: engines never
/// read a clock, so it has no now(); it makes a point in time and a length of time distinct types
/// (TimePoint + Duration and TimePoint - TimePoint compile, TimePoint + TimePoint does not).
struct EngineClock {
  using duration = std::chrono::microseconds;
  using rep = duration::rep;
  using period = duration::period;
  using time_point = std::chrono::time_point<EngineClock, duration>;
  static constexpr bool is_steady = true;
};
/// A length of time, in microseconds.
using Duration = EngineClock::duration;
/// A point in time: microseconds since the driver's epoch (`TimePoint{}` is the epoch).
using TimePoint = EngineClock::time_point;

/// A classic CAN frame (11- or 29-bit identifier, RTR, 0-8 data bytes). The data array is sized
/// for CAN FD so FD support can be added without changing the layout users see.
struct CanFrame {
  static constexpr std::uint32_t kMaxStandardId = cfg::kMaxStandardCanId;
  static constexpr std::uint32_t kMaxExtendedId = cfg::kMaxExtendedCanId;
  /// Linux <linux/can.h> CAN_ERR_FLAG: marks an error frame in the id word, as candump prints
  /// it and LINKTYPE_CAN_SOCKETCAN records it (the one definition for text and traces).
  static constexpr std::uint32_t kErrorFlag = 0x20000000u;

  std::uint32_t id = 0;  ///< 11-bit, or 29-bit when `extended`
  bool extended = false;
  bool rtr = false;
  bool error = false;    ///< an error frame reported by the driver (id holds the error class)
  std::uint8_t dlc = 0;  ///< number of data bytes, 0..8
  std::array<std::uint8_t, 64> data{};

  std::span<const std::uint8_t> payload() const { return {data.data(), dlc}; }
  /// Builds a data frame; returns a frame with dlc clamped to 8 if more bytes are given.
  static CanFrame make(std::uint32_t id, std::span<const std::uint8_t> bytes,
                       bool extended = false);
  bool operator==(const CanFrame& other) const;  ///< compares id, flags and the first dlc bytes
};

/// candump "compact" form: `605#2B171000E8030000`, `00000123#` (extended: 8 hex digits),
/// `705#R` (RTR). Error frames: the id with CAN_ERR_FLAG, as candump prints them.
std::string to_candump(const CanFrame& frame);
/// Parses the form above (also `123#R3`, an RTR with DLC 3). nullopt on malformed text.
std::optional<CanFrame> from_candump(std::string_view text);

}  // namespace nmt
