// The start-up's boot-up gate of the NMT master: after the reset communication of all nodes
// (CiA 302-2 §3.1 d) no SDO request of a boot goes out before every reset slave sent its boot-up
// or the wait for them (MasterOptions::boot.boot_up_wait) ends. Boot-ups have the lowest priority
// and a device's SDO answers would queue behind its own boot-up; the boots of all slaves start
// together (§3.3, Annex A). With bus load pacing (MasterOptions::pacing.bitrate) the gate also
// opens when no boot-up came for kQuiet: the other boot-ups were lost or are late, and pacing
// leaves them room. The gate only keeps time; the master opens it for the boots waiting at it
// (BootSlaveProcess::pass_boot_up_gate). Private to the library.
#pragma once

#include <chrono>
#include <optional>

#include "nmt/protocol/frame.hpp"

namespace nmt {

class BootUpGate {
 public:
  /// Paced: the gate opens when no boot-up came for this long.
  static constexpr Duration kQuiet = std::chrono::milliseconds(20);

  /// The start-up reset all nodes: closed until `until` (now + boot_up_wait); `paced`: the
  /// quiet rule applies.
  void close(TimePoint until, bool paced) {
    until_ = until;
    paced_ = paced;
    quiet_.reset();
  }
  /// Open for all: every reset slave booted up, or a boot's wait for its boot-up ran out.
  void open() {
    until_.reset();
    quiet_.reset();
  }
  bool closed() const { return until_.has_value(); }
  /// Until when a boot that starts after a reset waits for the boot-up: the gate's time while
  /// it is closed, else `now` + `wait`.
  TimePoint wait_until(TimePoint now, Duration wait) const { return until_.value_or(now + wait); }

  /// A slave booted up at the closed gate: paced, the quiet time counts from now.
  void booted_up(TimePoint now) {
    if (closed() && paced_) quiet_ = now + kQuiet;
  }
  /// The quiet time passed without a boot-up: the master opens the gate.
  bool quiet_over(TimePoint now) const { return quiet_ && now >= *quiet_; }
  /// When the quiet time ends (nullopt: no quiet time runs).
  std::optional<TimePoint> next_deadline() const { return quiet_; }

 private:
  std::optional<TimePoint> until_;
  std::optional<TimePoint> quiet_;
  bool paced_ = false;
};

}  // namespace nmt
