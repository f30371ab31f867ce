// The CiA 302-2 NMT master as one engine of the shape of nmt/engine.hpp: NMT start-up (§3.1),
// start process boot NMT slave (§3.3), boot NMT slave with error status A..O (§3.4, §3.8), check
// configuration (§3.5), check NMT state (§3.6), start error control, error handler and boot-up
// handler (§4), request NMT and request guarding (1F82h, 1F83h), the NMT inhibit time (102Ah);
// the NMT flying master, Execute LSS, the configuration manager and the SDO manager of DSP 302.
//
// It is configured by its own object dictionary, built from a master DCF (1F80h-1F8Ah, 1F90h,
// 102Ah, 1016h, 1F26h/1F27h, 1F53h/1F54h; cfg/master_objects.hpp), and serves it over its own
// SDO server; MasterOptions (nmt/master/master_options.hpp) holds what no object says.
//
//   auto master = nmt::NmtMaster::create(master_dcf, node_id, options).value();
//   master.start(now, out);              // power-on: boot-up, then NMT start-up
//   master.on_frame(frame, now, out);    // frames to send and MasterEvents go into `out`
//   master.on_timer(now, out);           // when now >= master.next_deadline()
//
// What it does where the specifications leave room, process by process and with their
// sections: docs/master.md. How it is built inside: ARCHITECTURE.md, "The NMT master inside".
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/master/master_event.hpp"
#include "nmt/master/master_options.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/slave/nmt_slave.hpp"

namespace cfg {
class ConfigManager;
struct DeviceDescription;
}  // namespace cfg

namespace nmt {

class LocalDictionary;

/// The COB-IDs of the flying master protocols (DSP 302 §5.5, Figures 15-19; CiA 302-2 §5.1-5.4).
/// 71h carries 2 bytes: the priority (1F90h sub 3) and the node-ID; the others carry none.
struct FlyingMasterCobId {
  static constexpr std::uint32_t kMasterResponse = 0x71;  ///< active master / winner: "I am master"
  static constexpr std::uint32_t kNegotiationTrigger = 0x72;   ///< start negotiation timers
  static constexpr std::uint32_t kActiveMasterRequest = 0x73;  ///< active NMT master detection
  static constexpr std::uint32_t kCapableResponse = 0x74;      ///< "I am master-capable"
  static constexpr std::uint32_t kCapableRequest = 0x75;       ///< NMT master detection (§5.1)
  static constexpr std::uint32_t kForceNegotiation = 0x76;  ///< force NMT flying master negotiation
};

/// A 1F82h request NMT value as it is written (CiA 302-2 §6.4, Table 28 on download): the NMT
/// service for the node(s) of the sub-index. The 8xh values exclude the NMT master and the
/// requesting device, whose node-ID the request then needs.
enum class NmtRequest : std::uint8_t {
  Stop = 0x04,
  Start = 0x05,
  ResetNode = 0x06,
  ResetCommunication = 0x07,
  EnterPreOperational = 0x7F,
  StopExcluding = 0x84,
  StartExcluding = 0x85,
  ResetNodeExcluding = 0x86,
  ResetCommunicationExcluding = 0x87,
  EnterPreOperationalExcluding = 0x8F,
};

/// The request a written 1F82h byte asks for; nullopt for the values Table 28 reserves (an SDO
/// write of one is aborted with 0609 0030).
constexpr std::optional<NmtRequest> nmt_request_from_byte(std::uint8_t byte) {
  switch (byte & 0x7F) {
    case 0x04:
    case 0x05:
    case 0x06:
    case 0x07:
      return static_cast<NmtRequest>(byte);
    case 0x7F:  // 7Fh, but not FFh
      return byte == 0x7F ? std::optional{NmtRequest::EnterPreOperational} : std::nullopt;
    case 0x0F:  // 8Fh, but not 0Fh
      return byte == 0x8F ? std::optional{NmtRequest::EnterPreOperationalExcluding} : std::nullopt;
    default:
      return std::nullopt;
  }
}
/// Table 28: 84h-8Fh exclude the NMT master and the requesting device.
constexpr bool excludes_master_and_requester(NmtRequest request) {
  return (static_cast<std::uint8_t>(request) & 0x80) != 0;
}
/// The NMT service (CiA 301 §7.2.8.3.1) a request asks for.
constexpr NmtCommand nmt_command_of(NmtRequest request) {
  switch (static_cast<NmtRequest>(static_cast<std::uint8_t>(request) & 0x7F)) {
    case NmtRequest::Stop:
      return NmtCommand::Stop;
    case NmtRequest::Start:
      return NmtCommand::Start;
    case NmtRequest::ResetNode:
      return NmtCommand::ResetNode;
    case NmtRequest::ResetCommunication:
      return NmtCommand::ResetCommunication;
    default:  // 7Fh, 8Fh
      return NmtCommand::EnterPreOperational;
  }
}

/// What the NMT master knows of a node's NMT state, as a 1F82h read gives it (CiA 302-2 §6.4,
/// Table 28 on upload): unknown, missing, or the state the node last showed.
struct KnownState {
  enum class Kind : std::uint8_t { Unknown, Missing, InState };
  Kind kind = Kind::Unknown;
  NmtState state = NmtState::Initialising;  ///< Kind::InState: stopped, operational, pre-op.

