// The driver's duties toward the master on any bus (nmt/master/master_host.hpp).
#include "nmt/master/master_host.hpp"

#include <utility>

#include "cfg/config_manager.hpp"

namespace nmt {

MasterHost::MasterHost(const NmtMaster& master, Apply apply, Done on_done)
    : master_(master),
      manager_(master.config_manager()),
      apply_(std::move(apply)),
      on_done_(std::move(on_done)) {}

void MasterHost::on_event(const MasterEvent& e) {
  if (e.kind == MasterEvent::Kind::PersistEntry && e.persist) {
    if (writer_ != nullptr) {
      writer_->write(*e.persist);
    } else {
      apply_(completion(e.persist->ticket, write(*e.persist)));
    }
  }
  // CiA 302-2 §3.1 g: once, when start-up first waits for the application.
  if (!enters_operational_ || entered_ ||
      master_.startup_state() != StartupState::AwaitApplication) {
    return;
  }
  entered_ = true;
  apply_(
      [](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.enter_operational(now, out); });
}

cfg::Status MasterHost::write(const MasterEvent::Persist& entry) const {
  if (manager_ == nullptr) return cfg::Error{"no configuration manager"};
  return manager_->persist(*entry.update);
}

MasterHost::Call MasterHost::completion(std::uint64_t ticket, cfg::Status result) const {
  return [on_done = on_done_, ticket, result = std::move(result)](NmtMaster& m, TimePoint now,
                                                                  NmtMaster::Output& out) {
    if (on_done) on_done(result);
    m.entry_persisted(ticket, result, now, out);
  };
}

}  // namespace nmt
