// The driver's half of "no disk I/O inside on_frame" (docs/master.md, MasterEvent::PersistEntry)
// for a master on a BusEventLoop: each staged store entry is written (cfg::ConfigManager::persist,
// an fsync'd atomic file write) on a worker thread, so the loop keeps serving frames and timers
// while the disk works, and the completion goes back to the loop's thread with EngineRef::post,
// which calls NmtMaster::entry_persisted: only then does the SDO confirmation leave. Entries are
// written one at a time, in the order the master asked (two writes of one entry stay in order).
//
//   EngineRef<NmtMaster> ref(master);
//   loop.add(ref);
//   EntryPersister persister(ref);
//   ref.set_event_handler([&](const MasterEvent& e, TimePoint) { persister.on_event(e); });
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

#include "cfg/result.hpp"
#include "nmt/bus_event_loop.hpp"
#include "nmt/nmt_master.hpp"

namespace nmt {

class EntryPersister {
 public:
  /// Called on the loop's thread with each write's outcome, just before entry_persisted().
  using Done = std::function<void(const cfg::Status&)>;

  /// `master` must have been added to its loop and outlive this (and the loop must run to
  /// deliver the completions).
  explicit EntryPersister(EngineRef<NmtMaster>& master, Done on_done = {});
  EntryPersister(const EntryPersister&) = delete;
  EntryPersister& operator=(const EntryPersister&) = delete;
  /// Writes what is still queued (a confirmed write must be durable), then ends the worker.
  ~EntryPersister();

  /// From the master's event handler (the loop's thread): queues a PersistEntry; other events
  /// are ignored.
  void on_event(const MasterEvent& e);

 private:
  void run();

  EngineRef<NmtMaster>& master_;
  const cfg::ConfigManager* manager_;
  Done on_done_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<MasterEvent::Persist> queue_;
  bool stopping_ = false;
  std::thread worker_;
};

}  // namespace nmt
