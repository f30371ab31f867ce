// Store entries written on a worker thread (nmt/io/entry_persister.hpp).
#include "nmt/io/entry_persister.hpp"

#include <utility>

namespace nmt {

EntryPersister::EntryPersister(EngineRef<NmtMaster>& master, MasterHost& host)
    : master_(master), host_(host), worker_([this] { run(); }) {
  host_.set_writer(this);
}

EntryPersister::~EntryPersister() {
  host_.set_writer(nullptr);
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  worker_.join();
}

void EntryPersister::write(MasterEvent::Persist entry) {
  {
    const std::lock_guard lock(mutex_);
    queue_.push_back(std::move(entry));
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
    // MasterHost::write reads only the update and the store's directory: safe beside the loop's
    // thread. The completion holds copies: the posted call may run after this persister is gone.
    master_.post(host_.completion(job.ticket, host_.write(job)));
  }
}

}  // namespace nmt
