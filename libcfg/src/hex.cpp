#include "cfg/hex.hpp"

#include <bit>

namespace cfg {

char* write_hex_digits(char* out, std::uint64_t value, int min_digits) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  const int n = value == 0 ? 1 : static_cast<int>((std::bit_width(value) + 3) / 4);  // >= 1 digit
  for (int i = n; i < min_digits; ++i) *out++ = '0';
  for (int i = n - 1; i >= 0; --i) *out++ = kDigits[(value >> (4 * i)) & 0xF];
  return out;
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
