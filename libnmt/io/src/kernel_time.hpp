// Conversions between the kernel's struct timespec and the microsecond time of libnmt, shared by
// the socket drivers (socketcan_bus.cpp, udp_bus.cpp). Private to libnmt/io.
#pragma once

#include <time.h>

#include <cstdint>

#include "nmt/protocol/frame.hpp"

namespace nmt::detail {

/// A wait for ppoll/nanosleep; a negative duration waits not at all.
inline timespec to_timespec(Duration d) {
  if (d.count() < 0) d = Duration::zero();
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(d.count() / 1'000'000);
  ts.tv_nsec = static_cast<long>((d.count() % 1'000'000) * 1000);
  return ts;
}

/// A kernel stamp (SO_TIMESTAMPNS, CLOCK_REALTIME) as microseconds since the Unix epoch.
inline TimePoint from_timespec(const timespec& ts) {
  return TimePoint{Duration{static_cast<std::int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000}};
}

}  // namespace nmt::detail
