// NMT flying master start-up and the watch over the active master (CiA 302-2 §3.7, §5.2-§5.5),
// and NMT master detection (§5.1) for self-starting devices and master-capable ones; the
// COB-IDs and bytes are DSP 302 §5.5's, whose figures the 302-2 text lacks. The choices
// where the spec leaves room are listed at the top of nmt/nmt_master.hpp.
#include <array>
#include <string>
#include <utility>

#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;
using Phase = FlyingMaster::Phase;
using Cob = FlyingMasterCobId;

namespace {

CanFrame empty_frame(std::uint32_t id) {
  return CanFrame::make(id, {});
}

/// DSP 302 §5.5.1.1 / §5.5.1.3: byte 0 the priority level, byte 1 the node-ID.
CanFrame master_response(std::uint16_t priority, cfg::NodeId node) {
  const std::array<std::uint8_t, 2> bytes{static_cast<std::uint8_t>(priority), node.value()};
  return CanFrame::make(Cob::kMasterResponse, bytes);
}

/// CiA 302-2 §3.7 f/g/i, §5.4.1 and DSP 302 §5.5: an active master stays unless its priority
/// level is lower (a higher 1F90h sub 3 value, Table 48: 0 is high) than this device's. The
/// node-ID only orders the time slots within one negotiation (§5.3); comparing it too made a
/// master of the same level that came back reset the running network for nothing (issue 22).
bool forces_negotiation(std::uint16_t active_priority, std::uint16_t own_priority) {
  return active_priority > own_priority;
}

std::string ms_text(Duration d) {
  return std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(d).count()) + " ms";
}

std::string priority_text(std::uint16_t priority) {
  return "priority " + std::to_string(priority);
}

/// How often a 76h that brought no reset is sent again before this device gives up forcing.
constexpr unsigned kForceTries = 3;

}  // namespace

FlyingTiming NmtMaster::Impl::flying_timing() const {
  auto sub = [this](std::uint8_t s) { return value_of(obj::kFlyingMasterParameters, s); };
  auto ms = [](std::uint32_t v) { return Duration{std::chrono::milliseconds(v)}; };
  return {ms(sub(1)), ms(sub(2)), static_cast<std::uint16_t>(sub(3)),
          ms(sub(4)), ms(sub(5)), ms(sub(6))};
}

std::optional<TimePoint> NmtMaster::Impl::flying_deadline() const {
  auto due = earliest(flying.deadline, detection.deadline);
  if (flying.phase == Phase::Active) due = earliest(due, flying.cycle_due);
  if (flying.phase == Phase::Standby) due = earliest(due, flying.heartbeat_due);
  return due;
}

void NmtMaster::Impl::queue_reset_all(TimePoint /*now*/) {
  // §3.1 d: node-ID 0 unless a slave is to be kept alive; then every other node-ID (also
  // those not in 1F81h) individually, never the master itself.
  bool keep_alive = false;
  for (unsigned node = cfg::kMinNodeId; node <= cfg::kMaxNodeId; ++node) {
    const auto n = static_cast<std::uint8_t>(node);
    if (is_slave(n) && assignment(n).keep_alive()) keep_alive = true;
  }
  if (!keep_alive) {
    queue_nmt(NmtCommand::ResetCommunication, 0);
    return;
  }
  for (unsigned node = cfg::kMinNodeId; node <= cfg::kMaxNodeId; ++node) {
    const auto n = static_cast<std::uint8_t>(node);
    if (n == node_id.value() || (is_slave(n) && assignment(n).keep_alive())) continue;
    queue_nmt(NmtCommand::ResetCommunication, n);
  }
}

namespace {

MasterEvent flying_event(MasterEvent::Kind kind, TimePoint at, std::uint8_t node,
                         std::optional<std::uint16_t> priority, std::string text) {
  auto e = master_event(kind, at, node, std::move(text));
  e.priority = priority;
  return e;
}

}  // namespace

