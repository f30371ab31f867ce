// What the --report page of push and master shows (html_report.hpp), gathered during the run:
// each node's boot steps, errors, retries and EMCYs from the master's events, the bus load and
// error frames from every frame on the bus (RunTraces::frames), and the result table.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "html_report.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/protocol/frame.hpp"

namespace cfgmgr {

class ReportRecorder {
 public:
  struct Node {
    std::uint8_t node_id = 0;
    std::string name;
    bool mandatory = false;
  };

  /// Records the lanes of `nodes` (events of other nodes are left out); the bus load is taken at
  /// `bitrate_bps` (`assumed`: not known to be the bus's).
  ReportRecorder(std::vector<Node> nodes, std::uint32_t bitrate_bps, bool assumed);

  /// A master event, at its own time (MasterEvent::at).
  void observe(const nmt::MasterEvent& e);
  /// A frame on the bus at `at` (the engines' clock): its bits (nmt::frame_bits, stuff bits
  /// included) count to the load; an error frame is marked, the first kMaxErrorFrameMarks of
  /// them (a bus in an error storm sends thousands a second: the rest are counted in the last
  /// mark's title, so a long run's page stays small).
  static constexpr std::size_t kMaxErrorFrameMarks = 200;
  void on_frame(const nmt::CanFrame& frame, nmt::TimePoint at);
  /// on_frame of this recorder as a RunTraces::frames sink (the recorder must outlive the run).
  std::function<void(const nmt::CanFrame&, nmt::TimePoint)> frame_sink() {
    return [this](const nmt::CanFrame& frame, nmt::TimePoint at) { on_frame(frame, at); };
  }

  /// Replaces what the events told of a node's result with a table's (push's): result,
  /// failed, message, entries, emergencies, retries and seconds of `row`; its lane stays.
  void set_result(const report::NodeRow& row);

  /// The page's data for a run from `start` to `end`; `header` gives tool, network, bus, ok
  /// and outcome (its nodes, load and marks are filled here).
  report::ReportData finish(nmt::TimePoint start, nmt::TimePoint end,
                            report::ReportData header) const;

 private:
  // A phase or mark in absolute time until finish() makes seconds of it.
  struct OpenPhase {
    report::PhaseKind kind;
    nmt::TimePoint begin;
    std::optional<nmt::TimePoint> end;
    std::string title;
    std::vector<nmt::TimePoint> entries;
  };
  struct TimedMark {
    report::MarkKind kind;
    nmt::TimePoint at;
    std::string title;
  };
  struct Lane {
    Node node;
    std::vector<OpenPhase> phases;
    std::vector<TimedMark> marks;
    unsigned boot_try = 0;
    std::optional<nmt::TimePoint> began;
    std::optional<nmt::TimePoint> ended;
    std::optional<report::NodeRow> result;  // set_result's
    std::string event_result = "not booted";
    std::string event_message;
    bool event_failed = false;
    std::size_t entries = 0;
    std::uint64_t emergencies = 0;
    unsigned retries = 0;
  };

  Lane* find(std::uint8_t node);
  static void close_phase(Lane& lane, nmt::TimePoint at);
  static void open_phase(Lane& lane, report::PhaseKind kind, nmt::TimePoint at, std::string title);

  std::vector<Lane> lanes_;
  std::vector<TimedMark> master_marks_;
  std::vector<TimedMark> error_frames_;      // the first kMaxErrorFrameMarks
  std::uint64_t error_frames_unmarked_ = 0;  // those after them, counted only
  std::uint32_t bitrate_bps_;
  bool assumed_;
  // The bus load: bits per bucket of `bucket_us_` from `origin_` (a frame's bits shared by the
  // buckets its time on the bus falls in); when the run outgrows kMaxBuckets, neighbours are
  // merged and the bucket doubles, so a long run stays small.
  std::optional<nmt::TimePoint> origin_;
  std::int64_t bucket_us_ = 1000;
  std::vector<double> bits_;
  std::uint64_t frames_ = 0;
};

}  // namespace cfgmgr
