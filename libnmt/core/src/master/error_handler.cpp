// NmtMaster: what the master does with the error control messages it hears, the boot-up
// handler (CiA 302-2 §4.3) and the error handler (§4.2, DSP 302 §5.3) that act on a boot-up or
// a lost heartbeat or guarding of a slave.
#include "master/nmt_master_impl.hpp"

namespace nmt {

// --- error control messages, the boot-up handler (§4.3) and the error handler (§4.2) ---

void NmtMaster::Impl::on_error_control(const ErrorControlMessage& message, TimePoint now,
                                       Output& out) {
  const auto node = message.node_id;  // 1..127: parse_error_control checked it
  if (node == node_id) return;
  if (message.byte == 0) {
    on_boot_up(node, now, out);
    return;
  }
  const auto state = message.state();
  if (!state) return;
  const auto& b = boots[node];
  if (b.awaits_guard_reply()) {
    set_known_state(node, KnownState::in(*state), now, out);
    boots.with(node, [&](BootSlaveProcess& p) { p.on_guard_reply(*state, now, out); });
    return;
  }
  // A heartbeat has bit 7 clear; a guarding reply may have it set (the toggle bit).
  if (!message.toggle()) {
    slaves[node].heartbeat_at = now;
    if (b.awaits_heartbeat()) {
      set_known_state(node, KnownState::in(*state), now, out);
      boots.with(node, [&](BootSlaveProcess& p) { p.on_heartbeat(*state, now, out); });
      return;
    }
  }
  set_known_state(node, KnownState::in(*state), now, out);
}

void NmtMaster::Impl::on_boot_up(cfg::NodeId node, TimePoint now, Output& out) {
  sdo_manager.node_booted(node, now, out);  // an SRD that booted forgot its entries
  const bool assigned = is_slave(node);
  auto e = master_event(MasterEvent::Kind::BootUp, now, node);
  e.assigned = assigned;
  report(out, std::move(e));
  auto& s = slaves[node];
  s.heartbeat_at.reset();
  set_known_state(node, KnownState::in(NmtState::PreOperational), now, out);
  if (!assigned) return;  // §3.1: unlisted devices are the application's concern
  if (boots.with(node, [&](BootSlaveProcess& b) { return b.on_boot_up(now, out); })) {
    const auto& b = boots[node];
    // The boot-up the gate waited for: when it was the last one, the gate opens for all.
    if (b.at_boot_up_gate() && b.boot_up_seen()) boots.open_gate(now, out);
    return;
  }
  if (startup.state == StartupState::Off || startup.state == StartupState::NotMaster ||
      !acts_as_master() || startup.state == StartupState::ExecutingLss) {
    return;  // Execute LSS: the reset of all nodes follows
  }
  stop_error_control(node);
  // DSP 302 §5.4: a slave whose state was set by request NMT is not rebooted automatically.
  if (s.held) return;
  // §4.3 / Table 20: 1F81h bit 2 allows configuring and starting it again.
  if (assignment(node).boot_slave()) start_boot(node, false, now, out);
}

void NmtMaster::Impl::report_loss(cfg::NodeId node, bool heartbeat, TimePoint now, Output& out) {
  report(out, master_event(
                  heartbeat ? MasterEvent::Kind::HeartbeatLost : MasterEvent::Kind::GuardingLost,
                  now, node));
  set_known_state(node, KnownState::missing(), now, out);
}

void NmtMaster::Impl::error_handler(cfg::NodeId node, bool heartbeat, TimePoint now, Output& out) {
  report_loss(node, heartbeat, now, out);
  if (!is_slave(node) || slaves[node].held) return;
  const auto a = assignment(node);
  const auto config = startup_config();
  // Figure 12 and the note of DSP 302 §5.3: for a mandatory slave, "stop all nodes" with 1F80h
  // bit 6, else "reset all nodes" with bit 4 (the master included: start-up runs again).
  if (a.mandatory() && config.stop_all_nodes()) {
    queue_nmt(NmtCommand::Stop, NmtTarget::all_nodes());
    return;
  }
  if (a.mandatory() && config.reset_all_nodes()) {
    queue_nmt(NmtCommand::ResetNode, NmtTarget::all_nodes());
    startup.due = now;
    return;
  }
  stop_error_control(node);
  // Table 12, bit 4 = 0: reset node of that mandatory slave; its boot-up starts its boot again
  // (boot-up handler).
  if (a.mandatory()) {
    queue_nmt(NmtCommand::ResetNode, node);
    return;
  }
  // An optional slave: start process boot NMT slave again (DSP 302 §5.3), if 1F81h bit 2
  // allows; its heartbeat or guarding is started again by the boot.
  if (a.boot_slave()) start_boot(node, false, now, out);
}

void NmtMaster::Impl::dispatch_error_control(TimePoint now, Output& out) {
  for (const auto& f : outputs.error_control.frames) out.send(f);
  for (const auto& e : outputs.error_control.events) {
    const bool heartbeat = e.protocol == ErrorControlProtocol::Heartbeat;
    if (e.kind == ErrorControlEvent::Kind::Resolved) {
      auto resolved = master_event(MasterEvent::Kind::ErrorControlResolved, now, e.node);
      resolved.heartbeat = heartbeat;
      report(out, std::move(resolved));
      continue;
    }
    // §4.1: no first heartbeat within the consumer time ends start error control with status
    // K; any other loss of the master's own error control is the error handler's (§4.2). A node
    // watched for the SDO manager alone (an SRD; a slave whose error control the master stopped
    // after a boot error) is reported lost and missing (1F82h), but the master does not act on
    // an error control it does not run.
    if (heartbeat && boots[e.node].awaits_first_heartbeat()) {
      boots.with(e.node, [&](BootSlaveProcess& b) { b.on_heartbeat_timeout(now, out); });
    } else if (e.watchers.master) {
      error_handler(e.node, heartbeat, now, out);
    } else {
      report_loss(e.node, heartbeat, now, out);
    }
    // DSP 302 §7.2.1-§7.2.2: the manager learns the loss of a node it watches (an SRD, a slave
    // of an SRD with Req EC: 1F11h), whoever else watches it.
    if (e.watchers.manager) sdo_manager.node_lost(e.node, now, out);
  }
}

}  // namespace nmt
