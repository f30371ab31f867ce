// The CiA 301 COB-ID word as objects 1005h, 1012h, 1014h, 1200h-12FFh, 1400h-1BFFh hold it, and
// the CAN identifier it stands for. The one conversion between the two.
//   bit 31: 1 = the object (PDO, SDO channel, EMCY, SYNC consumer, ...) is not valid / not used
//   bit 30: object-specific (PDO: no RTR allowed; SYNC/TIME: this node produces)
//   bit 29: 1 = 29-bit CAN identifier (CAN extended frame), 0 = 11-bit
//   bits 0-28: the identifier (bits 0-10 when bit 29 is 0)
#pragma once

#include <cstdint>
#include <optional>

namespace cfg {

inline constexpr std::uint32_t kCobIdInvalidBit = 0x80000000u;  ///< bit 31
inline constexpr std::uint32_t kCobIdBit30 = 0x40000000u;       ///< bit 30 (object-specific)
inline constexpr std::uint32_t kCobIdFrameBit = 0x20000000u;    ///< bit 29: 29-bit identifier
inline constexpr std::uint32_t kMaxStandardCanId = 0x7FF;
inline constexpr std::uint32_t kMaxExtendedCanId = 0x1FFFFFFF;

/// A CAN identifier with its frame format: what a frame carries on the bus.
struct CanId {
  std::uint32_t id = 0;   ///< 0..7FFh, or 0..1FFFFFFFh when extended
  bool extended = false;  ///< 29-bit identifier
  constexpr bool operator==(const CanId&) const = default;
};

/// A COB-ID word as stored in the dictionary. Value type; any 32-bit word is representable
/// (check valid() and well_formed() before using it on the bus).
class CobId {
 public:
  constexpr CobId() = default;
  /// The word as read from the dictionary (e.g. 1014h = 0x80000081).
  static constexpr CobId from_word(std::uint32_t word) { return CobId(word); }
  /// A valid COB-ID for `id` (11-bit when id <= 7FFh and !extended).
  static constexpr CobId of(CanId can_id) {
    return CobId((can_id.id & kMaxExtendedCanId) | (can_id.extended ? kCobIdFrameBit : 0u));
  }
  static constexpr CobId standard(std::uint32_t id) { return of({id, false}); }

  constexpr std::uint32_t word() const { return word_; }
  /// Bit 31 clear.
  constexpr bool valid() const { return (word_ & kCobIdInvalidBit) == 0; }
  constexpr bool extended() const { return (word_ & kCobIdFrameBit) != 0; }
  constexpr bool bit30() const { return (word_ & kCobIdBit30) != 0; }
  /// The identifier as a frame carries it.
  constexpr CanId can_id() const {
    return {word_ & (extended() ? kMaxExtendedCanId : kMaxStandardCanId), extended()};
  }
  /// The identifier fits the frame format: an 11-bit COB-ID has no bits set in 11-28.
  constexpr bool well_formed() const {
    return extended() || (word_ & kMaxExtendedCanId & ~kMaxStandardCanId) == 0;
  }
  /// The same COB-ID with bit 31 set or cleared (the PDO-safe order toggles it).
  constexpr CobId with_valid(bool valid) const {
    return CobId(valid ? (word_ & ~kCobIdInvalidBit) : (word_ | kCobIdInvalidBit));
  }
  constexpr bool operator==(const CobId&) const = default;

 private:
  constexpr explicit CobId(std::uint32_t word) : word_(word) {}
  std::uint32_t word_ = 0;
};

/// The CAN identifier a valid, well-formed COB-ID stands for; nullopt otherwise.
constexpr std::optional<CanId> usable_can_id(CobId cob_id) {
  if (!cob_id.valid() || !cob_id.well_formed()) return std::nullopt;
  return cob_id.can_id();
}

}  // namespace cfg
