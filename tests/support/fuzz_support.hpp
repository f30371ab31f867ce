// What the libFuzzer targets of tests/fuzz share: a check that stops with the failed condition
// and its line (so a crash report says which promise broke), and the input read byte by byte
// (0 once it is used up).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#define check(condition) fuzz_support::check_at((condition), #condition, __LINE__)

namespace fuzz_support {

inline void check_at(bool ok, const char* what, int line) {
  if (ok) return;
  std::fprintf(stderr, "check failed at line %d: %s\n", line, what);
  std::abort();
}

struct Input {
  const std::uint8_t* data;
  std::size_t size;
  std::size_t pos = 0;
  bool empty() const { return pos >= size; }
  std::uint8_t next() { return pos < size ? data[pos++] : 0; }
};

}  // namespace fuzz_support
