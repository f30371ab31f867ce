// The shared vocabulary of both libraries: object addresses, little-endian bytes, hex digits and
// integer literals, CRC-32 (headers object_address.hpp, bytes.hpp, integer_literal.hpp).

#include <zlib.h>

#include <algorithm>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/object_address.hpp"

namespace cfg {

std::string to_string(ObjectAddress address) {
  return hex_digits(address.index, 4) + "h sub " + hex_digits(address.sub_index, 2) + "h";
}

std::string object_name(std::uint16_t index) {
  return hex_digits(index, 4) + "h";
}

void append_le(std::vector<std::uint8_t>& out, std::uint64_t value, std::size_t size) {
  assert(size >= 1 && size <= 8);
  for (std::size_t i = 0; i < size; ++i) out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
}

std::vector<std::uint8_t> le32_bytes(std::uint32_t value) {
  std::vector<std::uint8_t> out;
  append_le(out, value, 4);
  return out;
}

std::uint32_t crc32(std::span<const std::uint8_t> bytes) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  // zlib takes uInt lengths: feed large inputs in pieces.
  while (!bytes.empty()) {
    const std::size_t n = std::min<std::size_t>(bytes.size(), 1U << 30);
    crc = ::crc32(crc, bytes.data(), static_cast<uInt>(n));
    bytes = bytes.subspan(n);
  }
  return static_cast<std::uint32_t>(crc);
}

std::optional<std::uint64_t> parse_hex_number(std::string_view text, std::size_t max_digits) {
  if (text.empty() || text.size() > max_digits || text.size() > 16) return std::nullopt;
  std::uint64_t v = 0;
  for (char c : text) {
    const int d = hex_digit_value(c);
    if (d < 0) return std::nullopt;
    v = v << 4 | static_cast<std::uint64_t>(d);
  }
  return v;
}

IntegerLiteralResult parse_integer_literal(std::string_view text) {
  int base = 10;
  std::string_view digits = text;
  if (text.size() >= 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    digits = text.substr(2);
  } else if (text.size() >= 2 && text[0] == '0') {
    base = 8;
    digits = text.substr(1);
  }
  IntegerLiteralResult result;
  if (digits.empty()) return result;  // "", "0x"
  // One pass: digits checked and accumulated together (this runs for nearly every value of a
  // device file). A value past 64 bits is out of range only if every digit is valid.
  const auto b = static_cast<std::uint64_t>(base);
  std::uint64_t value = 0;
  // Up to 16 hex, 21 octal or 19 decimal digits cannot pass 64 bits: no check per digit then.
  const std::size_t safe_digits = base == 16 ? 16 : base == 8 ? 21 : 19;
  if (digits.size() <= safe_digits) {
    for (char c : digits) {
      const int d = hex_digit_value(c);
      if (d < 0 || d >= base) return result;  // "12abc", "08", "-1", "+1"
      value = value * b + static_cast<std::uint64_t>(d);
    }
    result.literal = IntegerLiteral{value, base == 16};
    return result;
  }
  bool overflow = false;
  for (char c : digits) {
    const int d = hex_digit_value(c);
    if (d < 0 || d >= base) return result;  // "12abc", "08", "-1", "+1"
    const auto digit = static_cast<std::uint64_t>(d);
    // GCC and clang builtins: no division per digit.
    if (__builtin_mul_overflow(value, b, &value) || __builtin_add_overflow(value, digit, &value)) {
      overflow = true;
    }
  }
  if (overflow) {
    result.error = IntegerLiteralError::OutOfRange;
    return result;
  }
  IntegerLiteral lit;
  lit.is_hex = base == 16;
  lit.value = value;
  result.literal = lit;
  return result;
}

}  // namespace cfg
