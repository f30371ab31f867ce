// NMT flying master start-up and the watch over the active master (CiA 302-2 §3.7, §5.2-§5.5),
// and NMT master detection (§5.1) for self-starting devices and master-capable ones: the engine
// FlyingMasterProcess (flying_master.hpp describes it and its port). The COB-IDs and bytes are
// DSP 302 §5.5's, whose figures the 302-2 text lacks. The choices where the spec leaves room
// are listed in docs/master.md.
#include "master/flying_master.hpp"

#include <array>
#include <string>
#include <utility>

#include "master/master_text.hpp"

namespace nmt {

using Phase = FlyingMasterProcess::Phase;
using Cob = FlyingMasterCobId;

namespace {

CanFrame empty_frame(std::uint32_t id) {
  return CanFrame::make(id, {});
}

/// DSP 302 §5.5.1.1 / §5.5.1.3: byte 0 the priority level, byte 1 the node-ID.
CanFrame response_71(std::uint16_t priority, cfg::NodeId node) {
  const std::array<std::uint8_t, 2> bytes{static_cast<std::uint8_t>(priority), node.value()};
  return CanFrame::make(Cob::kMasterResponse, bytes);
}

/// CiA 302-2 §3.7 f/g/i, §5.4.1 and DSP 302 §5.5: an active master stays unless its priority
/// level is lower (a higher 1F90h sub 3 value, Table 48: 0 is high) than this device's. The
/// node-ID only orders the time slots within one negotiation (§5.3); comparing it too made a
/// master of the same level that came back reset the running network for nothing.
bool forces_negotiation(std::uint16_t active_priority, std::uint16_t own_priority) {
  return active_priority > own_priority;
}

/// How often a 76h that brought no reset is sent again before this device gives up forcing.
constexpr unsigned kForceTries = 3;

MasterEvent flying_event(MasterEvent::Kind kind, TimePoint at, std::optional<cfg::NodeId> node,
                         std::optional<std::uint16_t> priority, MasterEvent::FlyingMaster why) {
  auto e = master_event(kind, at, node);
  e.priority = priority;
  e.flying = why;
  return e;
}

}  // namespace

std::optional<TimePoint> FlyingMasterProcess::next_deadline() const {
  auto due = earliest(flying_.deadline, detection_.deadline);
  if (flying_.phase == Phase::Active) due = earliest(due, flying_.cycle_due);
  if (flying_.phase == Phase::Standby) due = earliest(due, flying_.heartbeat_due);
  return due;
}

std::optional<cfg::NodeId> FlyingMasterProcess::active_master() const {
  if (flying_.phase != Phase::Active && flying_.phase != Phase::Standby) return std::nullopt;
  return flying_.active;
}

void FlyingMasterProcess::stop() {
  flying_ = Flying{};
}

void FlyingMasterProcess::start(const FlyingTiming& timing, TimePoint now, Output& out) {
  timing_ = timing;
  const auto& t = timing_;
  const bool warm = flying_.warm;
  const bool forced = flying_.forced;
  const unsigned tries = flying_.force_tries;
  flying_ = Flying{};
  flying_.warm = warm;
  flying_.forced = forced;
  flying_.force_tries = tries;
  flying_.phase = Phase::Delay;
  // §3.7 b: wait the negotiation time delay, so devices that initialise at different speeds
  // all listen when the detection starts (DSP 302 §5.5.1.2).
  flying_.deadline = now + t.delay;
  port_.set_startup(StartupState::Negotiating);
  out.report(flying_event(
      MasterEvent::Kind::NegotiationBegan, now, node_, t.priority,
      {.reason = warm ? FlyingMasterReason::ResetCommunication : FlyingMasterReason::PowerOn,
       .own_priority = t.priority,
       .wait = t.delay}));
}

void FlyingMasterProcess::restart(TimePoint now) {
  // A reset communication of this device: boot-up and flying master start-up again, warm.
  flying_.phase = Phase::Delay;
  flying_.deadline.reset();
  flying_.warm = true;
  port_.restart(now);
}

void FlyingMasterProcess::wait(TimePoint now, Output& out, FlyingMasterReason why) {
  const auto& t = timing_;
  // §5.3: waiting time = priority level x priority time slot + node-ID x device time slot,
  // from the trigger (each trigger heard starts it again, DSP 302 §5.5.1.3).
  const auto wait = t.priority * t.priority_slot + node_.value() * t.node_slot;
  const bool began = flying_.phase != Phase::Negotiate;
  flying_.phase = Phase::Negotiate;
  flying_.deadline = now + wait;
  port_.set_startup(StartupState::Negotiating);
  if (began) {
    out.report(flying_event(
        MasterEvent::Kind::NegotiationBegan, now, node_, t.priority,
        {.reason = why, .own_priority = t.priority, .timeout = t.timeout, .wait = wait}));
  }
}

void FlyingMasterProcess::win(TimePoint now, Output& out) {
  const auto& t = timing_;
  flying_.phase = Phase::Active;
  flying_.deadline.reset();
  flying_.active = node_;
  flying_.active_priority = t.priority;
  flying_.forced = false;
  flying_.force_tries = 0;
  // §3.7 h: the winner answers the negotiation with its priority and node-ID (its frame goes
  // ahead of the start-up's NMT commands: the master sends those after its parts' frames) ...
  out.send(response_71(t.priority, node_));
  // ... and checks for other active masters every 1F90h sub 6 (§5.5.3).
  flying_.cycle_due.reset();
  if (t.cycle.count() > 0) flying_.cycle_due = now + t.cycle;
  out.report(
      flying_event(MasterEvent::Kind::ActiveMaster, now, node_, t.priority,
                   {.reason = FlyingMasterReason::NoBetterMaster, .own_priority = t.priority}));
  // §3.7 h: "enter the NMT master mode": NMT start-up goes on (§3.1 c onwards).
  port_.became_active(now, out);
}

void FlyingMasterProcess::standby(cfg::NodeId node, std::uint16_t priority, TimePoint now,
                                  Output& out, FlyingMasterReason why) {
  flying_.phase = Phase::Standby;
  flying_.deadline.reset();
  flying_.active = node;
  flying_.active_priority = priority;
  flying_.forced = false;
  flying_.force_tries = 0;
  // §5.5.2: the active master's heartbeat is watched, with 1016h's time for it (note 2), else
  // one derived from this device's own heartbeat period, which the network's masters share.
  flying_.heartbeat_due.reset();
  std::optional<Duration> watch = port_.heartbeat_time(node);
  const auto producer_ms = port_.own_heartbeat_ms();
  if (!watch && producer_ms != 0) {
    watch = std::chrono::milliseconds(2 * producer_ms + 100);
  }
  flying_.watch = watch;
  if (watch) flying_.heartbeat_due = now + *watch;
  port_.set_startup(StartupState::Standby);
  out.report(flying_event(MasterEvent::Kind::Standby, now, node, priority,
                          {.reason = why, .own_priority = timing_.priority, .watch = watch}));
}

void FlyingMasterProcess::force(TimePoint now, Output& out, cfg::NodeId node,
                                std::uint16_t priority) {
  const auto& t = timing_;
  // §3.7 g/i, §5.4: the active master has a lower priority: force a negotiation; it answers
  // with a reset communication of all nodes, which restarts this device too.
  out.send(empty_frame(Cob::kForceNegotiation));
  flying_.forced = true;
  ++flying_.force_tries;
  flying_.phase = Phase::Forced;
  flying_.deadline = now + t.timeout + t.delay;
  port_.set_startup(StartupState::Negotiating);
  out.report(
      flying_event(MasterEvent::Kind::ForceNegotiation, now, node, priority,
                   {.reason = FlyingMasterReason::LowerPriority, .own_priority = t.priority}));
}

void FlyingMasterProcess::master_response(std::uint16_t priority, cfg::NodeId node, TimePoint now,
                                          Output& out) {
  const auto& t = timing_;
  if (flying_.phase == Phase::Active) {
    // Another device says it is the master: two active masters (a healed split, or a 71h of
    // ours that did not reach it). Forcing makes the other reset all nodes, this device
    // included, and the negotiation decides again (§5.5.3).
    out.report(
        flying_event(MasterEvent::Kind::MultipleMasters, now, node, priority,
                     {.reason = FlyingMasterReason::AnsweredToo, .own_priority = t.priority}));
    out.send(empty_frame(Cob::kForceNegotiation));
    return;
  }
  if (flying_.phase == Phase::Standby && node == flying_.active) {
    flying_.active_priority = priority;  // the same master answering someone's detection
    if (flying_.watch) flying_.heartbeat_due = now + *flying_.watch;
    return;
  }
  if (!forces_negotiation(priority, t.priority)) {
    // §3.7 f: a master with a higher priority level, or the same level (only "lower then the own
    // priority" forces, §3.7 g/i): this device becomes an NMT slave.
    standby(node, priority, now, out,
            priority == t.priority ? FlyingMasterReason::SamePriority
                                   : FlyingMasterReason::HigherPriority);
    return;
  }
  // DSP 302 §5.5.2 implementation hint: no second force after one that a worse master won
  // again (timing parameters that do not order the masters), else the network never settles.
  if (flying_.forced && flying_.phase != Phase::Forced) {
    standby(node, priority, now, out, FlyingMasterReason::WonAgainAfterForce);
    // Remembered across the resets that follow (the winner's start-up resets all nodes, and
    // this device detects again after each): forgetting it here made every such reset force a
    // negotiation again, a livelock. Cleared when this device wins or yields to a better master.
    flying_.forced = true;
    return;
  }
  if (flying_.phase == Phase::Forced) return;  // the reset is on its way
  force(now, out, node, priority);
}

void FlyingMasterProcess::detect_master(std::optional<DetectionTiming> timing, TimePoint now) {
  detection_ = Detection{};
  if (!timing) {
    port_.queue_nmt(NmtCommand::Start, NmtTarget::all_nodes());
    return;
  }
  // §5.1: "after the CANopen device switched into the NMT state Pre-operational and an
  // additional time delay (1F91h sub 2)".
  detection_.timing = *timing;
  detection_.phase = Detection::Phase::Delay;
  detection_.deadline = now + timing->delay;
}

bool FlyingMasterProcess::detection_frame(const CanFrame& frame, TimePoint now, Output& out) {
  using P = Detection::Phase;
  if (detection_.phase == P::Detect && frame.id == Cob::kCapableResponse) {
    // DSP 302 §5.5.3.1: a device able to become NMT master exists; it starts the network.
    detection_ = Detection{};
    out.report(flying_event(MasterEvent::Kind::MasterDetection, now, std::nullopt, std::nullopt,
                            {.reason = FlyingMasterReason::CapableDeviceAnswered}));
    return true;
  }
  if (detection_.phase == P::Wait) {
    const auto command = parse_nmt_command(frame);
    if (command && command->target.all() && command->command == NmtCommand::Start) {
      // DSP 302 §5.5.3.1: the node-ID slots keep a group of self-starting devices from each
      // sending the start: one with a lower node-ID did.
      detection_ = Detection{};
      out.report(flying_event(MasterEvent::Kind::MasterDetection, now, std::nullopt, std::nullopt,
                              {.reason = FlyingMasterReason::OtherStartedAllNodes}));
      return false;
    }
  }
  return false;
}

void FlyingMasterProcess::detection_timer(TimePoint now, Output& out) {
  using P = Detection::Phase;
  if (!detection_.deadline || now < *detection_.deadline) return;
  detection_.deadline.reset();
  const auto& t = detection_.timing;
  switch (detection_.phase) {
    case P::Delay:
      out.send(empty_frame(Cob::kCapableRequest));
      detection_.phase = P::Detect;
      detection_.deadline = now + t.timeout;
      break;
    case P::Detect: {
      // §5.1: no answer: start remote node after node-ID x node time slot (1F91h sub 3).
      const auto wait = node_.value() * t.node_slot;
      detection_.phase = P::Wait;
      detection_.deadline = now + wait;
      out.report(flying_event(
          MasterEvent::Kind::MasterDetection, now, std::nullopt, std::nullopt,
          {.reason = FlyingMasterReason::NoCapableDevice, .timeout = t.timeout, .wait = wait}));
      break;
    }
    case P::Wait:
      detection_ = Detection{};
      port_.queue_nmt(NmtCommand::Start, NmtTarget::all_nodes());
      break;
    case P::Off:
      break;
  }
}

bool FlyingMasterProcess::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (frame.extended || frame.rtr || frame.error) return false;
  if (detection_.phase != Detection::Phase::Off && detection_frame(frame, now, out)) {
    return true;
  }
  // §5.1: every device capable of the NMT master mode answers NMT master detection.
  if (frame.id == Cob::kCapableRequest) {
    if (!port_.master_capable()) return false;
    out.send(empty_frame(Cob::kCapableResponse));
    return true;
  }
  if (flying_.phase == Phase::Off) return false;
  const auto& t = timing_;
  switch (frame.id) {
    case Cob::kActiveMasterRequest:
      // §5.2: only the active master answers.
      if (flying_.phase != Phase::Active) return false;
      out.send(response_71(t.priority, node_));
      return true;
    case Cob::kMasterResponse: {
      // The node-ID of the 71h sender is checked here, once (1..127, not this device).
      const auto sender = frame.dlc < 2 ? std::nullopt : cfg::NodeId::from(frame.data[1]);
      if (!sender || *sender == node_) return false;
      master_response(frame.data[0], *sender, now, out);
      return true;
    }
    case Cob::kNegotiationTrigger:
      if (flying_.phase == Phase::Active) {
        // A negotiation while this device is master (a 73h or 71h was lost): it answers as
        // the active master, so the others stand by (or force) instead of electing a second.
        out.send(response_71(t.priority, node_));
        return true;
      }
      // §5.3: "other CANopen devices ... shall immediately start their waiting time".
      wait(now, out, FlyingMasterReason::TriggerHeard);
      return true;
    case Cob::kForceNegotiation:
      // §5.4, §5.5.3: only the active master acts: reset communication of all nodes, itself
      // included, and the negotiation runs again.
      if (flying_.phase != Phase::Active) return false;
      out.report(
          flying_event(MasterEvent::Kind::MultipleMasters, now, std::nullopt, std::nullopt,
                       {.reason = FlyingMasterReason::ForceReceived, .own_priority = t.priority}));
      port_.reset_all_nodes();
      restart(now);
      return true;
    default:
      break;
  }
  if (const auto command = parse_nmt_command(frame)) {
    if (!command->target.addresses(node_)) return false;
    if (command->command == NmtCommand::ResetCommunication ||
        command->command == NmtCommand::ResetNode) {
      // DSP 302 §5.5.1.2: a reset makes every master-capable device negotiate again (warm).
      restart(now);
      return true;
    }
    // The active master alone sends NMT commands; the others obey them as slaves.
    if (flying_.phase == Phase::Active) return false;
    port_.obey(command->command, now, out);
    return true;
  }
  // §5.5.2: the active master's heartbeat (not its boot-up: a master that booted again has
  // to win a negotiation first).
  if (flying_.phase == Phase::Standby && flying_.active &&
      frame.id == kErrorControlCobIdBase + flying_.active->value() && frame.dlc == 1 &&
      frame.data[0] != 0 && flying_.watch) {
    flying_.heartbeat_due = now + *flying_.watch;
  }
  return false;
}

