// Test helpers for EDS/DCF texts written in tests: parsing with a file name, and the line a
// piece of text stands on (diagnostics name lines).
#pragma once

#include <algorithm>
#include <string>
#include <string_view>

#include "cfg/device_file.hpp"

namespace test_support {

inline cfg::ReadResult parse_text(std::string_view text, cfg::ReadMode mode,
                                  std::string file_name) {
  cfg::ReadOptions options;
  options.mode = mode;
  options.file_name = std::move(file_name);
  return cfg::parse_device_description(text, options);
}

/// 1-based line of the first occurrence of `needle` in `text`; -1 if there is none.
inline int line_of(std::string_view text, std::string_view needle) {
  const std::size_t at = text.find(needle);
  if (at == std::string_view::npos) return -1;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

}  // namespace test_support
