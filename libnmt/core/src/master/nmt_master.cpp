// NmtMaster: the public calls, NMT start-up (CiA 302-2 §3.1), the slave states the NMT command
// queue's commands set (the queue and its inhibit time, §6.1: nmt_command_queue.hpp), and the
// routing of frames and time to the parts. The boot-up handler and the error handler are in
// error_handler.cpp. Boot NMT slave is an engine per node (boot_slave_process.hpp, its port in
// boot_port.cpp), the objects and request NMT/guarding in master_dictionary.cpp, the SDO
// transfers in sdo_transfer_scheduler.hpp (the master's side in master_transfers.cpp), the texts
// of the enums and events in master_text.cpp.
#include "nmt/master/nmt_master.hpp"

#include <algorithm>
#include <bitset>
#include <utility>

#include "cfg/hex.hpp"
#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

/// The state a slave is in after a command, as far as the master can tell.
KnownState state_after(NmtCommand command) {
  switch (command) {
    case NmtCommand::Start:
      return KnownState::in(NmtState::Operational);
    case NmtCommand::Stop:
      return KnownState::in(NmtState::Stopped);
    case NmtCommand::EnterPreOperational:
      return KnownState::in(NmtState::PreOperational);
    case NmtCommand::ResetNode:
    case NmtCommand::ResetCommunication:
      return KnownState::unknown();  // unknown until its boot-up
  }
  return KnownState::unknown();
}

}  // namespace

// --- construction ---

NmtMaster::Impl::Impl(cfg::NodeId id, MasterOptions opts, LocalDictionary dictionary)
    : node_id(id),
      options(std::move(opts)),
      dict(std::move(dictionary)),
      server(dict, SdoServerConfig::from_dictionary(dict)),
      producer(id),
      sdo_manager(dict, ports.manager, id, manager_settings(options, server.config())) {}

cfg::Result<NmtMaster> NmtMaster::create(const cfg::DeviceDescription& description,
                                         cfg::NodeId node_id, MasterOptions options) {
  if (auto valid = options.validate(); !valid) return valid.error();
  auto dict = LocalDictionary::from_device(description, node_id);
  if (!dict) return dict.error();
  Impl::add_missing_objects(dict.value());
  Impl::add_flying_master_objects(dict.value(), node_id);
  if (auto checked = Impl::check_configuration_values(dict.value()); !checked) {
    return checked.error();
  }
  auto impl = std::make_unique<Impl>(node_id, std::move(options), std::move(dict.value()));
  impl->install_hooks();
  impl->sdo_manager.install();
  return NmtMaster(std::move(impl));
}

NmtMaster::NmtMaster(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
NmtMaster::NmtMaster(NmtMaster&&) noexcept = default;
NmtMaster& NmtMaster::operator=(NmtMaster&&) noexcept = default;
NmtMaster::~NmtMaster() = default;

// --- the public calls: each runs, then settles into the Output of the call ---

void NmtMaster::start(TimePoint now, Output& out) {
  impl_->start(now, out);
  impl_->settle(now, out);
}

void NmtMaster::entry_persisted(std::uint64_t ticket, const cfg::Status& result, TimePoint now,
                                Output& out) {
  impl_->store_objects.entry_persisted(ticket, result, now, out);
  impl_->settle(now, out);
}

bool NmtMaster::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto& m = *impl_;
  if (m.startup.state == StartupState::Off) return false;
  m.transfers.pace_frame_of_others(frame, now);
  bool mine = false;
  const auto services = services_in(m.own_state);
  if (services.sdo) {
    auto& server_out = m.outputs.parts;
    server_out.clear();
    if (m.server.on_frame(frame, now, server_out, HookOutput(out))) {
      mine = true;
      for (const auto& f : server_out.frames) out.send(f);
    }
  }
  if (m.sdo_manager.on_frame(frame, now, out)) mine = true;
  if (m.transfers.on_frame(frame, now, m.outputs.transfers)) mine = true;
  if (m.flying.on_frame(frame, now, out)) {
    m.settle(now, out);
    return true;
  }
  if (m.execute_lss.on_frame(frame, now, out)) {
    m.settle(now, out);
    return true;
  }
  m.outputs.emcy.clear();
  if (m.emcy.on_frame(frame, now, m.outputs.emcy)) {
    m.dispatch_emergencies(out);
    m.settle(now, out);
    return true;
  }
  if (auto message = parse_error_control(frame)) {
    m.outputs.error_control.clear();
    m.error_control.on_frame(frame, now, m.outputs.error_control);
    m.dispatch_error_control(now, out);
    m.on_error_control(*message, now, out);
    mine = true;
  }
  m.settle(now, out);
  return mine;
}

