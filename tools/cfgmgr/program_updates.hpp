// What the software update in the boot (DSP 302 §4 figure 7, §9 program download) did per node,
// from the NMT master's events, for the reports of `cfgmgr push` and `cfgmgr master`: the steps
// CheckSoftware -> UpdateSoftware -> CheckSoftware -> (the rest of the boot) mean "program
// updated"; a boot error during or right after UpdateSoftware is the failure, which the
// master's G/H/I words describe (the step and the SDO abort).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "cfg/network.hpp"
#include "cfg/program_image.hpp"
#include "nmt/nmt_master.hpp"

namespace cfgmgr {

struct ProgramUpdate {
  bool updated = false;     ///< downloaded, started, and 1F52h then matched 1F53h/1F54h
  bool failed = false;      ///< the boot ended with an error during or after the download
  std::uint64_t bytes = 0;  ///< of the image, confirmed so far (all of it once downloaded)
  std::uint64_t total = 0;  ///< the image's size
  nmt::TimePoint began{0};  ///< UpdateSoftware began (stop, clear, 1F50h, start)
  std::optional<nmt::TimePoint> ended;  ///< start confirmed (CheckSoftware again) or error
  /// 1F52h before the update: the master's events do not carry it (nullopt).
  std::optional<cfg::ProgramVersion> before;
  std::optional<cfg::ProgramVersion> after;  ///< 1F52h after it: the expected version
  double seconds() const;
};

class ProgramUpdates {
 public:
  /// Nothing tracked without a network (no images, no expected versions).
  ProgramUpdates() = default;
  explicit ProgramUpdates(std::shared_ptr<const cfg::Network> network)
      : network_(std::move(network)) {}

  /// Follows `e`; returns the line for people once a node's update succeeded ("node 3: program
  /// updated: 1012 bytes in 0.072 s, now 2026-11-27 08:15:00.000 (1F52h 15671, 29700000)").
  std::optional<std::string> observe(const nmt::MasterEvent& e);
  /// The node's last update this run; nullptr when it had none.
  const ProgramUpdate* find(std::uint8_t node) const;
  /// `--json`'s "program" of a node: {"updated", "before", "after", "bytes", "seconds"} (a
  /// version as {"date_days", "time_ms", "text"}), or null when the node had no update.
  std::string json(std::uint8_t node) const;

 private:
  std::shared_ptr<const cfg::Network> network_;
  std::map<std::uint8_t, ProgramUpdate> updates_;
};

}  // namespace cfgmgr
