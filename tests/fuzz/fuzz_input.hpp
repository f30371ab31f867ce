// The fuzzer's input as the targets read it: one byte at a time, zeros once it is used up (so a
// short input still decodes into whole operations).
#pragma once

#include <cstddef>
#include <cstdint>

namespace fuzz {

struct Input {
  const std::uint8_t* data;
  std::size_t size;
  std::size_t pos = 0;
  bool empty() const { return pos >= size; }
  std::uint8_t next() { return pos < size ? data[pos++] : 0; }
};

}  // namespace fuzz
