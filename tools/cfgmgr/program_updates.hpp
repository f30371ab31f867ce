// What the software update in the boot (DSP 302 §4 figure 7, §9 program download) did per node,
// from the NMT master's events, for the reports of `cfgmgr push` and `cfgmgr master`: the step
// UpdateSoftware begins one, ProgramProgress says how far the image is, and SlaveBooted (or
// BootError I) carries the master's account (MasterEvent::program: 1F52h before and after,
// bytes, when it began and ended). The failure's words are the master's G/H/I text.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "cfg/network.hpp"
#include "cfg/program_image.hpp"
#include "nmt/master/nmt_master.hpp"

namespace cfgmgr {

struct ProgramUpdate {
  bool updated = false;     ///< downloaded, started, and 1F52h then matched 1F53h/1F54h
  bool failed = false;      ///< the boot ended with an error during or after the download
  std::uint64_t bytes = 0;  ///< of the image, confirmed so far (all of it once downloaded)
  std::uint64_t total = 0;  ///< the image's size
  nmt::TimePoint began{};   ///< UpdateSoftware began (stop, clear, 1F50h, start)
  std::optional<nmt::TimePoint> ended;        ///< start confirmed (CheckSoftware again) or error
  std::optional<cfg::ProgramVersion> before;  ///< 1F52h before the update
  std::optional<cfg::ProgramVersion> after;   ///< 1F52h after it (nullopt: not read again)
  /// A CiA 302-3 node (1F55h expectation): 1F56h sub 1 before and after, in place of the
  /// versions (which stay nullopt).
  std::optional<std::uint32_t> identification_before;
  std::optional<std::uint32_t> identification_after;
  /// The device refused clear (1F51h = 3) with this abort and the download went on
  /// (MasterEvent::ProgramClearRefused, a DSP 302 v3.2.1 device); nullopt: clear was accepted.
  std::optional<cfg::SdoAbort> clear_refused;
  double seconds() const;
};

class ProgramUpdates {
 public:
  /// Nothing tracked without a network (no images, no expected versions).
  ProgramUpdates() = default;
  explicit ProgramUpdates(std::shared_ptr<const cfg::Network> network)
      : network_(std::move(network)) {}

  /// Follows `e`; returns the line for people once a node's update succeeded ("node 3: program
  /// updated: 1012 bytes in 0.072 s, now 2026-11-27 08:15:00.000 (1F52h 15671, 29700000)"), and
  /// when the device refused clear (the master's text: "node 3: program clear (1F51h sub 01h =
  /// 3) refused: 0x06090031 (...); the download goes on").
  std::optional<std::string> observe(const nmt::MasterEvent& e);
  /// The node's last update this run; nullptr when it had none.
  const ProgramUpdate* find(std::uint8_t node) const;
  /// `--json`'s "program" of a node: {"updated", "before", "after", "identification_before",
  /// "identification_after", "bytes", "seconds", "clear_refused"} (a version as {"date_days",
  /// "time_ms", "text"}, null for a CiA 302-3 node; an identification as a number, null for a
  /// DSP 302 node; clear_refused the abort in words, null when clear was accepted), or null
  /// when the node had no update.
  std::string json(std::uint8_t node) const;

 private:
  std::shared_ptr<const cfg::Network> network_;
  std::map<std::uint8_t, ProgramUpdate> updates_;
};

}  // namespace cfgmgr
