// Little-endian integers as CANopen puts them on the bus and in concise DCF streams (CiA 301
// §7.1.2: "little endian"), and hex digits of text. The one place of these conversions.
#pragma once

#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace cfg {

/// The unsigned integer in the first `size` bytes of `bytes` (1..8; asserted, and `bytes` must
/// hold them), least significant byte first.
constexpr std::uint64_t load_le(std::span<const std::uint8_t> bytes, std::size_t size) {
  assert(size >= 1 && size <= 8 && bytes.size() >= size);
  std::uint64_t v = 0;
  for (std::size_t i = size; i-- > 0;) v = v << 8 | bytes[i];
  return v;
}
constexpr std::uint16_t load_le16(std::span<const std::uint8_t> bytes) {
  return static_cast<std::uint16_t>(load_le(bytes, 2));
}
constexpr std::uint32_t load_le32(std::span<const std::uint8_t> bytes) {
  return static_cast<std::uint32_t>(load_le(bytes, 4));
}

/// The one rule for reading an UNSIGNED32 whose length the bus or a file decides (an SDO upload,
/// a written value, a stored entry): its first up to 4 bytes, least significant first; bytes
/// that are missing count as 0, so an empty value is 0 and 1..3 bytes are the number they hold.
/// (load_le32 is for 4 bytes known to be there.)
constexpr std::uint32_t low_le32(std::span<const std::uint8_t> bytes) {
  const std::size_t size = bytes.size() < 4 ? bytes.size() : 4;
  return size == 0 ? 0 : static_cast<std::uint32_t>(load_le(bytes, size));
}

/// Writes the low `size` bytes of `value` (1..8) to `out`, least significant first.
constexpr void store_le(std::uint64_t value, std::span<std::uint8_t> out, std::size_t size) {
  assert(size >= 1 && size <= 8 && out.size() >= size);
  for (std::size_t i = 0; i < size; ++i) out[i] = static_cast<std::uint8_t>(value >> (8 * i));
}
/// Appends the low `size` bytes of `value` (1..8), least significant first.
void append_le(std::vector<std::uint8_t>& out, std::uint64_t value, std::size_t size);
/// An UNSIGNED32 as its 4 bytes on the bus (CiA 301 §7.1.2): SDO download data of 1010h, 1020h,
/// 1F51h, ... The writer that goes with low_le32().
std::vector<std::uint8_t> le32_bytes(std::uint32_t value);

/// CRC-32 of IEEE 802.3 (reflected polynomial EDB88320h, initial and final value FFFFFFFFh), as
/// zlib's crc32() computes it: the checksum of config manager store files and of a program
/// download (1F56h). Not the SDO block CRC, which is CRC-16 (nmt::sdo_block_crc).
std::uint32_t crc32(std::span<const std::uint8_t> bytes);

/// 0..15 for a hex digit (either case), -1 for any other character.
namespace detail {
// A table, not three range tests: digits and letters mix in device files ("0x1A00"), and a
// lookup has no branch to mispredict.
inline constexpr std::array<std::int8_t, 256> kHexDigitValues = [] {
  std::array<std::int8_t, 256> t{};
  for (int c = 0; c < 256; ++c) {
    t[static_cast<std::size_t>(c)] =
        static_cast<std::int8_t>((c >= '0' && c <= '9')   ? c - '0'
                                 : (c >= 'a' && c <= 'f') ? c - 'a' + 10
                                 : (c >= 'A' && c <= 'F') ? c - 'A' + 10
                                                          : -1);
  }
  return t;
}();
}  // namespace detail

constexpr int hex_digit_value(char c) {
  return detail::kHexDigitValues[static_cast<unsigned char>(c)];
}

/// `text` read as hex digits only (no prefix), 1..max_digits of them (max_digits <= 16);
/// nullopt for an empty text, another character, or more digits.
std::optional<std::uint64_t> parse_hex_number(std::string_view text, std::size_t max_digits = 16);

}  // namespace cfg