void NmtMaster::on_timer(TimePoint now, Output& out) {
  auto& m = *impl_;
  if (m.startup.state == StartupState::Off) return;
  if (m.startup.due && now >= *m.startup.due) {
    m.startup.due.reset();
    m.start(now, out);
  }
  if (services_in(m.own_state).sdo) {
    auto& server_out = m.outputs.parts;
    server_out.clear();
    m.server.on_timer(now, server_out);
    for (const auto& f : server_out.frames) out.send(f);
  }
  m.sdo_manager.on_timer(now, out);
  m.transfers.on_timer(now, m.outputs.transfers);
  m.flying.on_timer(now, out);
  m.execute_lss.on_timer(now, out);
  {
    auto& producer_out = m.outputs.parts;
    producer_out.clear();
    m.producer.on_timer(now, producer_out);
    for (const auto& f : producer_out.frames) out.send(f);
  }
  m.outputs.error_control.clear();
  m.error_control.on_timer(now, m.outputs.error_control);
  m.dispatch_error_control(now, out);
  m.boots.on_timer(now, out);
  m.outputs.emcy.clear();
  m.emcy.on_timer(now, m.outputs.emcy);
  m.dispatch_emergencies(out);
  m.settle(now, out);
}

std::optional<TimePoint> NmtMaster::next_deadline() const {
  const auto& m = *impl_;
  if (m.startup.state == StartupState::Off) return std::nullopt;
  auto due = m.startup.due;
  due = earliest(due, m.server.next_deadline());
  due = earliest(due, m.transfers.next_deadline());
  due = earliest(due, m.producer.next_deadline());
  due = earliest(due, m.error_control.next_deadline());
  due = earliest(due, m.flying.next_deadline());
  due = earliest(due, m.execute_lss.next_deadline());
  due = earliest(due, m.sdo_manager.next_deadline());
  due = earliest(due, m.boots.next_deadline());
  due = earliest(due, m.nmt_commands.next_deadline());
  due = earliest(due, m.emcy.next_deadline());
  return due;
}

void NmtMaster::enter_operational(TimePoint now, Output& out) {
  if (impl_->startup.state == StartupState::AwaitApplication) impl_->finish_startup(now, out);
  impl_->settle(now, out);
}

void NmtMaster::end_emergency_windows(TimePoint now, Output& out) {
  impl_->emcy.end_windows(now, impl_->outputs.emcy);
  impl_->dispatch_emergencies(out);
}

SdoAbort NmtMaster::request_nmt(NmtTarget target, NmtRequest request, TimePoint now, Output& out,
                                std::optional<cfg::NodeId> requester) {
  const auto code = impl_->request_nmt(target, request, requester, now, &out);
  impl_->settle(now, out);
  return code;
}

SdoAbort NmtMaster::request_guarding(NmtTarget target, bool start, TimePoint now, Output& out) {
  const auto code = impl_->request_guarding(target, start ? 1 : 0, now);
  impl_->settle(now, out);
  return code;
}

cfg::Status NmtMaster::boot_slave(cfg::NodeId node, TimePoint now, Output& out) {
  auto& m = *impl_;
  // A flying master that is not the active one boots nobody (CiA 302-2 §3.1 b).
  if (!m.acts_as_master()) {
    return cfg::Error{node_text(node) + ": not booted: this master is not the active NMT master"};
  }
  // §3.4 a: a device not listed as a slave in 1F81h is not booted (status A).
  if (!m.is_slave(node)) {
    return cfg::Error{node_text(node) + ": not booted: no slave of this master (1F81h sub " +
                      cfg::hex(node.value(), 2) + "h, §3.4 a: status A)"};
  }
  m.boot_as_asked(node, now, out);
  m.settle(now, out);
  return {};
}

