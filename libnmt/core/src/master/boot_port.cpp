// The master's side of the boot NMT slave engines (BootSlaveProcess, boot_slave_process.hpp):
// their port (transfers, NMT queue, error control, the values they compare against), the
// opening of the start-up's boot-up gate (boot_slave_set.hpp), and what follows a boot's report:
// start remote node (CiA 302-2 §3.4 part 3 g-l), "missing" after status B, error control stopped
// after an error.
#include <string>
#include <utility>

#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;

void NmtMaster::Impl::start_boot(cfg::NodeId node, bool after_reset, TimePoint now, Output& out) {
  boots.with(node, [&](BootSlaveProcess& b) {
    if (after_reset) {
      b.start_after_reset(boots.gate().wait_until(now, options.boot.boot_up_wait), now, out);
    } else {
      b.start(BootSlaveProcess::AskedBy::Master, now, out);
    }
  });
}

void NmtMaster::Impl::boot_as_asked(cfg::NodeId node, TimePoint now, Output& out) {
  slaves[node].held = false;
  stop_error_control(node);
  boots.with(node, [&](BootSlaveProcess& b) {
    b.start(BootSlaveProcess::AskedBy::Application, now, out);
  });
}

void NmtMaster::Impl::start_remote_node(cfg::NodeId node) {
  const auto config = startup_config();
  // §3.4 part 3 g-l. While NMT start-up runs, no slave is started: §3.1 h starts them once every
  // mandatory slave booted (finish_startup), and a halted start-up (§3.1 f) starts none.
  const bool operational = slaves[node].known_state.nmt_state() == NmtState::Operational;
  const bool broadcast_later = config.start_all_nodes() && own_state != NmtState::Operational;
  if (!operational && !config.no_start_slaves() && !broadcast_later &&
      startup.state == StartupState::Operational) {
    queue_nmt(NmtCommand::Start, node);
  }
}

// --- the port ---

void NmtMaster::Impl::BootPort::transfer(std::uint64_t try_id,
                                         SdoTransferScheduler::Request request, TimePoint now) {
  m_.transfers.start_boot(try_id, std::move(request), now, m_.outputs.transfers);
}

void NmtMaster::Impl::BootPort::cancel_transfers(cfg::NodeId node, TimePoint now) {
  m_.transfers.cancel_boot(node, now, m_.outputs.transfers);
}

void NmtMaster::Impl::BootPort::queue_nmt(NmtCommand command, cfg::NodeId node) {
  m_.queue_nmt(command, node);
}

bool NmtMaster::Impl::BootPort::start_error_control(cfg::NodeId node, TimePoint now) {
  // §4.1: heartbeat when 1016h has the node; the first timeout counts from now.
  if (const auto time = m_.heartbeat_time(node)) {
    m_.error_control.monitor(node, Watcher::Master, *time, now);
    return true;
  }
  // Else guarding when 1F81h bytes 2-3 (guard time) and byte 1 (retry factor) are non-zero
  // (guard refuses 0s); its first request leaves at the end of this call (settle()).
  const auto a = m_.assignment(node);
  (void)m_.error_control.guard(node, Watcher::Master, a.guard_time_ms(), a.retry_factor(), now);
  return false;
}

BootSlaveExpectations NmtMaster::Impl::BootPort::expectations(cfg::NodeId node) const {
  BootSlaveExpectations e;
  e.assignment = m_.assignment(node);
  e.device_type = m_.value_of(obj::kDeviceTypeIdentification, node);
  for (std::uint16_t i = 0; i < 4; ++i) {
    e.identity[i] = m_.value_of(static_cast<std::uint16_t>(obj::kVendorIdentification + i), node);
  }
  e.software = {m_.value_of(obj::kExpectedApplicationSwDate, node),
                m_.value_of(obj::kExpectedApplicationSwTime, node)};
  e.software_identification = m_.value_of(obj::kExpectedSoftwareIdentification, node);
  e.configuration = m_.store_objects.expected_configuration(node);
  e.restore_sub = static_cast<std::uint8_t>(m_.value_of(obj::kRestoreConfiguration, node));
  e.boot_time_ms = m_.value_of(obj::kBootTime, 0);
  return e;
}

std::optional<Duration> NmtMaster::Impl::BootPort::heartbeat_time(cfg::NodeId node) const {
  return m_.heartbeat_time(node);
}

KnownState NmtMaster::Impl::BootPort::known_state(cfg::NodeId node) const {
  return m_.slaves[node].known_state;
}

std::optional<TimePoint> NmtMaster::Impl::BootPort::last_heartbeat(cfg::NodeId node) const {
  return m_.slaves[node].heartbeat_at;
}

std::optional<std::vector<cfg::ObjectWrite>> NmtMaster::Impl::BootPort::configuration(
    cfg::NodeId node) const {
  return m_.store_objects.configuration(node);
}

std::optional<std::vector<std::uint8_t>> NmtMaster::Impl::BootPort::program(
    cfg::NodeId node) const {
  if (!m_.options.configurations) return std::nullopt;
  return m_.options.configurations->program(node);
}

TimePoint NmtMaster::Impl::BootPort::startup_began() const {
  return m_.startup.began;
}

void NmtMaster::Impl::BootPort::boot_con(cfg::NodeId node, std::optional<BootError> status,
                                         bool left_to_application, TimePoint now,
                                         Outbox<MasterEvent>& out) {
  if (!status) {
    if (!left_to_application) m_.start_remote_node(node);
    return;
  }
  // L: the slave runs and is under error control. Any other error: the master's error control
  // of it stops (the SDO manager's watch for an SRD goes on: DSP 302 §7.2.2, 1F11h), and after B
  // the slave is missing (1F82h).
  if (*status == BootError::L) return;
  m_.stop_error_control(node);
  if (*status == BootError::B) m_.set_known_state(node, KnownState::missing(), now, out);
}

}  // namespace nmt
