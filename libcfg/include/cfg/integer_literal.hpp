// Unsigned integer literals as CiA 306 writes them (§4.6.3: "0x" hexadecimal, a leading 0 for
// octal as in C, else decimal), also accepted by the tools for numbers on the command line. The
// one parser of this syntax; value.hpp builds $NODEID sums and signed values on it.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace cfg {

struct IntegerLiteral {
  std::uint64_t value = 0;
  bool is_hex = false;  ///< written with 0x (a bit pattern, for signed types)
};

enum class IntegerLiteralError : std::uint8_t {
  Malformed,   ///< empty, "0x" alone, a sign, a digit outside the base, inner spaces
  OutOfRange,  ///< more than 64 bits
};

/// Parses the whole of `text` (no surrounding spaces, no sign, no suffix).
/// "0x1F" -> 31 (hex), "017" -> 15 (octal), "0" -> 0, "12" -> 12.
struct IntegerLiteralResult {
  std::optional<IntegerLiteral> literal;
  IntegerLiteralError error = IntegerLiteralError::Malformed;  ///< when !literal
};
IntegerLiteralResult parse_integer_literal(std::string_view text);

}  // namespace cfg