void NmtMaster::configuration_done(cfg::NodeId node, bool ok, TimePoint now, Output& out) {
  auto& m = *impl_;
  m.boots.with(node, [&](BootSlaveProcess& b) { b.configuration_done(ok, now, out); });
  m.settle(now, out);
}

cfg::Result<NmtMaster::TransferId> NmtMaster::sdo_upload(cfg::NodeId node, std::uint16_t index,
                                                         std::uint8_t sub, TimePoint now,
                                                         Output& out) {
  auto id = impl_->start_application_transfer(node, index, sub, true, {}, now);
  if (id) impl_->settle(now, out);  // engine rule 5: a refused start puts nothing into `out`
  return id;
}

cfg::Result<NmtMaster::TransferId> NmtMaster::sdo_download(cfg::NodeId node, std::uint16_t index,
                                                           std::uint8_t sub,
                                                           std::vector<std::uint8_t> data,
                                                           TimePoint now, Output& out) {
  auto id = impl_->start_application_transfer(node, index, sub, false, std::move(data), now);
  if (id) impl_->settle(now, out);
  return id;
}

cfg::Result<SdoClient::TransferId> NmtMaster::Impl::start_application_transfer(
    cfg::NodeId node, std::uint16_t index, std::uint8_t sub, bool upload,
    std::vector<std::uint8_t> data, TimePoint now) {
  if (node == node_id) {
    // The master's client for its own node-ID would talk to its own server on 600h + node-ID,
    // which does not hear what the master sends: nothing would answer.
    return cfg::Error{"node " + std::to_string(node.value()) +
                      " is this master; read and write its own objects through dictionary()"};
  }
  return transfers.start_application(node, {index, sub}, upload, std::move(data), now,
                                     outputs.transfers);
}

cfg::NodeId NmtMaster::node_id() const {
  return impl_->node_id;
}
NmtState NmtMaster::state() const {
  return impl_->own_state;
}
StartupState NmtMaster::startup_state() const {
  return impl_->startup.state;
}
std::optional<cfg::NodeId> NmtMaster::active_master() const {
  const auto& m = *impl_;
  if (m.flying.phase() == FlyingMasterProcess::Phase::Off) {
    if (m.startup.state == StartupState::Off || m.startup.state == StartupState::NotMaster)
      return std::nullopt;
    return m.node_id;
  }
  return m.flying.active_master();
}
KnownState NmtMaster::known_state(cfg::NodeId node) const {
  return impl_->slaves[node].known_state;
}
BootStep NmtMaster::boot_step(cfg::NodeId node) const {
  return impl_->boots[node].step();
}
std::optional<BootError> NmtMaster::last_error(cfg::NodeId node) const {
  return impl_->boots[node].last_error();
}
const cfg::ConfigManager* NmtMaster::config_manager() const {
  return impl_->options.manager.get();
}

const LocalDictionary& NmtMaster::dictionary() const {
  return impl_->dict;
}
LocalDictionary& NmtMaster::dictionary() {
  return impl_->dict;
}

// --- NMT start-up (§3.1) ---

void NmtMaster::Impl::start(TimePoint now, Output& out) {
  // The master is a CANopen device (§3.1: "shall behave according to the NMT slave state
  // machine"): initialisation ends with its boot-up message.
  own_state = NmtState::Initialising;
  consume_emergencies();
  out.send(make_boot_up(node_id));
  producer.set_period(static_cast<std::uint16_t>(value_of(obj::kProducerHeartbeatTime, 0)), now);
  producer.on_boot_up(now);
  set_own_state(NmtState::PreOperational, now, out);
  begin_startup(now, out);
}

