// The NMT master's side of Execute LSS (execute_lss.hpp): where it sits in NMT start-up (DSP 302
// §4 figure 1 step 3: after the master decision, before the reset communication of all nodes)
// and the port it calls: the slaves' LSS addresses, the end of the start-up pass, and when the
// master may look for unconfigured devices.
#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;

bool NmtMaster::Impl::execute_lss_first(TimePoint now, Output& out) {
  if (!options.lss.enabled) return false;
  if (startup.lss_pass_done) {
    // The pass ran for this start-up: on to the reset of all nodes; later looks if asked for.
    startup.lss_pass_done = false;
    execute_lss.watch(now);
    return false;
  }
  startup.state = StartupState::ExecutingLss;
  execute_lss.start(now, out);
  return true;
}

std::optional<LssAddress> NmtMaster::Impl::lss_address_of(cfg::NodeId node) const {
  if (const auto it = options.lss.addresses.find(node); it != options.lss.addresses.end()) {
    return it->second;
  }
  // CiA 305's LSS address is 1018h sub 1-4, which 1F85h-1F88h expect (0: not checked, so
  // not known).
  LssAddress address{value_of(obj::kVendorIdentification, node), value_of(obj::kProductCode, node),
                     value_of(obj::kRevisionNumber, node), value_of(obj::kSerialNumber, node)};
  for (int part = 0; part < 4; ++part) {
    if (address.part(part) == 0) return std::nullopt;
  }
  return address;
}

// --- the port ---

std::optional<cfg::NodeId> NmtMaster::Impl::LssPort::slave_with(const LssAddress& address) const {
  for (const auto n : all_node_ids()) {
    if (m.is_slave(n) && m.lss_address_of(n) == address) return n;
  }
  return std::nullopt;
}

std::vector<LssAddress> NmtMaster::Impl::LssPort::known_addresses() const {
  // The slaves not known to run (1F82h: 0 unknown, 1 missing): a slave heard running has its
  // node-ID, and its device would answer the scan's selection only to be left as it is. A look
  // after start-up mostly finds the device of a slave that went missing.
  std::vector<LssAddress> known;
  for (const auto n : all_node_ids()) {
    if (!m.is_slave(n) || m.slaves[n].known_state.nmt_state().has_value()) continue;
    if (const auto address = m.lss_address_of(n)) known.push_back(*address);
  }
  return known;
}

void NmtMaster::Impl::LssPort::pass_ended(TimePoint now, Output& out) {
  m.startup.lss_pass_done = true;
  m.begin_startup(now, out);
}

bool NmtMaster::Impl::LssPort::may_look() const {
  return m.acts_as_master() && m.startup.state != StartupState::Off &&
         m.startup.state != StartupState::NotMaster &&
         m.startup.state != StartupState::ExecutingLss;
}

}  // namespace nmt
