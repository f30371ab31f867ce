// Private to libcfg: reading the keys of [DynamicChannels] (CiA DSP 302 §8.4) into segments, with
// diagnostics, shared by the reader (which reports each fault at its key's line) and
// cfg::dynamic_channels_of (which reads the section kept in the model, silently).
#pragma once

#include <functional>
#include <span>
#include <string>
#include <string_view>

#include "cfg/dynamic_channels.hpp"

namespace cfg::detail {

struct DynamicChannelsKey {
  std::string_view key;
  std::string_view value;
  int line = 0;
};

/// Where the faults go: `error` for what makes a segment unusable, `warn` for what can be read
/// anyway (the reader makes it a warning, or an error in strict mode). Either may be empty.
struct DynamicChannelsReport {
  std::function<void(int line, std::string message)> error;
  std::function<void(int line, std::string message)> warn;
};

/// The segments of the keys of one [DynamicChannels] section in file order (of a key given
/// twice the later wins). `section_line` is where faults of the whole section are reported.
DynamicChannels read_dynamic_channels(std::span<const DynamicChannelsKey> keys, int section_line,
                                      const DynamicChannelsReport& report);

}  // namespace cfg::detail
