// The address of a value in an object dictionary, and the one way messages write it:
// "1017h sub 00h" (CiA 301 writes indices and sub-indices in hex with an 'h' suffix), or "1017h"
// for a whole object. Every library and tool message uses these.
#pragma once

#include <compare>
#include <cstdint>
#include <string>

namespace cfg {

struct ObjectAddress {
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  constexpr bool operator==(const ObjectAddress&) const = default;
  // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy 14 flags the 0 of the defaulted compare
  constexpr auto operator<=>(const ObjectAddress&) const = default;
  /// One number for maps and sets: index << 8 | sub-index.
  constexpr std::uint32_t key() const { return std::uint32_t{index} << 8 | sub_index; }
};

/// "1017h sub 00h".
std::string to_string(ObjectAddress address);
/// "1017h".
std::string object_name(std::uint16_t index);

}  // namespace cfg