void NmtMaster::Impl::begin_startup(TimePoint now, Output& out) {
  const auto config = startup_config();
  // Every path here resets communication of all nodes (or this device stops being the master):
  // the SDO entries the manager gave out are gone.
  sdo_manager.clear();
  for (const auto n : all_node_ids()) {
    // The manager's transfers still running would bring it stale results (clear()).
    transfers.cancel_manager(n, now, outputs.transfers);
    boots.with(n, [&](BootSlaveProcess& b) { b.reset(now); });
    stop_error_control(n);
    auto& s = slaves[n];
    const auto held_state = s.known_state;
    s = SlaveRecord{};
    s.known_state = held_state;
  }
  if (!config.is_master() || !config.flying_master()) flying.stop();
  // §3.1 a: not the master. Table 16: a self-starting device goes operational by itself, and
  // with bit 1 also starts all nodes.
  if (!config.is_master()) {
    startup.state = StartupState::NotMaster;
    auto e = master_event(MasterEvent::Kind::NotMaster, now, std::nullopt);
    e.nmt_startup = config.value;
    report(out, std::move(e));
    flying.stop_detection();
    if (config.self_starting()) {
      // §5.1: all nodes only when no master-capable device answers (flying_master.hpp).
      if (config.start_all_nodes()) flying.detect_master(detection_timing(), now);
      set_own_state(NmtState::Operational, now, out);
    }
    return;
  }
  // §3.1 b: with bit 5 NMT flying master start-up (§3.7, flying_master.cpp) decides; it
  // comes back here when this device won.
  if (config.flying_master() && flying.phase() != FlyingMasterProcess::Phase::Active) {
    flying.start(flying_timing(), now, out);
    return;
  }
  if (execute_lss_first(now, out)) return;  // DSP 302 §4 figure 1 step 3 (lss_port.cpp)
  startup.state = StartupState::BootingSlaves;
  startup.began = now;
  // §3.1 d (keep-alive slaves are checked by their boot, §3.4 part 2).
  queue_reset_all(now);
  report(out, master_event(MasterEvent::Kind::StartupBegan, now, std::nullopt));
  // No SDO request until every reset slave sent its boot-up (or boot_up_wait passed): boot-ups
  // have the lowest priority, and a device's answers would queue behind its own boot-up.
  boots.gate().close(now + options.boot.boot_up_wait, options.pacing.bitrate != 0);
  // §3.1 e, §3.3: boot every slave in parallel (Annex A).
  for (const auto n : all_node_ids()) {
    if (!is_slave(n)) continue;
    start_boot(n, !assignment(n).keep_alive(), now, out);
  }
}

void NmtMaster::Impl::check_startup(TimePoint now, Output& out) {
  // §3.1 e-f. A mandatory slave's final error stops NMT start-up (the start of the network), not
  // the other slaves' processes boot NMT slave, which §3.3 runs asynchronously: start-up ends
  // (halted or not) once every slave's process has its verdict, so each slave gets its own.
  const bool endless_boot_time = value_of(obj::kBootTime, 0) == 0;
  bool all_ended = true;
  bool mandatory_waiting = false;
  std::vector<cfg::NodeId> failed;  // mandatory slaves whose process ended with an error
  for (const auto n : all_node_ids()) {
    if (!is_slave(n)) continue;
    const auto& s = boots[n];
    if (assignment(n).mandatory()) {
      if (s.booted()) continue;
      if (s.final_error() && s.last_error()) {
        failed.push_back(n);
      } else if (s.tried() && s.last_error() == BootError::B && endless_boot_time) {
        // §3.3, 1F89h = 0: tried again without end. Its verdict (B) is in; start-up goes on
        // only when it boots, but a start-up another slave halts need not wait for it.
        mandatory_waiting = true;
      } else {
        all_ended = false;
      }
    } else if (!s.tried()) {
      // §3.3: optional slaves: wait for the signal that boot NMT slave was tried.
      all_ended = false;
    }
  }
  if (!all_ended) return;
  if (!failed.empty()) {
    startup.state = StartupState::Halted;
    auto e = master_event(MasterEvent::Kind::StartupHalted, now, failed.front());
    for (const auto n : failed) e.halted_by.push_back({n, *boots[n].last_error()});
    e.error = boots[failed.front()].last_error();
    report(out, std::move(e));
    return;
  }
  if (mandatory_waiting) return;
  // §3.1 g: with 1F80h bit 2 the application decides when the master goes operational.
  if (startup_config().no_auto_operational()) {
    startup.state = StartupState::AwaitApplication;
    report(out, master_event(MasterEvent::Kind::StartupAwaitsApplication, now, std::nullopt));
    return;
  }
  finish_startup(now, out);
}

