// The master's side of its SDO transfers (SdoTransferScheduler, sdo_transfer_scheduler.hpp):
// the scheduler's port, the routing of its events to their owners, and settle(), which after
// every call dispatches the transfers' results, sends due NMT commands, moves start-up on and
// then hands out the call's SDO requests.
#include <utility>
#include <variant>

#include "cfg/object_address.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace {

// MasterEvent::ProgramProgress: `done` of the 1F50h image's `total` bytes confirmed.
MasterEvent program_progress(cfg::NodeId node, std::size_t done, std::size_t total, TimePoint now) {
  auto e = master_event(MasterEvent::Kind::ProgramProgress, now, node);
  e.step = BootStep::UpdateSoftware;
  e.bytes = done;
  e.total = total;
  return e;
}

}  // namespace

// --- the scheduler's port ---

bool NmtMaster::Impl::TransferPort::default_sdo_given_out(cfg::NodeId node) const {
  return m.sdo_manager.default_sdo_given_out(node);
}

bool NmtMaster::Impl::TransferPort::boot_try_runs(cfg::NodeId node, std::uint64_t try_id) const {
  const auto& b = m.boots[node];
  return b.running() && b.try_id() == try_id;
}

bool NmtMaster::Impl::TransferPort::heard_from(cfg::NodeId node) const {
  return m.slaves[node].known_state.kind == KnownState::Kind::InState;
}

// --- routing ---

void NmtMaster::Impl::route_transfer_events(TimePoint now, Output& out) {
  using Scheduler = SdoTransferScheduler;
  // By index: routing a result starts transfers, which append frames (never events) to
  // outputs.transfers.
  for (std::size_t i = 0; i < outputs.transfers.events.size(); ++i) {
    auto event = std::move(outputs.transfers.events[i]);
    if (const auto* p = std::get_if<Scheduler::ProgramProgress>(&event)) {
      report(out, program_progress(p->node, p->done, p->total, now));
      continue;
    }
    auto& finished = std::get<Scheduler::Finished>(event);
    const auto node = finished.node;
    const auto& result = finished.result;
    if (const auto* manager = std::get_if<Scheduler::Manager>(&finished.owner)) {
      sdo_manager.on_transfer_result(manager->tag, result, now, out);
    } else if (const auto* application = std::get_if<Scheduler::Application>(&finished.owner)) {
      auto e = master_event(MasterEvent::Kind::SdoFinished, now, node);
      e.sdo = result;
      e.sdo->id = application->id;
      report(out, std::move(e));
    } else {
      // Of a try that still runs (the scheduler drops those of ended tries).
      boots.with(node, [&](BootSlaveProcess& b) { b.on_sdo_result(result, now, out); });
    }
  }
  outputs.transfers.events.clear();
}

void NmtMaster::Impl::settle(TimePoint now, Output& out) {
  // The call's SDO requests stay in outputs.transfers until the end: the NMT commands of the call
  // (each round's flush_nmt) go out ahead of them, by output order (§6.1 queue,
  // nmt_command_queue.hpp).
  for (;;) {
    if (transfers.collect(now)) {
      while (transfers.dispatch_next(now, outputs.transfers)) route_transfer_events(now, out);
      continue;
    }
    transfers.release_held(now, outputs.transfers);
    transfers.pump(now, outputs.transfers);
    sdo_manager.pump(now, out);
    if (startup.state == StartupState::BootingSlaves) check_startup(now, out);
    flush_nmt(now, out);
    if (transfers.settled()) break;
  }
  transfers.report_progress(outputs.transfers);
  route_transfer_events(now, out);
  for (const auto& f : outputs.transfers.frames) out.send(f);
  outputs.transfers.frames.clear();
  // Node guarding started in this call (boot's start error control, the SDO manager's watch,
  // request node guarding) has its first request due at `now` (NodeGuardingMaster::guard): the
  // error control service sends it here, last, after the call's NMT commands and SDO requests,
  // where it has always gone: a slave that boot starts is started before its first guarding
  // request, so its first reply says operational (CiA 302-2 §3.4 part 3 e before g-l). (A request
  // that fell due before on_timer came goes with it: engine.hpp rule 3.)
  outputs.error_control.clear();
  error_control.send_due_requests(now, outputs.error_control);
  dispatch_error_control(now, out);
}

}  // namespace nmt