void FlyingMasterProcess::on_timer(TimePoint now, Output& out) {
  detection_timer(now, out);
  if (flying_.phase == Phase::Off) return;
  const auto& t = timing_;
  if (flying_.phase == Phase::Active && flying_.cycle_due && now >= *flying_.cycle_due) {
    // §5.5.3: the cyclic force, without resetting itself.
    out.send(empty_frame(Cob::kForceNegotiation));
    flying_.cycle_due.reset();
    if (t.cycle.count() > 0) flying_.cycle_due = now + t.cycle;
  }
  if (flying_.phase == Phase::Standby && flying_.heartbeat_due && now >= *flying_.heartbeat_due) {
    // §5.5.2: negotiation by a reset communication of all nodes (this device included).
    out.report(flying_event(MasterEvent::Kind::ActiveMasterLost, now, flying_.active,
                            flying_.active_priority,
                            {.reason = FlyingMasterReason::HeartbeatLost,
                             .own_priority = t.priority,
                             .watch = flying_.watch}));
    port_.reset_all_nodes();
    restart(now);
    return;
  }
  if (!flying_.deadline || now < *flying_.deadline) return;
  flying_.deadline.reset();
  switch (flying_.phase) {
    case Phase::Delay:
      // §3.7 c, §5.2: active NMT master detection.
      out.send(empty_frame(Cob::kActiveMasterRequest));
      flying_.phase = Phase::Detect;
      flying_.deadline = now + t.timeout;
      break;
    case Phase::Detect:
      if (!flying_.warm) {
        // §3.7 d: after power-on, reset communication of all nodes first (DSP 302 §5.5.1.2:
        // PDO traffic must not disturb the timing; this device resets too, warm).
        out.report(flying_event(MasterEvent::Kind::NegotiationBegan, now, node_, t.priority,
                                {.reason = FlyingMasterReason::NoActiveMasterAfterPowerOn,
                                 .own_priority = t.priority,
                                 .timeout = t.timeout}));
        port_.reset_all_nodes();
        restart(now);
        break;
      }
      // §3.7 e: after a reset communication, the negotiation.
      out.send(empty_frame(Cob::kNegotiationTrigger));
      wait(now, out, FlyingMasterReason::NoActiveMaster);
      break;
    case Phase::Negotiate:
      win(now, out);
      break;
    case Phase::Forced:
      // The reset did not come (a 76h lost, or a master that does not obey): detect again,
      // forcing at most kForceTries times in a row.
      if (flying_.force_tries < kForceTries) flying_.forced = false;
      out.send(empty_frame(Cob::kActiveMasterRequest));
      flying_.phase = Phase::Detect;
      flying_.deadline = now + t.timeout;
      break;
    default:
      break;
  }
}

}  // namespace nmt
