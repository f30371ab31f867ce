// What the driver of an NmtMaster owes it on any bus, besides frames and timers (nmt_master.hpp):
//  - MasterEvent::PersistEntry: the staged store entry written (cfg::ConfigManager::persist, an
//    fsync'd atomic file write) and the master told with NmtMaster::entry_persisted, so that the
//    SDO confirmation of the write leaves once the entry is durable (an abort when it failed);
//  - StartupState::AwaitApplication (CiA 302-2 §3.1 g, 1F80h bit 2): the application lets the
//    master enter operational. A host whose application has nothing of its own to do first (a
//    tool) lets it at once; an application with work of its own turns that off and calls
//    NmtMaster::enter_operational itself.
// An entry is written in one of two ways: at once, inside on_event, on the driver's thread (the
// simulated bus: simulated time stands still meanwhile), or by a Writer elsewhere (a real bus:
// nmt::EntryPersister, nmt/io/entry_persister.hpp, a worker thread, so that the loop keeps serving
// frames while the disk works), which hands the completion back to the driver's thread.
//
//   SimEngineNode<NmtMaster> node(std::move(master));
//   MasterHost host(node.engine(), [&node](const MasterHost::Call& call) { node.apply(call); });
//   node.set_event_handler([&](const MasterEvent& e, TimePoint) { host.on_event(e); });
#pragma once

#include <cstdint>
#include <functional>

#include "cfg/config_manager.hpp"
#include "cfg/result.hpp"
#include "nmt/master/master_event.hpp"
#include "nmt/master/nmt_master.hpp"

namespace nmt {

class MasterHost {
 public:
  /// An API call of the master, run by the driver at its time with its output.
  using Call = std::function<void(NmtMaster&, TimePoint, NmtMaster::Output&)>;
  /// Runs a Call on the driver's thread, now (SimEngineNode::apply, EngineRef::apply).
  using Apply = std::function<void(const Call&)>;
  /// Called with each write's outcome on the driver's thread, just before entry_persisted() (to
  /// report a failure; the master aborts the download itself).
  using Done = std::function<void(const cfg::Status&)>;

  /// Writes entries elsewhere than on the driver's thread.
  class Writer {
   public:
    virtual ~Writer() = default;
    /// Called from on_event (the driver's thread) with each staged entry; writes it
    /// (MasterHost::write) and then has the host's completion(entry.ticket, status) run on the
    /// master on the driver's thread (EngineRef::post from a worker thread). Entries of one
    /// store are written in the order they came.
    virtual void write(MasterEvent::Persist entry) = 0;
  };

  /// `master` must outlive this; `apply` runs the host's calls of it.
  MasterHost(const NmtMaster& master, Apply apply, Done on_done = {});

  /// From the master's event handler, with every event, after the master's call returned.
  void on_event(const MasterEvent& e);

  /// Entries go to `writer` (nullptr: written at once in on_event). The writer must outlive its
  /// use here.
  void set_writer(Writer* writer) { writer_ = writer; }
  /// Whether the host lets the master enter operational once it awaits the application
  /// (StartupState::AwaitApplication); default true. Off, the application calls
  /// NmtMaster::enter_operational itself.
  void set_enters_operational(bool at_once) { enters_operational_ = at_once; }

  /// Writes `entry` to the master's configuration manager (an error when it has none). Reads only
  /// the update, the store's directory and the manager the master had when this host was made:
  /// safe on a thread beside the driver's (cfg/config_manager.hpp).
  cfg::Status write(const MasterEvent::Persist& entry) const;
  /// The call that completes the write of entry `ticket` with `result`: on_done, then
  /// NmtMaster::entry_persisted. It holds copies of what it needs, so it may run after this host
  /// is gone.
  Call completion(std::uint64_t ticket, cfg::Status result) const;

 private:
  const NmtMaster& master_;
  const cfg::ConfigManager* manager_;  ///< the master's, fixed at its creation
  Apply apply_;
  Done on_done_;
  Writer* writer_ = nullptr;
  bool enters_operational_ = true;
  bool entered_ = false;
};

}  // namespace nmt
