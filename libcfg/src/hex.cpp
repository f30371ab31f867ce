#include "cfg/hex.hpp"

namespace cfg {

std::string hex_digits(std::uint64_t value, int min_digits) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  char buf[16];
  int n = 0;
  do {
    buf[15 - n++] = kDigits[value & 0xF];
    value >>= 4;
  } while (value != 0);
  std::string out;
  if (min_digits > n) out.assign(static_cast<std::size_t>(min_digits - n), '0');
  out.append(buf + 16 - n, buf + 16);
  return out;
}

}  // namespace cfg