void NmtMaster::Impl::flying_begin(TimePoint now, Output& out) {
  const auto t = flying_timing();
  const bool warm = flying.warm;
  const bool forced = flying.forced;
  const unsigned tries = flying.force_tries;
  flying = FlyingMaster{};
  flying.warm = warm;
  flying.forced = forced;
  flying.force_tries = tries;
  flying.phase = Phase::Delay;
  // §3.7 b: wait the negotiation time delay, so devices that initialise at different speeds
  // all listen when the detection starts (DSP 302 §5.5.1.2).
  flying.deadline = now + t.delay;
  startup = StartupState::Negotiating;
  report(out, flying_event(MasterEvent::Kind::NegotiationBegan, now, node_id.value(), t.priority,
                           std::string("flying master start-up after ") +
                               (warm ? "a reset communication" : "power-on") +
                               ": active master detection in " + ms_text(t.delay)));
}

void NmtMaster::Impl::flying_restart(TimePoint now) {
  // A reset communication of this device: boot-up and flying master start-up again, warm.
  flying.phase = Phase::Delay;
  flying.deadline.reset();
  flying.warm = true;
  startup_due = now;
}

void NmtMaster::Impl::flying_wait(TimePoint now, Output& out, const std::string& why) {
  const auto t = flying_timing();
  // §5.3: waiting time = priority level x priority time slot + node-ID x device time slot,
  // from the trigger (each trigger heard starts it again, DSP 302 §5.5.1.3).
  const auto wait = t.priority * t.priority_slot + node_id.value() * t.node_slot;
  const bool began = flying.phase != Phase::Negotiate;
  flying.phase = Phase::Negotiate;
  flying.deadline = now + wait;
  startup = StartupState::Negotiating;
  if (began) {
    report(out, flying_event(MasterEvent::Kind::NegotiationBegan, now, node_id.value(), t.priority,
                             why + ": negotiation, waiting " + ms_text(wait)));
  }
}

void NmtMaster::Impl::flying_win(TimePoint now, Output& out) {
  const auto t = flying_timing();
  flying.phase = Phase::Active;
  flying.deadline.reset();
  flying.active = node_id.value();
  flying.active_priority = t.priority;
  flying.forced = false;
  flying.force_tries = 0;
  // §3.7 h: the winner answers the negotiation with its priority and node-ID ...
  out.send(master_response(t.priority, node_id));
  // ... and checks for other active masters every 1F90h sub 6 (§5.5.3).
  flying.cycle_due.reset();
  if (t.cycle.count() > 0) flying.cycle_due = now + t.cycle;
  report(out, flying_event(MasterEvent::Kind::ActiveMaster, now, node_id.value(), t.priority,
                           "active NMT master: no better master answered within the waiting "
                           "time (" +
                               priority_text(t.priority) + ")"));
  // §3.7 h: "enter the NMT master mode": NMT start-up goes on (§3.1 c onwards).
  begin_startup(now, out);
}

void NmtMaster::Impl::flying_standby(std::uint8_t node, std::uint16_t priority, TimePoint now,
                                     Output& out, const std::string& why) {
  flying.phase = Phase::Standby;
  flying.deadline.reset();
  flying.active = node;
  flying.active_priority = priority;
  flying.forced = false;
  flying.force_tries = 0;
  // §5.5.2: the active master's heartbeat is watched, with 1016h's time for it (note 2), else
  // one derived from this device's own heartbeat period, which the network's masters share.
  flying.heartbeat_due.reset();
  std::optional<Duration> watch = heartbeat_time(node);
  const auto producer_ms = value_of(obj::kProducerHeartbeatTime, 0);
  if (!watch && producer_ms != 0) {
    watch = std::chrono::milliseconds(2 * producer_ms + 100);
  }
  flying.watch = watch;
  if (watch) flying.heartbeat_due = now + *watch;
  startup = StartupState::Standby;
  report(out, flying_event(MasterEvent::Kind::Standby, now, node, priority,
                           node_text(node) + " is the active NMT master (" +
                               priority_text(priority) + "): " + why +
                               (watch ? "; watching its heartbeat (" + ms_text(*watch) + ")"
                                      : "; its heartbeat is not watched (no 1016h entry, 1017h "
                                        "is 0)")));
}

