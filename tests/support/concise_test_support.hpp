// Test helpers for concise DCF tests: readable gtest output for cfg::ObjectWrite
// ("1400sub01 = 02 02 00 80"), short constructors for values written by hand, file reading.
#pragma once

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <ostream>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"

namespace cfg {

inline void PrintTo(const ObjectWrite& write, std::ostream* os) {
  char head[32];
  std::snprintf(head, sizeof head, "%04Xsub%02X =", write.index, write.sub_index);
  *os << head;
  for (std::uint8_t b : write.data) {
    char byte[4];
    std::snprintf(byte, sizeof byte, " %02X", b);
    *os << byte;
  }
}

}  // namespace cfg

namespace test_support {

/// Little-endian bytes of `value`, `size` bytes wide (CiA 301 §7.1 encoding).
inline std::vector<std::uint8_t> le(std::uint64_t value, int size) {
  std::vector<std::uint8_t> out;
  for (int i = 0; i < size; ++i) out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
  return out;
}
inline cfg::ObjectWrite u8(std::uint16_t index, std::uint8_t sub, std::uint8_t value) {
  return {index, sub, le(value, 1)};
}
inline cfg::ObjectWrite u16(std::uint16_t index, std::uint8_t sub, std::uint16_t value) {
  return {index, sub, le(value, 2)};
}
inline cfg::ObjectWrite u32(std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
  return {index, sub, le(value, 4)};
}

/// The bytes of a file; empty when it cannot be read (tests check existence first).
inline std::vector<std::uint8_t> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Text of a file; empty when it cannot be read.
inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace test_support
