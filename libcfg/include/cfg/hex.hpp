// Hexadecimal text, the way CANopen documents and EDS files write numbers: upper-case digits.
// The one place of this formatting for libcfg, libnmt and the tools.
#pragma once

#include <cstdint>
#include <string>

namespace cfg {

/// Upper-case hex digits without prefix, zero-padded to at least `min_digits`:
/// hex_digits(0x1A, 4) == "001A", hex_digits(0x1A) == "1A".
std::string hex_digits(std::uint64_t value, int min_digits = 1);

/// The same with a "0x" prefix: hex(1000, 4) == "0x03E8".
inline std::string hex(std::uint64_t value, int min_digits = 1) {
  return "0x" + hex_digits(value, min_digits);
}

/// The characters of hex_digits(value, min_digits) written to `out` (no allocation, no
/// terminator), for writers that fill a buffer. `out` must have room for max(16, min_digits)
/// characters. Returns the end of what was written.
char* write_hex_digits(char* out, std::uint64_t value, int min_digits = 1);

}  // namespace cfg