void NmtMaster::Impl::flying_force(TimePoint now, Output& out, std::uint8_t node,
                                   std::uint16_t priority) {
  const auto t = flying_timing();
  // §3.7 g/i, §5.4: the active master has a lower priority: force a negotiation; it answers
  // with a reset communication of all nodes, which restarts this device too.
  out.send(empty_frame(Cob::kForceNegotiation));
  flying.forced = true;
  ++flying.force_tries;
  flying.phase = Phase::Forced;
  flying.deadline = now + t.timeout + t.delay;
  startup = StartupState::Negotiating;
  report(out, flying_event(MasterEvent::Kind::ForceNegotiation, now, node, priority,
                           node_text(node) + " is master with " + priority_text(priority) +
                               ", lower than ours (" + priority_text(t.priority) +
                               "): force NMT flying master negotiation"));
}

void NmtMaster::Impl::flying_master_response(std::uint16_t priority, std::uint8_t node,
                                             TimePoint now, Output& out) {
  const auto t = flying_timing();
  if (flying.phase == Phase::Active) {
    // Another device says it is the master: two active masters (a healed split, or a 71h of
    // ours that did not reach it). Forcing makes the other reset all nodes, this device
    // included, and the negotiation decides again (§5.5.3).
    report(out, flying_event(MasterEvent::Kind::MultipleMasters, now, node, priority,
                             node_text(node) + " answered as active NMT master too (" +
                                 priority_text(priority) + "): forcing a negotiation"));
    out.send(empty_frame(Cob::kForceNegotiation));
    return;
  }
  if (flying.phase == Phase::Standby && node == flying.active) {
    flying.active_priority = priority;  // the same master answering someone's detection
    if (flying.watch) flying.heartbeat_due = now + *flying.watch;
    return;
  }
  if (!forces_negotiation(priority, t.priority)) {
    // §3.7 f: a master with a higher priority level, or the same level (only "lower then the own
    // priority" forces, §3.7 g/i): this device becomes an NMT slave.
    flying_standby(node, priority, now, out,
                   std::string(priority == t.priority ? "the same priority level as ours"
                                                      : "a higher priority level than ours") +
                       " (" + priority_text(t.priority) + ")");
    return;
  }
  // DSP 302 §5.5.2 implementation hint: no second force after one that a worse master won
  // again (timing parameters that do not order the masters), else the network never settles.
  if (flying.forced && flying.phase != Phase::Forced) {
    flying_standby(node, priority, now, out,
                   "worse than ours, but it won again after this device forced a negotiation");
    // Remembered across the resets that follow (the winner's start-up resets all nodes, and
    // this device detects again after each): forgetting it here made every such reset force a
    // negotiation again, a livelock. Cleared when this device wins or yields to a better master.
    flying.forced = true;
    return;
  }
  if (flying.phase == Phase::Forced) return;  // the reset is on its way
  flying_force(now, out, node, priority);
}

void NmtMaster::Impl::start_all_when_no_master(TimePoint now) {
  detection = MasterDetection{};
  if (!dict.has_object(obj::kSelfStartingNodesTiming)) {
    queue_nmt(NmtCommand::Start, 0);
    return;
  }
  // §5.1: "after the CANopen device switched into the NMT state Pre-operational and an
  // additional time delay (1F91h sub 2)".
  detection.phase = MasterDetection::Phase::Delay;
  detection.deadline = now + std::chrono::milliseconds(value_of(obj::kSelfStartingNodesTiming, 2));
}