  static constexpr KnownState unknown() { return {}; }
  static constexpr KnownState missing() { return {Kind::Missing}; }
  static constexpr KnownState in(NmtState state) {
    // Initialising is no state the master knows a node in (Table 28 has no value for it).
    return state == NmtState::Initialising ? unknown() : KnownState{Kind::InState, state};
  }
  /// Table 28's byte on upload: 00h unknown, 01h missing, 04h/05h/7Fh the state; the
  /// reserved values read as unknown.
  static constexpr KnownState from_byte(std::uint8_t byte) {
    switch (byte) {
      case 0x01:
        return missing();
      case static_cast<std::uint8_t>(NmtState::Stopped):
      case static_cast<std::uint8_t>(NmtState::Operational):
      case static_cast<std::uint8_t>(NmtState::PreOperational):
        return in(static_cast<NmtState>(byte));
      default:
        return unknown();
    }
  }
  /// The state when the master knows it; nullopt when unknown or missing.
  constexpr std::optional<NmtState> nmt_state() const {
    return kind == Kind::InState ? std::optional{state} : std::nullopt;
  }
  constexpr std::uint8_t to_byte() const {
    switch (kind) {
      case Kind::Missing:
        return 0x01;
      case Kind::InState:
        return static_cast<std::uint8_t>(state);
      default:
        return 0x00;
    }
  }
  constexpr bool operator==(const KnownState&) const = default;
};

/// The NMT master. Movable (its state lives behind one pointer), not copyable.
class NmtMaster {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;
  using TransferId = SdoClient::TransferId;

  /// Builds the master of node `node_id` from its DCF (or EDS): every sub-object becomes a
  /// dictionary entry (LocalDictionary::from_device), and the objects of CiA 302-2 §6 the file
  /// lacks are added with their defaults (1F80h = 1: master, 1F81h..1F88h, 1F8Ah = 1 and 1F82h,
  /// 1F83h for node-IDs 1..127, 102Ah = 0, 1F89h = 0, 1016h with 127 unused entries, 1F26h,
  /// 1F27h, 1F53h, 1F54h, 1F90h = 100, 500, 1, 1500, 10, 4000 + 10 x node-ID ms). Fails with a
  /// message naming the entry when a value does not parse, has reserved bits set, or breaks
  /// §6.13 (1F90h priority above 2, priority time slot not above 127 x device time slot), and
  /// with the error of options.validate() (a timeout that is not positive).
  static cfg::Result<NmtMaster> create(const cfg::DeviceDescription& description,
                                       cfg::NodeId node_id, MasterOptions options = {});
  NmtMaster(NmtMaster&&) noexcept;
  NmtMaster& operator=(NmtMaster&&) noexcept;
  ~NmtMaster();

