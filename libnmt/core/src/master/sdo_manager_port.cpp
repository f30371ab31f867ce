// The master's side of the SDO manager's port (manager/sdo_manager_process.hpp, DSP 302 §7):
// what the manager may ask of the NMT master (is it active, run this transfer, watch this node)
// answered from the master's state, and the master's public accessors of the manager's tables.
#include <algorithm>
#include <utility>

#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace {
constexpr std::uint8_t kGuardLifeTimeFactor = 3;
}  // namespace

SdoManagerSettings NmtMaster::Impl::manager_settings(const MasterOptions& options,
                                                     const SdoServerConfig& server) {
  SdoManagerSettings s;
  s.enabled = options.sdo_manager.enabled;
  s.channels = options.sdo_manager.channels;
  s.max_queued_requests = options.sdo_manager.max_queued_requests;
  s.scan_timeout = options.sdo_manager.scan_timeout;
  s.sdo_timeout = options.sdo.timeout;
  s.sdo_retries = options.sdo.retries;
  s.server_timeout = server.timeout;
  s.server_block_transfer = server.block_transfer;
  return s;
}

bool NmtMaster::Impl::ManagerPort::master_active() const {
  // §7: "The SDO Manager is active only if the NMT Master residing on the same device is active."
  if (!m.startup_config().is_master() || !m.acts_as_master()) return false;
  return m.startup.state == StartupState::BootingSlaves ||
         m.startup.state == StartupState::Halted ||
         m.startup.state == StartupState::AwaitApplication ||
         m.startup.state == StartupState::Operational;
}

bool NmtMaster::Impl::ManagerPort::serves_sdo() const {
  return services_in(m.own_state).sdo;
}

void NmtMaster::Impl::ManagerPort::start_transfer(SdoManagerTransfer transfer, TimePoint now) {
  m.transfers.start_manager(transfer.tag,
                            {.node = transfer.node,
                             .object = transfer.address,
                             .upload = transfer.upload,
                             .data = std::move(transfer.data),
                             .timeout = transfer.timeout,
                             .retries = transfer.retries},
                            now, m.outputs.transfers);
}

std::optional<Duration> NmtMaster::Impl::ManagerPort::consumer_time(cfg::NodeId node) const {
  return m.heartbeat_time(node);
}

void NmtMaster::Impl::ManagerPort::watch(cfg::NodeId node, std::optional<Duration> heartbeat,
                                         TimePoint now) {
  // A node the master watches already (a slave under error control since its boot) stays
  // watched as it is, now for the manager too: the master's stop no longer ends it.
  if (m.error_control.join(node, Watcher::Manager)) return;
  if (!heartbeat) heartbeat = m.heartbeat_time(node);
  if (heartbeat && heartbeat->count() > 0) {
    m.error_control.monitor(node, Watcher::Manager, *heartbeat, now);
    return;
  }
  const auto a = m.assignment(node);
  // Its first request leaves at the end of the call (NmtMaster::Impl::settle()).
  if (m.error_control.guard(node, Watcher::Manager, a.guard_time_ms(), a.retry_factor(), now)) {
    return;
  }
  const auto guard_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(m.options.sdo_manager.srd_guard_time)
          .count();
  (void)m.error_control.guard(
      node, Watcher::Manager,
      static_cast<std::uint16_t>(std::clamp<std::int64_t>(guard_ms, 1, 0xFFFF)),
      kGuardLifeTimeFactor, now);
}

void NmtMaster::Impl::ManagerPort::unwatch(cfg::NodeId node) {
  m.error_control.stop(node, Watcher::Manager);
}

// --- the public accessors ---

std::vector<ManagedSdoConnection> NmtMaster::sdo_connections() const {
  return impl_->sdo_manager.connections();
}

std::vector<RegisteredSrd> NmtMaster::registered_srds() const {
  return impl_->sdo_manager.srds();
}

}  // namespace nmt
