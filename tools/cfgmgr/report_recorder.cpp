// The --report page's data from a run (report_recorder.hpp).
#include "report_recorder.hpp"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "cfg/hex.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/protocol/frame_bits.hpp"

namespace cfgmgr {
namespace {

using report::MarkKind;
using report::PhaseKind;

/// Buckets of the load curve at most: enough for a smooth curve 860 pixels wide.
constexpr std::size_t kMaxBuckets = 512;

// The boot steps (CiA 302-2 §3) as the page groups them; nullopt for the steps that end a boot.
std::optional<PhaseKind> phase_of(nmt::BootStep step) {
  using S = nmt::BootStep;
  switch (step) {
    case S::AwaitBootUp:
      return PhaseKind::BootUp;
    case S::Identify:
    case S::CheckNmtState:
    case S::CheckSoftware:
      return PhaseKind::Identify;
    case S::UpdateSoftware:
      return PhaseKind::Program;
    case S::VerifyConfiguration:
      return PhaseKind::Verify;
    case S::Restore:
      return PhaseKind::Restore;
    case S::Download:
      return PhaseKind::Download;
    case S::Save:
      return PhaseKind::Save;
    case S::ApplicationStep:
      return PhaseKind::Application;
    case S::StartErrorControl:
      return PhaseKind::ErrorControl;
    case S::RetryWait:
      return PhaseKind::RetryWait;
    case S::Idle:
    case S::Booted:
    case S::Failed:
      break;
  }
  return std::nullopt;
}

// Buckets twice as wide: each pair of neighbours merged.
void widen(std::vector<double>& bits, std::int64_t& bucket_us) {
  std::vector<double> wide((bits.size() + 1) / 2, 0);
  for (std::size_t i = 0; i < bits.size(); ++i) wide[i / 2] += bits[i];
  bits = std::move(wide);
  bucket_us *= 2;
}

std::string download_title(std::size_t written, std::size_t total, unsigned boot_try) {
  return "configuration download: " + std::to_string(written) + " of " + std::to_string(total) +
         (total == 1 ? " entry" : " entries") + " written (try " + std::to_string(boot_try) + ")";
}

}  // namespace

ReportRecorder::ReportRecorder(std::vector<Node> nodes, std::uint32_t bitrate_bps, bool assumed)
    : bitrate_bps_(bitrate_bps != 0 ? bitrate_bps : 1), assumed_(assumed) {
  std::sort(nodes.begin(), nodes.end(),
            [](const Node& a, const Node& b) { return a.node_id < b.node_id; });
  for (auto& n : nodes) {
    Lane lane;
    lane.node = std::move(n);
    lanes_.push_back(std::move(lane));
  }
}

ReportRecorder::Lane* ReportRecorder::find(std::uint8_t node) {
  for (auto& lane : lanes_) {
    if (lane.node.node_id == node) return &lane;
  }
  return nullptr;
}

void ReportRecorder::close_phase(Lane& lane, nmt::TimePoint at) {
  if (!lane.phases.empty() && !lane.phases.back().end) lane.phases.back().end = at;
}

void ReportRecorder::open_phase(Lane& lane, PhaseKind kind, nmt::TimePoint at, std::string title) {
  close_phase(lane, at);
  lane.phases.push_back(OpenPhase{kind, at, std::nullopt, std::move(title), {}});
}

void ReportRecorder::observe(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  if (e.kind == K::StartupComplete || e.kind == K::StartupHalted ||
      e.kind == K::StartupAwaitsApplication || e.kind == K::NotMaster) {
    master_marks_.push_back({MarkKind::Master, e.at, nmt::describe(e)});
    return;
  }
  if (!e.node_id) return;
  Lane* lane = find(e.node_id->value());
  if (lane == nullptr) return;
  OpenPhase* open =
      !lane->phases.empty() && !lane->phases.back().end ? &lane->phases.back() : nullptr;
  switch (e.kind) {
    case K::BootStepChanged: {
      if (e.boot_try != lane->boot_try) {
        // A new try of boot NMT slave (CiA 302-2 §3.3): counted by its number, as push does.
        if (lane->boot_try != 0) {
          ++lane->retries;
          lane->marks.push_back(
              {MarkKind::Retry, e.at, "try " + std::to_string(e.boot_try) + " of the boot began"});
        }
        lane->boot_try = e.boot_try;
      }
      if (e.step == nmt::BootStep::Download && open != nullptr &&
          open->kind == PhaseKind::Download) {
        // The same download, one more entry written.
        if (e.entry_written) open->entries.push_back(e.at);
        open->title = download_title(e.written, e.total, e.boot_try);
        break;
      }
      const auto kind = phase_of(e.step);
      if (!kind) {
        close_phase(*lane, e.at);
        break;
      }
      if (!lane->began) lane->began = e.at;
      open_phase(*lane, *kind, e.at,
                 *kind == PhaseKind::Download ? download_title(e.written, e.total, e.boot_try)
                                              : std::string(nmt::to_string(e.step)) + " (try " +
                                                    std::to_string(e.boot_try) + ")");
      break;
    }
    case K::ProgramProgress:
      if (open != nullptr && open->kind == PhaseKind::Program) {
        open->title = "program download: " + std::to_string(e.bytes) + " of " +
                      std::to_string(e.total) + " bytes confirmed";
      }
      break;
    case K::SlaveBooted:
      close_phase(*lane, e.at);
      lane->ended = e.at;
      lane->event_failed = false;
      lane->event_result = e.configured         ? "configured"
                           : e.no_configuration ? "no_configuration"
                                                : "skipped";
      lane->event_message = nmt::describe(e);
      lane->entries = e.written;
      break;
    case K::BootError:
      close_phase(*lane, e.at);
      lane->marks.push_back({MarkKind::Error, e.at, nmt::describe(e)});
      lane->event_failed = true;
      lane->event_result = e.error ? "error " + std::string(1, nmt::letter(*e.error)) : "error";
      lane->event_message = nmt::describe_boot_error(e);
      lane->ended = e.at;
      if (!e.final) {
        open_phase(*lane, PhaseKind::RetryWait, e.at,
                   "waiting to retry after " + lane->event_result);
      }
      break;
    case K::SlaveStateChanged:
      if (e.state == nmt::NmtState::Operational) {
        open_phase(*lane, PhaseKind::Operational, e.at, "operational (started)");
      } else if (open != nullptr && open->kind == PhaseKind::Operational) {
        close_phase(*lane, e.at);
      }
      break;
    case K::BootUp:
      lane->marks.push_back({MarkKind::BootUp, e.at, nmt::describe(e)});
      break;
    case K::HeartbeatLost:
    case K::GuardingLost:
      lane->marks.push_back({MarkKind::Error, e.at, nmt::describe(e)});
      break;
    case K::Emergency:
      if (e.emergency && e.emergency->emcy.error_code != nmt::emcy_code::kErrorReset) {
        ++lane->emergencies;
      }
      lane->marks.push_back({MarkKind::Emergency, e.at, nmt::describe(e)});
      break;
    case K::EmergencyFlood:
      if (e.emergency) lane->emergencies += e.emergency->suppressed;
      lane->marks.push_back({MarkKind::Emergency, e.at, nmt::describe(e)});
      break;
    default:
      break;
  }
}

void ReportRecorder::on_frame(const nmt::CanFrame& frame, nmt::TimePoint at) {
  ++frames_;
  if (frame.error && error_frames_.size() < kMaxErrorFrameMarks) {
    error_frames_.push_back(
        {MarkKind::ErrorFrame, at, "error frame (class " + cfg::hex(frame.id, 8) + ")"});
  } else if (frame.error) {
    ++error_frames_unmarked_;
  }
  // The frame occupied the bus for its bits at the bit rate before `at` (its end, as the
  // simulated bus and a receiving driver stamp it): its bits go to the buckets of that time.
  const unsigned bits = nmt::frame_bits(frame).total();
  const auto length_us = static_cast<std::int64_t>(static_cast<double>(bits) * 1e6 /
                                                   static_cast<double>(bitrate_bps_));
  const nmt::TimePoint began = at - std::chrono::microseconds(length_us);
  if (!origin_) origin_ = began;
  const auto since_us = [this](nmt::TimePoint t) {
    return std::max<std::int64_t>(
        0, std::chrono::duration_cast<std::chrono::microseconds>(t - *origin_).count());
  };
  const std::int64_t from_us = since_us(began);
  const std::int64_t to_us = std::max(since_us(at), from_us + 1);
  while (static_cast<std::size_t>(to_us / bucket_us_) >= kMaxBuckets) widen(bits_, bucket_us_);
  const auto last = static_cast<std::size_t>(to_us / bucket_us_);
  if (bits_.size() <= last) bits_.resize(last + 1, 0);
  // Each bucket its share of the frame's time; the bits are counted as doubles of a bit.
  for (auto i = static_cast<std::size_t>(from_us / bucket_us_); i <= last; ++i) {
    const std::int64_t lo = std::max(from_us, static_cast<std::int64_t>(i) * bucket_us_);
    const std::int64_t hi = std::min(to_us, static_cast<std::int64_t>(i + 1) * bucket_us_);
    if (hi > lo) {
      bits_[i] += static_cast<double>(bits) * static_cast<double>(hi - lo) /
                  static_cast<double>(to_us - from_us);
    }
  }
}

void ReportRecorder::set_result(const report::NodeRow& row) {
  if (Lane* lane = find(row.node_id)) lane->result = row;
}

report::ReportData ReportRecorder::finish(nmt::TimePoint start, nmt::TimePoint end,
                                          report::ReportData header) const {
  const auto seconds = [start](nmt::TimePoint at) {
    return std::chrono::duration<double>(at - start).count();
  };
  report::ReportData data = std::move(header);
  data.duration_s = seconds(end);
  data.frames = frames_;
  data.bitrate_bps = bitrate_bps_;
  data.bitrate_assumed = assumed_;
  for (const Lane& lane : lanes_) {
    report::NodeRow row;
    if (lane.result) {
      row = *lane.result;
    } else {
      row.result = lane.event_result;
      row.failed = lane.event_failed;
      row.message = lane.event_message;
      row.entries = lane.entries;
      row.emergencies = lane.emergencies;
      row.retries = lane.retries;
      if (lane.began && lane.ended) row.seconds = seconds(*lane.ended) - seconds(*lane.began);
    }
    row.node_id = lane.node.node_id;
    row.name = lane.node.name;
    row.mandatory = lane.node.mandatory;
    row.phases.clear();
    row.marks.clear();
    for (const OpenPhase& p : lane.phases) {
      report::Phase phase{p.kind, seconds(p.begin), seconds(p.end.value_or(end)), p.title, {}};
      for (const auto at : p.entries) phase.entries_s.push_back(seconds(at));
      row.phases.push_back(std::move(phase));
    }
    for (const TimedMark& m : lane.marks) row.marks.push_back({m.kind, seconds(m.at), m.title});
    data.nodes.push_back(std::move(row));
  }
  for (const TimedMark& m : master_marks_) {
    data.master_marks.push_back({m.kind, seconds(m.at), m.title});
  }
  for (const TimedMark& m : error_frames_) {
    data.bus_marks.push_back({m.kind, seconds(m.at), m.title});
  }
  if (error_frames_unmarked_ > 0) {
    data.bus_marks.back().title +=
        "; " + std::to_string(error_frames_unmarked_) + " more error frames after it, not marked";
  }
  if (origin_) {
    // The buckets up to the end of the run (the quiet ones after the last frame too), merged
    // as on_frame merges them while there are too many.
    std::vector<double> bits = bits_;
    std::int64_t bucket_us = bucket_us_;
    const std::int64_t span_us = std::max<std::int64_t>(
        0, std::chrono::duration_cast<std::chrono::microseconds>(end - *origin_).count());
    while (static_cast<std::size_t>(span_us / bucket_us) >= kMaxBuckets) widen(bits, bucket_us);
    bits.resize(std::max(bits.size(), static_cast<std::size_t>(span_us / bucket_us) + 1), 0);
    const double bucket_s = static_cast<double>(bucket_us) / 1e6;
    const double origin_s = seconds(*origin_);
    for (std::size_t i = 0; i < bits.size(); ++i) {
      const double begin = origin_s + static_cast<double>(i) * bucket_s;
      data.load.push_back({begin, begin + bucket_s, bits[i] / (bucket_s * bitrate_bps_)});
    }
  }
  return data;
}

}  // namespace cfgmgr
