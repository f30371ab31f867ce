#include "cfg/hex.hpp"

#include <algorithm>
#include <bit>

namespace cfg {

char* write_hex_digits(char* out, std::uint64_t value, int min_digits) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  const int digits = value == 0 ? 1 : static_cast<int>((std::bit_width(value) + 3) / 4);
  char* const end = out + std::max(digits, min_digits);
  for (char* p = end; p != out; value >>= 4) *--p = kDigits[value & 0xF];  // pads with '0'
  return end;
}

std::string hex_digits(std::uint64_t value, int min_digits) {
  char buf[16];
  const auto n = static_cast<int>(write_hex_digits(buf, value, 1) - buf);
  std::string out;
  if (min_digits > n) out.assign(static_cast<std::size_t>(min_digits - n), '0');
  out.append(buf, static_cast<std::size_t>(n));
  return out;
}

}  // namespace cfg