void NmtMaster::Impl::finish_startup(TimePoint now, Output& out) {
  set_own_state(NmtState::Operational, now, out);
  const auto config = startup_config();
  // §3.1 h: start all with node-ID 0 only when every slave booted (and none is kept alive:
  // a kept-alive slave was never reset, so a broadcast would not be what the start-up did);
  // otherwise each booted slave that is not yet operational on its own. With bit 1 clear these
  // are the starts §3.4 l held back while start-up ran (start_remote_node).
  if (!config.no_start_slaves()) {
    bool all_booted = config.start_all_nodes();
    for (const auto n : all_node_ids()) {
      if (!is_slave(n)) continue;
      const auto& s = boots[n];
      if (!s.booted() || s.last_error() || assignment(n).keep_alive()) all_booted = false;
    }
    if (all_booted) {
      queue_nmt(NmtCommand::Start, NmtTarget::all_nodes());
    } else {
      for (const auto n : all_node_ids()) {
        if (!is_slave(n) || !boots[n].booted() || !assignment(n).boot_slave()) continue;
        if (slaves[n].known_state.nmt_state() == NmtState::Operational) continue;
        queue_nmt(NmtCommand::Start, n);
      }
    }
  }
  startup.state = StartupState::Operational;
  report(out, master_event(MasterEvent::Kind::StartupComplete, now, std::nullopt));
}

void NmtMaster::Impl::set_own_state(NmtState state, TimePoint now, Output& out) {
  if (own_state == state) return;
  own_state = state;
  producer.set_state(state);
  auto e = master_event(MasterEvent::Kind::MasterStateChanged, now, node_id);
  e.state = state;
  report(out, std::move(e));
}

void NmtMaster::Impl::apply_own_command(NmtCommand command, TimePoint now, Output& out) {
  switch (command) {
    case NmtCommand::Start:
      if (startup.state == StartupState::AwaitApplication) {
        finish_startup(now, out);
      } else {
        set_own_state(NmtState::Operational, now, out);
      }
      break;
    case NmtCommand::Stop:
      set_own_state(NmtState::Stopped, now, out);
      break;
    case NmtCommand::EnterPreOperational:
      set_own_state(NmtState::PreOperational, now, out);
      break;
    case NmtCommand::ResetNode:
    case NmtCommand::ResetCommunication:
      // The master resets itself: boot-up and NMT start-up again.
      startup.due = now;
      break;
  }
}

// --- NMT commands and the inhibit time (§6.1) ---

void NmtMaster::Impl::flush_nmt(TimePoint now, Output& out) {
  // §6.1: the queue sends what the inhibit time allows; settle() runs it before it hands out
  // the call's SDO requests, so a reset reaches a slave before the request that follows it.
  nmt_commands.set_inhibit_time(nmt_inhibit_time());
  outputs.nmt.clear();
  nmt_commands.on_timer(now, outputs.nmt);
  for (const auto& f : outputs.nmt.frames) out.send(f);
  for (const auto& [command, target] : outputs.nmt.events) {
    const auto state = state_after(command);
    if (const auto node = target.node()) {
      set_known_state(*node, state, now, out);
    } else {
      for (const auto n : all_node_ids()) {
        if (is_slave(n)) set_known_state(n, state, now, out);
      }
    }
    auto e = master_event(MasterEvent::Kind::NmtCommandSent, now, target.node());
    e.command = command;
    report(out, std::move(e));
  }
}

void NmtMaster::Impl::set_known_state(cfg::NodeId node, KnownState state, TimePoint now,
                                      Output& out) {
  auto& s = slaves[node];
  if (s.known_state == state) return;
  s.known_state = state;
  if (!is_slave(node)) return;
  auto e = master_event(MasterEvent::Kind::SlaveStateChanged, now, node);
  e.state = state.nmt_state();
  e.missing = !e.state && state.kind == KnownState::Kind::Missing;
  report(out, std::move(e));
}

void NmtMaster::Impl::report(Output& out, MasterEvent e) {
  out.report(std::move(e));
}

}  // namespace nmt