  // --- engine (nmt/engine.hpp) ---------------------------------------------------------------
  /// Power-on at `now`: the master's boot-up message, then NMT start-up (§3.1): the master
  /// decision and the reset communication go into `out`.
  void start(TimePoint now, Output& out);
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  // --- application -----------------------------------------------------------------------------
  /// §3.1 g with 1F80h bit 2 set: the master enters operational and start-up goes on (start all
  /// nodes per bits 1 and 3). Does nothing in other start-up states.
  void enter_operational(TimePoint now, Output& out);
  /// 1F82h request NMT as the application on the master's own device asks it, for one node or
  /// all nodes (the write to sub-index 80h); `requester` (for the *Excluding requests) is
  /// excluded with the master. Returns the abort an SDO write of the same value gets (None: done).
  SdoAbort request_nmt(NmtTarget target, NmtRequest request, TimePoint now, Output& out,
                       std::optional<cfg::NodeId> requester = std::nullopt);
  /// 1F83h request guarding for one node or all nodes (sub-index 80h), start or stop.
  SdoAbort request_guarding(NmtTarget target, bool start, TimePoint now, Output& out);
  /// Starts the process start process boot NMT slave for `node` (also for a slave left to the
  /// application by 1F81h bit 2: the application asks for it, so it is configured and started;
  /// or held by a request NMT). Could not start (engine.hpp rule 5: an error that says why,
  /// nothing into `out`): `node` is no slave in 1F81h (the status A of §3.4 a, which the
  /// process reports when a slave is taken out of 1F81h while it runs), or a flying master is
  /// not the active master (§3.1 b).
  cfg::Status boot_slave(cfg::NodeId node, TimePoint now, Output& out);
  /// Ends the application's configuration step of `node` (MasterOptions::boot.application_step):
  /// `ok` false ends its boot with status J.
  void configuration_done(cfg::NodeId node, bool ok, TimePoint now, Output& out);
  /// The driver made the entry of MasterEvent::PersistEntry `ticket` durable (`result` ok) or
  /// failed to (`result` says why): the manager takes the value (on success) and the SDO
  /// download that wrote it is confirmed, or aborted with 0800 0020. An unknown ticket is
  /// ignored.
  void entry_persisted(std::uint64_t ticket, const cfg::Status& result, TimePoint now, Output& out);
  /// Says the EMCY floods counted so far: a MasterEvent::EmergencyFlood for each window that
  /// suppressed EMCYs and is still open (MasterOptions::emcy), and the windows end. A driver
  /// that stops calls it last, so that no count goes unsaid.
  void end_emergency_windows(TimePoint now, Output& out);
  /// SDO transfers of the application to a slave, on the master's client for that slave (queued
  /// behind the boot's own transfers). Results come as MasterEvent::SdoFinished. Could not start
  /// (engine.hpp rule 5: the error says why, nothing in `out`): `node` is the master itself, or
  /// SdoClient::check_start refuses (a value over 4 GiB).
  cfg::Result<TransferId> sdo_upload(cfg::NodeId node, std::uint16_t index, std::uint8_t sub,
                                     TimePoint now, Output& out);
  cfg::Result<TransferId> sdo_download(cfg::NodeId node, std::uint16_t index, std::uint8_t sub,
                                       std::vector<std::uint8_t> data, TimePoint now, Output& out);

  // --- observation -----------------------------------------------------------------------------
  cfg::NodeId node_id() const;
  /// The master's own NMT state.
  NmtState state() const;
  StartupState startup_state() const;
  /// The active NMT master as this device knows it: its own node-ID once it won the flying
  /// master negotiation (or without 1F80h bit 5, once start-up began), the winner's while in
  /// standby, nullopt while negotiating or when not a master.
  std::optional<cfg::NodeId> active_master() const;
  /// The state the master knows of `node`, as a 1F82h read gives it (KnownState::to_byte).
  KnownState known_state(cfg::NodeId node) const;
  BootStep boot_step(cfg::NodeId node) const;
  /// The error status of the last finished try of `node`; nullopt after status OK or before.
  std::optional<BootError> last_error(cfg::NodeId node) const;
  /// The dictionary (its values configure the master). Writes through LocalDictionary::write
  /// are checked as SDO writes are; the NMT commands a 1F82h write asks for are queued and due
  /// at once (next_deadline()), so they go out from the next on_timer(). A write that starts
  /// work in the call itself (1F82h for the master itself, 1F25h, 1F20h-1F27h with a store
  /// directory) needs an output of the master to put it in (`out` of LocalDictionary::write, a
  /// NmtMaster::Output the caller then sends and reads): without one it is refused with
  /// 0800 0022 (engine.hpp rule 6: no output kept for a later call).
  const LocalDictionary& dictionary() const;
  LocalDictionary& dictionary();
  /// MasterOptions::manager (nullptr without one): the driver persists a PersistEntry's update
  /// with it (cfg::ConfigManager::persist) before it calls entry_persisted().
  const cfg::ConfigManager* config_manager() const;
  /// The SDO manager's connections, the rows of 1F03h-1F06h in row order (empty without it).
  std::vector<ManagedSdoConnection> sdo_connections() const;
  /// The SRDs the SDO manager registered, by node-ID.
  std::vector<RegisteredSrd> registered_srds() const;

 private:
  struct Impl;
  explicit NmtMaster(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};
static_assert(Engine<NmtMaster>);

}  // namespace nmt
