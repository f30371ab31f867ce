// Store entries written on a worker thread (nmt/entry_persister.hpp).
#include "nmt/entry_persister.hpp"

#include <utility>

#include "cfg/config_manager.hpp"

namespace nmt {

EntryPersister::EntryPersister(EngineRef<NmtMaster>& master, Done on_done)
    : master_(master),
      manager_(master.engine().config_manager()),
      on_done_(std::move(on_done)),
      worker_([this] { run(); }) {}

EntryPersister::~EntryPersister() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  worker_.join();
}

void EntryPersister::on_event(const MasterEvent& e) {
  if (e.kind != MasterEvent::Kind::PersistEntry || !e.persist) return;
  {
    const std::lock_guard lock(mutex_);
    queue_.push_back(*e.persist);
  }
  wake_.notify_one();
}

void EntryPersister::run() {
  for (;;) {
    MasterEvent::Persist job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, and nothing left to write
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    // persist() reads only the update and the store's directory: safe beside the loop's thread
    // (cfg/config_manager.hpp).
    cfg::Status done = manager_ != nullptr ? manager_->persist(*job.update)
                                           : cfg::Status{cfg::Error{"no configuration manager"}};
    // The callback by value: the posted call may run after this persister is gone.
    master_.post([on_done = on_done_, ticket = job.ticket, done = std::move(done)](
                     NmtMaster& m, TimePoint now, NmtMaster::Output& out) {
      if (on_done) on_done(done);
      m.entry_persisted(ticket, done, now, out);
    });
  }
}

}  // namespace nmt
