// The master's side of the configuration manager objects' port
// (manager/configuration_store_objects.hpp, DSP 302 §6): which nodes are its slaves, whether it
// boots slaves now, the boot that 1F25h 'conf' asks for, and the completion of a held SDO
// download on the SDO server it ran on (the default one, or one of the SDO manager's channels).
#include "master/nmt_master_impl.hpp"

namespace nmt {

bool NmtMaster::Impl::StorePort::is_slave(cfg::NodeId node) const {
  return m.is_slave(node);
}

bool NmtMaster::Impl::StorePort::boots_slaves() const {
  return m.startup_config().is_master() && m.acts_as_master();
}

void NmtMaster::Impl::StorePort::configure(cfg::NodeId node, TimePoint now, Output& out) {
  // As boot_slave(): the application (here a tool) asks for it.
  m.boot_as_asked(node, now, out);
  m.boots.with(node, [](BootSlaveProcess& b) { b.request_reconfiguration(); });
}

void NmtMaster::Impl::StorePort::complete_download(std::uint64_t ticket, SdoAbort code,
                                                   Output& out) {
  Outbox<NoEvent> server_out;
  if (!m.server.complete_download(ticket, code, server_out)) {
    m.sdo_manager.complete_download(ticket, code, server_out);
  }
  for (const auto& f : server_out.frames) out.send(f);
}

}  // namespace nmt
