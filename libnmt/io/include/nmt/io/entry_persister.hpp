// The worker-thread way of a MasterHost's store writes (nmt/master/master_host.hpp, "no disk I/O
// inside on_frame", MasterEvent::PersistEntry) for a master on a BusEventLoop: each staged store
// entry is written (MasterHost::write, an fsync'd atomic file write) on a worker thread, so the
// loop keeps serving frames and timers while the disk works, and the completion goes back to the
// loop's thread with EngineRef::post, which calls NmtMaster::entry_persisted: only then does the
// SDO confirmation leave. Entries are written one at a time, in the order the master asked (two
// writes of one entry stay in order).
//
//   EngineRef<NmtMaster> ref(master);
//   loop.add(ref);
//   MasterHost host(master, [&ref](const MasterHost::Call& call) { ref.apply(call); });
//   EntryPersister persister(ref, host);
//   ref.set_event_handler([&](const MasterEvent& e, TimePoint) { host.on_event(e); });
#pragma once

#include <condition_variable>
#include <deque>
#include <mutex>
#include <thread>

#include "nmt/io/bus_event_loop.hpp"
#include "nmt/master/master_host.hpp"
#include "nmt/master/nmt_master.hpp"

namespace nmt {

class EntryPersister final : public MasterHost::Writer {
 public:
  /// Becomes `host`'s writer (MasterHost::set_writer) until destroyed. `master` must have been
  /// added to its loop and, with `host`, outlive this (and the loop must run to deliver the
  /// completions).
  EntryPersister(EngineRef<NmtMaster>& master, MasterHost& host);
  EntryPersister(const EntryPersister&) = delete;
  EntryPersister& operator=(const EntryPersister&) = delete;
  /// Writes what is still queued (a confirmed write must be durable), then ends the worker; the
  /// host writes at once again.
  ~EntryPersister() override;

  /// Queues the entry for the worker (MasterHost::on_event calls it on the loop's thread).
  void write(MasterEvent::Persist entry) override;

 private:
  void run();

  EngineRef<NmtMaster>& master_;
  MasterHost& host_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<MasterEvent::Persist> queue_;
  bool stopping_ = false;
  std::thread worker_;
};

}  // namespace nmt