bool NmtMaster::Impl::detection_frame(const CanFrame& frame, TimePoint now, Output& out) {
  using P = MasterDetection::Phase;
  if (detection.phase == P::Detect && frame.id == Cob::kCapableResponse) {
    // DSP 302 §5.5.3.1: a device able to become NMT master exists; it starts the network.
    detection = MasterDetection{};
    report(out, master_event(MasterEvent::Kind::MasterDetection, now, 0,
                             "an NMT master-capable device answered (74h): the network is left "
                             "to the NMT master"));
    return true;
  }
  if (detection.phase == P::Wait) {
    const auto command = parse_nmt_command(frame);
    if (command && command->node_id == 0 && command->command == NmtCommand::Start) {
      // DSP 302 §5.5.3.1: the node-ID slots keep a group of self-starting devices from each
      // sending the start: one with a lower node-ID did.
      detection = MasterDetection{};
      report(out, master_event(MasterEvent::Kind::MasterDetection, now, 0,
                               "another device started all nodes first"));
      return false;
    }
  }
  return false;
}

void NmtMaster::Impl::detection_timer(TimePoint now, Output& out) {
  using P = MasterDetection::Phase;
  if (!detection.deadline || now < *detection.deadline) return;
  detection.deadline.reset();
  auto ms = [this](std::uint8_t sub) {
    return Duration{std::chrono::milliseconds(value_of(obj::kSelfStartingNodesTiming, sub))};
  };
  switch (detection.phase) {
    case P::Delay:
      out.send(empty_frame(Cob::kCapableRequest));
      detection.phase = P::Detect;
      detection.deadline = now + ms(1);
      break;
    case P::Detect: {
      // §5.1: no answer: start remote node after node-ID x node time slot (1F91h sub 3).
      const auto wait = node_id.value() * ms(3);
      detection.phase = P::Wait;
      detection.deadline = now + wait;
      report(out, master_event(MasterEvent::Kind::MasterDetection, now, 0,
                               "no NMT master-capable device answered within " + ms_text(ms(1)) +
                                   ": start all nodes in " + ms_text(wait)));
      break;
    }
    case P::Wait:
      detection = MasterDetection{};
      queue_nmt(NmtCommand::Start, 0);
      break;
    case P::Off:
      break;
  }
}

bool NmtMaster::Impl::flying_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (frame.extended || frame.rtr || frame.error) return false;
  if (detection.phase != MasterDetection::Phase::Off && detection_frame(frame, now, out)) {
    return true;
  }
  const auto config = startup_config();
  // §5.1: every device capable of the NMT master mode answers NMT master detection.
  if (frame.id == Cob::kCapableRequest) {
    if (!config.is_master()) return false;
    out.send(empty_frame(Cob::kCapableResponse));
    return true;
  }
  if (flying.phase == Phase::Off) return false;
  const auto t = flying_timing();
  switch (frame.id) {
    case Cob::kActiveMasterRequest:
      // §5.2: only the active master answers.
      if (flying.phase != Phase::Active) return false;
      out.send(master_response(t.priority, node_id));
      return true;
    case Cob::kMasterResponse:
      if (frame.dlc < 2 || !cfg::is_node_id(frame.data[1]) || frame.data[1] == node_id.value()) {
        return false;
      }
      flying_master_response(frame.data[0], frame.data[1], now, out);
      return true;
    case Cob::kNegotiationTrigger:
      if (flying.phase == Phase::Active) {
        // A negotiation while this device is master (a 73h or 71h was lost): it answers as
        // the active master, so the others stand by (or force) instead of electing a second.
        out.send(master_response(t.priority, node_id));
        return true;
      }
      // §5.3: "other CANopen devices ... shall immediately start their waiting time".
      flying_wait(now, out, "negotiation trigger (72h) heard");
      return true;
    case Cob::kForceNegotiation:
      // §5.4, §5.5.3: only the active master acts: reset communication of all nodes, itself
      // included, and the negotiation runs again.
      if (flying.phase != Phase::Active) return false;
      report(out, flying_event(MasterEvent::Kind::MultipleMasters, now, 0, std::nullopt,
                               "force NMT flying master negotiation (76h) received: another "
                               "master is active or has a higher priority; reset communication "
                               "of all nodes"));
      queue_reset_all(now);
      flying_restart(now);
      return true;
    default:
      break;
  }
  if (const auto command = parse_nmt_command(frame)) {
    if (command->node_id != 0 && command->node_id != node_id.value()) return false;
    if (command->command == NmtCommand::ResetCommunication ||
        command->command == NmtCommand::ResetNode) {
      // DSP 302 §5.5.1.2: a reset makes every master-capable device negotiate again (warm).
      flying_restart(now);
      return true;
    }
    // The active master alone sends NMT commands; the others obey them as slaves.
    if (flying.phase == Phase::Active) return false;
    apply_own_command(command->command, now, out);
    return true;
  }
  // §5.5.2: the active master's heartbeat (not its boot-up: a master that booted again has
  // to win a negotiation first).
  if (flying.phase == Phase::Standby && frame.id == kErrorControlCobIdBase + flying.active &&
      frame.dlc == 1 && frame.data[0] != 0 && flying.watch) {
    flying.heartbeat_due = now + *flying.watch;
  }
  return false;
}

