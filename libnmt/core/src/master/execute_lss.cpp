// Execute LSS (execute_lss.hpp): the start-up pass and the looks for unconfigured devices, the
// node-ID each found device gets, and the MasterEvents the LssProcedure's events become.
#include "master/execute_lss.hpp"

#include <string>
#include <utility>

#include "master/master_text.hpp"

namespace nmt {

using Kind = LssProcedureEvent::Kind;

namespace {

// What became of the device of a scan's Assigned or Skipped event, with the LSS master's timeout
// for an unanswered service.
MasterEvent::Lss lss_outcome(const LssProcedureEvent& e, Duration timeout) {
  return {.outcome = e.outcome.value_or(LssScanOutcome::NoNodeId),
          .error_code = e.error_code,
          .spec_error = e.spec_error,
          .timeout = timeout};
}

}  // namespace

void ExecuteLssProcess::start(TimePoint now, Output& out) {
  stop();
  reported_.clear();
  phase_ = Phase::Startup;
  begin_scan(now, out);
}

void ExecuteLssProcess::watch(TimePoint now) {
  if (phase_ != Phase::Off && phase_ != Phase::Idle) return;  // a pass or look runs
  phase_ = Phase::Idle;
  next_look_.reset();
  if (period_ > Duration{0}) next_look_ = now + period_;
}

void ExecuteLssProcess::stop() {
  // A fresh LssProcedure: the running service's answers no longer match anything it waits for.
  lss_ = LssProcedure(lss_.options());
  phase_ = Phase::Off;
  next_look_.reset();
}

bool ExecuteLssProcess::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (phase_ == Phase::Off || phase_ == Phase::Idle) return false;
  lss_out_.clear();
  const bool taken = lss_.on_frame(frame, now, lss_out_);
  forward(now, out);
  return taken;
}

void ExecuteLssProcess::on_timer(TimePoint now, Output& out) {
  if (phase_ == Phase::Idle) {
    if (!next_look_ || now < *next_look_) return;
    next_look_ = now + period_;
    if (!port_.may_look()) return;
    // Identify non-configured remote slave: one frame, answered (50h) by every device without
    // a node-ID; the scan (the slaves' addresses confirmed, then the rest searched bit by bit)
    // only when one answers.
    lss_out_.clear();
    // The LssProcedure is idle between looks, so the start cannot fail; were it so, no look.
    if (lss_.any_unconfigured(now, lss_out_)) phase_ = Phase::Probe;
    forward(now, out);
    return;
  }
  if (phase_ == Phase::Off) return;
  lss_out_.clear();
  lss_.on_timer(now, lss_out_);
  forward(now, out);
}

std::optional<TimePoint> ExecuteLssProcess::next_deadline() const {
  switch (phase_) {
    case Phase::Off:
      return std::nullopt;
    case Phase::Idle:
      return next_look_;
    default:
      return lss_.next_deadline();
  }
}

void ExecuteLssProcess::begin_scan(TimePoint now, Output& out) {
  chosen_.clear();
  assigned_ = 0;
  lss_out_.clear();
  auto started = lss_.scan([this](const LssAddress& address) { return choose(address); }, now,
                           lss_out_, port_.known_addresses());
  if (!started) {
    // The LssProcedure is idle here (stopped, or its look ended), so this cannot happen; were
    // it so, the pass or look ends at once.
    LssProcedureEvent e;
    e.procedure = LssProcedureKind::Scan;
    // Failed without a service's event: the scan could not start
    // (MasterEvent::LssScan::Stop::CouldNotStart).
    e.kind = Kind::Failed;
    e.at = now;
    scan_ended(e, now, out);
    return;
  }
  forward(now, out);
}

std::optional<cfg::NodeId> ExecuteLssProcess::choose(const LssAddress& address) {
  const auto node = port_.slave_with(address);
  if (node) chosen_.insert_or_assign(address, *node);
  return node;
}

void ExecuteLssProcess::forward(TimePoint now, Output& out) {
  for (const auto& f : lss_out_.frames) out.send(f);
  // handle() may start the next service into lss_out_: take the events out first.
  auto events = std::move(lss_out_.events);
  lss_out_.events.clear();
  for (const auto& e : events) handle(e, now, out);
}

void ExecuteLssProcess::handle(const LssProcedureEvent& e, TimePoint now, Output& out) {
  if (e.procedure == LssProcedureKind::AnyUnconfigured) {
    if (e.found > 0) {
      phase_ = Phase::Scan;
      begin_scan(now, out);
    } else {
      phase_ = Phase::Idle;
    }
    return;
  }
  if (e.procedure != LssProcedureKind::Scan) return;
  switch (e.kind) {
    case Kind::Assigned: {
      ++assigned_;
      const cfg::NodeId node = e.node_id.value();  // Assigned always names it
      auto m = master_event(MasterEvent::Kind::LssAssigned, e.at, node);
      m.lss_address = e.address;
      m.lss = lss_outcome(e, lss_.options().timeout);
      out.report(std::move(m));
      return;
    }
    case Kind::Skipped: {
      const auto chosen = chosen_.find(e.address);
      if (chosen != chosen_.end()) {
        // The device is a slave's, but it refused or did not answer configure node-ID.
        auto m = master_event(MasterEvent::Kind::LssFailed, e.at, chosen->second);
        m.lss_address = e.address;
        m.lss = lss_outcome(e, lss_.options().timeout);
        out.report(std::move(m));
        return;
      }
      if (phase_ != Phase::Startup && !reported_.insert(e.address).second) return;
      auto m = master_event(MasterEvent::Kind::LssUnmatched, e.at, std::nullopt);
      m.lss_address = e.address;
      m.lss = lss_outcome(e, lss_.options().timeout);
      out.report(std::move(m));
      return;
    }
    default:
      scan_ended(e, now, out);
      return;
  }
}

void ExecuteLssProcess::scan_ended(const LssProcedureEvent& e, TimePoint now, Output& out) {
  const bool startup = phase_ == Phase::Startup;
  using Stop = MasterEvent::LssScan::Stop;
  auto m = master_event(MasterEvent::Kind::LssScanEnded, e.at, std::nullopt);
  m.lss_scan = MasterEvent::LssScan{.found = e.found,
                                    .assigned = assigned_,
                                    .stopped = e.kind == Kind::Done ? Stop::None
                                               : e.step             ? Stop::DeviceStoppedAnswering
                                                                    : Stop::CouldNotStart,
                                    .part = e.step ? e.step->part : std::uint8_t{0}};
  out.report(std::move(m));
  phase_ = Phase::Idle;
  next_look_.reset();
  if (period_ > Duration{0}) next_look_ = now + period_;
  if (startup) port_.pass_ended(now, out);
}

}  // namespace nmt
