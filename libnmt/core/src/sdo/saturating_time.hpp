// Time arithmetic for deadlines that saturates instead of overflowing on absurd durations
// (a timeout of Duration::max() means "never").
#pragma once

#include <cstdint>
#include <limits>

#include "nmt/protocol/frame.hpp"

namespace nmt {

inline TimePoint later(TimePoint now, Duration d) {
  if (d.count() > 0 &&
      now.time_since_epoch().count() > std::numeric_limits<std::int64_t>::max() - d.count()) {
    return TimePoint::max();
  }
  return now + d;
}

}  // namespace nmt