void NmtMaster::Impl::flying_timer(TimePoint now, Output& out) {
  detection_timer(now, out);
  if (flying.phase == Phase::Off) return;
  const auto t = flying_timing();
  if (flying.phase == Phase::Active && flying.cycle_due && now >= *flying.cycle_due) {
    // §5.5.3: the cyclic force, without resetting itself.
    out.send(empty_frame(Cob::kForceNegotiation));
    flying.cycle_due.reset();
    if (t.cycle.count() > 0) flying.cycle_due = now + t.cycle;
  }
  if (flying.phase == Phase::Standby && flying.heartbeat_due && now >= *flying.heartbeat_due) {
    // §5.5.2: negotiation by a reset communication of all nodes (this device included).
    report(out, flying_event(MasterEvent::Kind::ActiveMasterLost, now, flying.active,
                             flying.active_priority,
                             "heartbeat of the active NMT master " + node_text(flying.active) +
                                 " lost: reset communication of all nodes, negotiation"));
    queue_reset_all(now);
    flying_restart(now);
    return;
  }
  if (!flying.deadline || now < *flying.deadline) return;
  flying.deadline.reset();
  switch (flying.phase) {
    case Phase::Delay:
      // §3.7 c, §5.2: active NMT master detection.
      out.send(empty_frame(Cob::kActiveMasterRequest));
      flying.phase = Phase::Detect;
      flying.deadline = now + t.timeout;
      break;
    case Phase::Detect:
      if (!flying.warm) {
        // §3.7 d: after power-on, reset communication of all nodes first (DSP 302 §5.5.1.2:
        // PDO traffic must not disturb the timing; this device resets too, warm).
        report(out,
               flying_event(MasterEvent::Kind::NegotiationBegan, now, node_id.value(), t.priority,
                            "no active master answered within " + ms_text(t.timeout) +
                                " after power-on: reset communication of all nodes"));
        queue_reset_all(now);
        flying_restart(now);
        break;
      }
      // §3.7 e: after a reset communication, the negotiation.
      out.send(empty_frame(Cob::kNegotiationTrigger));
      flying_wait(now, out, "no active master answered within " + ms_text(t.timeout));
      break;
    case Phase::Negotiate:
      flying_win(now, out);
      break;
    case Phase::Forced:
      // The reset did not come (a 76h lost, or a master that does not obey): detect again,
      // forcing at most kForceTries times in a row.
      if (flying.force_tries < kForceTries) flying.forced = false;
      out.send(empty_frame(Cob::kActiveMasterRequest));
      flying.phase = Phase::Detect;
      flying.deadline = now + t.timeout;
      break;
    default:
      break;
  }
}

}  // namespace nmt
