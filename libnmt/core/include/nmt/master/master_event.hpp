// What the NMT master reports (MasterEvent) and the vocabulary its events use: boot status
// (CiA 302-2 Table 1), boot steps, start-up states, the SDO manager's connections and SRDs.
// Included by nmt/master/nmt_master.hpp; the behaviour they report is described in docs/master.md.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/program_image.hpp"
#include "cfg/sdo_manager_objects.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/protocol/emcy.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/slave/nmt_slave.hpp"

namespace cfg {
struct StoreUpdate;
}  // namespace cfg

namespace nmt {

/// Error status of the process boot NMT slave (CiA 302-2 §3.8, Table 1).
enum class BootError : char {
  A = 'A',  ///< not listed in 1F81h
  B = 'B',  ///< no response to the 1000h upload
  C = 'C',  ///< 1000h differs from 1F84h
  D = 'D',  ///< 1018h sub 1 differs from 1F85h
  E = 'E',  ///< check NMT state: no heartbeat
  F = 'F',  ///< check NMT state: no guarding reply
  G = 'G',  ///< program download objects not configured or inconsistent
  H = 'H',  ///< software update required but not allowed
  I = 'I',  ///< software update required but the program download failed
  J = 'J',  ///< configuration download failed
  K = 'K',  ///< no heartbeat during start error control
  L = 'L',  ///< the slave was initially operational (keep-alive)
  M = 'M',  ///< 1018h sub 2 differs from 1F86h
  N = 'N',  ///< 1018h sub 3 differs from 1F87h
  O = 'O',  ///< 1018h sub 4 differs from 1F88h
};
/// The letter, 'A'..'O'.
constexpr char letter(BootError error) {
  return static_cast<char>(error);
}
/// Table 1's words: "value of object 1000h from the device differs from 1F84h (device type)".
std::string_view describe(BootError error);

/// Where a slave's boot stands (for progress displays).
enum class BootStep : std::uint8_t {
  Idle,                 ///< not booting (not a slave, or left to the application)
  AwaitBootUp,          ///< after a reset, waiting for the boot-up message
  Identify,             ///< 1000h and 1018h uploads (§3.4 c-e)
  CheckNmtState,        ///< keep-alive: heartbeat or one guarding RTR (§3.6)
  CheckSoftware,        ///< 1F52h against 1F53h/1F54h
  UpdateSoftware,       ///< program download (1F50h/1F51h)
  VerifyConfiguration,  ///< 1020h upload (§3.5 b)
  Restore,              ///< 1011h 'load', reset, boot-up
  Download,             ///< configuration writes (§3.5 d)
  Save,                 ///< 1020h, 1010h 'save'
  ApplicationStep,      ///< the application's own configuration step (configuration_done())
  StartErrorControl,    ///< waiting for the first heartbeat (§4.1)
  Booted,               ///< boot NMT slave ended with status OK
  Failed,               ///< ended with an error status; RetryWait follows for retried slaves
  RetryWait,            ///< waiting for the next try (§3.3)
};
std::string_view to_string(BootStep step);

/// NMT start-up as a whole (CiA 302-2 §3.1).
enum class StartupState : std::uint8_t {
  Off,               ///< before start()
  NotMaster,         ///< 1F80h bit 0 is 0 (a self-starting device went operational)
  Negotiating,       ///< NMT flying master start-up (§3.7): detection or negotiation running
  Standby,           ///< lost the flying master negotiation: an NMT slave watching the master
  BootingSlaves,     ///< start process boot NMT slave for every slave
  Halted,            ///< a mandatory slave failed (§3.1 f) and every slave's boot ended: no
                     ///< start of the network
  AwaitApplication,  ///< 1F80h bit 2: the application calls enter_operational()
  Operational,       ///< start-up ended (§3.1 i): normal operation
  ExecutingLss,      ///< MasterOptions::lss: Execute LSS before the reset of all nodes (see the
                     ///< top)
};
std::string_view to_string(StartupState state);

/// One SDO connection the SDO manager set up (DSP 302 §7.2.3, a row of 1F03h-1F06h, with the
/// COB-IDs it gave it). The client is always an SRD.
struct ManagedSdoConnection {
  std::uint16_t row = 0;  ///< 1..1016: 1F03h sub 1..254, then 1F04h sub 1..254, ...
  cfg::NodeId srd = *cfg::NodeId::from(1);     ///< client node-ID
  std::uint16_t client_index = 0;              ///< the SRD's client entry, 1280h..12FFh
  cfg::NodeId server = *cfg::NodeId::from(1);  ///< server node-ID: the slave S, or the manager
  std::uint16_t server_index = 0;              ///< the server's entry; 1200h: S's default SDO
  cfg::CobId request{};                        ///< client -> server (sub 1 of both entries)
  cfg::CobId response{};                       ///< server -> client (sub 2)
  bool to_manager = false;                     ///< the SRD's registration channel to the manager
  bool operator==(const ManagedSdoConnection&) const = default;
};

/// An SRD the SDO manager registered (DSP 302 §7.2.1).
struct RegisteredSrd {
  cfg::NodeId node = *cfg::NodeId::from(1);
  std::uint16_t client_index = 0;    ///< its channel to the manager; 0 with all default SDOs
  bool all_default_sdos = false;     ///< 1F10h Cnxn 2 granted
  bool slave_error_control = false;  ///< Req EC granted (bit 3 of 1F10h)
  bool operator==(const RegisteredSrd&) const = default;
};

/// Why boot NMT slave ended with an error status: the facts behind the letter (CiA 302-2 §3.4,
/// §3.5, §3.8). `reason` says which of the other fields are set.
struct BootFailure {
  enum class Reason : std::uint8_t {
    NotListed,           ///< A: 1F81h sub node-ID has bit 0 clear
    TransferFailed,      ///< B, D/M/N/O, G, I, J: `transfer` (1000h, 1018h, 1F52h, 1020h)
    ValueDiffers,        ///< C, D, M, N, O: `object` is `actual`, `expected_by` holds `expected`
    NoExpectedSoftware,  ///< G: 1F81h bit 5 set, but 1F53h, 1F54h and 1F55h of the node are 0
    SoftwareDiffers,     ///< H: 1F52h `software` differs from `expected_software`, and ...
    UpdateNotAllowed,    ///< H: ... 1F81h bit 6 does not allow an update
    NoProgramImage,      ///< H: ... no program image is available
    SoftwareDiffersAfterUpdate,  ///< I: 1F52h after the program download still differs
    ProgramDownloadFailed,       ///< I: `transfer` of the update (1F51h, 1F50h) failed
    /// I: the flash status 1F57h sub 1 read after the image reports an error (CiA 302-3):
    /// `actual` is its value, bits 1-7 the status, bits 16-31 a manufacturer's code.
    FlashStatusError,
    /// I: 1F57h sub 1 still said "in progress" (bit 0) when the program data timeout had
    /// passed since the image went down: `actual` is its last value.
    FlashNeverReady,
    NoHeartbeat,            ///< E: no heartbeat within the consumer time (1016h)
    NoGuardingReply,        ///< F: no reply to the node guarding request
    NoConfigurationStored,  ///< J: 1F26h/1F27h expect a configuration, none is stored
    RestoreFailed,          ///< J: `transfer` of 1011h 'load' failed
    NoBootUpAfterRestore,   ///< J: no boot-up after the restore and reset
    WriteFailed,            ///< J: `transfer` of entry `entry` of `entries` failed
    SaveFailed,             ///< J: `transfer` of 1010h 'save' failed
    ApplicationStepFailed,  ///< J: configuration_done(node, false)
    NoFirstHeartbeat,       ///< K: no heartbeat within `consumer_time_ms` (1016h)
    KeptAlive,              ///< L: kept alive (1F81h bit 4), configuration not checked
  };
  Reason reason = Reason::NotListed;
  BootStep step = BootStep::Idle;       ///< the step the try was in when it failed
  std::optional<SdoResult> transfer{};  ///< the SDO transfer that failed (object, abort, refusal)
  /// ValueDiffers: the object read from the device, the value it had, the object of the master
  /// that holds the expected value (1F84h..1F88h) and that value.
  cfg::ObjectAddress object{};
  std::uint32_t actual = 0;
  std::uint16_t expected_by = 0;
  std::uint32_t expected = 0;
  /// Software*, UpdateNotAllowed, NoProgramImage: 1F52h as read and 1F53h/1F54h. With a CiA
  /// 302-3 expectation (1F55h) instead: `object` is 1F56h sub 1, `actual` its value,
  /// `expected_by` 1F55h and `expected` the identification expected.
  cfg::ProgramVersion software{};
  cfg::ProgramVersion expected_software{};
  std::size_t entry = 0;               ///< WriteFailed: the entry that failed, 1-based
  std::size_t entries = 0;             ///< WriteFailed: entries in the download
  std::uint64_t consumer_time_ms = 0;  ///< NoFirstHeartbeat: the consumer time waited
  /// A mandatory slave's final B: 1F89h (boot time, ms) elapsed; nullopt otherwise.
  std::optional<std::uint32_t> boot_time_ms{};
  bool operator==(const BootFailure&) const = default;
};

/// A mandatory slave whose boot ended with an error status (MasterEvent::StartupHalted).
struct MandatoryFailure {
  cfg::NodeId node = *cfg::NodeId::from(1);
  BootError error = BootError::A;
  bool operator==(const MandatoryFailure&) const = default;
};

/// Why an event of NMT flying master start-up or master detection came (CiA 302-2 §3.7,
/// §5.1-§5.5); MasterEvent::FlyingMaster says which times apply.
enum class FlyingMasterReason : std::uint8_t {
  PowerOn,                     ///< NegotiationBegan: detection in `wait` after power-on
  ResetCommunication,          ///< NegotiationBegan: detection in `wait` after a reset
  TriggerHeard,                ///< NegotiationBegan: 72h heard, waiting `wait`
  NoActiveMaster,              ///< NegotiationBegan: none answered within `timeout`, waiting `wait`
  NoActiveMasterAfterPowerOn,  ///< NegotiationBegan: none answered within `timeout`: reset all
  NoBetterMaster,              ///< ActiveMaster: no better master answered within the wait
  SamePriority,                ///< Standby: the active master has our priority level
  HigherPriority,              ///< Standby: the active master has a higher priority level
  WonAgainAfterForce,          ///< Standby: worse, but it won again after our force
  LowerPriority,               ///< ForceNegotiation: the active master has a lower priority
  AnsweredToo,                 ///< MultipleMasters: node_id answered as active master too
  ForceReceived,               ///< MultipleMasters: 76h received while active: reset all
  HeartbeatLost,               ///< ActiveMasterLost: its heartbeat stopped
  CapableDeviceAnswered,       ///< MasterDetection: 74h came: the network is left to it
  OtherStartedAllNodes,        ///< MasterDetection: another device started all nodes first
  NoCapableDevice,             ///< MasterDetection: none answered within `timeout`: start in `wait`
};

/// Why the SDO manager refused or released something (DSP 302 §7.2): the `why` of
/// SrdRegistrationFailed, SdoConnectionRefused and SdoConnectionReleased.
struct SdoManagerReason {
  enum class Kind : std::uint8_t {
    None,
    SlaveDoesNotAnswer,   ///< `node` (the slave S) did not answer
    NoFreeServerEntry,    ///< `node` (S) has no free server SDO entry
    TransferFailed,       ///< `transfer` to `node` (nullopt: node 0) failed
    DefaultSdoInUse,      ///< all default SDOs asked for, but one is in use
    NotAClientEntry,      ///< 1F10h names `index`, no client SDO entry
    NoFreeServerChannel,  ///< no free server channel on the manager
    NoFreeCobIds,         ///< no free COB-IDs in 1F02h (registration)
    NoTwoFreeCobIds,      ///< no two free COB-IDs in 1F02h (connection)
    Releases,             ///< 1F01h: the SRD `node` releases
    Deregisters,          ///< 1F01h: the SRD `node` de-registers
    SrdBootedUp,          ///< the SRD `node` booted up
    SrdLost,              ///< the SRD `node` is lost (error control)
    SlaveFailed,          ///< the slave `node` failed (error control)
    SlaveBootedUp,        ///< the slave `node` booted up: its server entry is gone
  };
  Kind kind = Kind::None;
  std::optional<cfg::NodeId> node{};
  std::optional<SdoResult> transfer{};
  std::uint16_t index = 0;
};

/// What the master reports: the kind and the typed facts of it; which fields are set depends on
/// the kind (see Kind). The engine makes no words: describe(event)
/// (nmt/master/master_event_text.hpp) makes the line a person reads ("node 3: boot error C: ..."),
/// and a program reads the fields.
struct MasterEvent {
  enum class Kind : std::uint8_t {
    NotMaster,                 ///< 1F80h bit 0 is 0 (`nmt_startup`): no NMT master (§3.1 a)
    StartupBegan,              ///< the master decided and sent its reset communication
    BootStepChanged,           ///< node_id moved to `step` (try `boot_try`); Download also
                               ///< reports written/total (`entry_written`: one more entry)
    SlaveBooted,               ///< boot NMT slave: status OK (`configured`: a download happened)
    BootError,                 ///< boot NMT slave: `error` and `failure`; `final` when no try
                               ///< follows
    StartupHalted,             ///< a mandatory slave's error stopped NMT start-up (§3.1 f),
                               ///< `halted_by` every such slave; reported once every slave's
                               ///< boot ended (docs/master.md)
    StartupAwaitsApplication,  ///< 1F80h bit 2: every mandatory slave booted; call
                               ///< enter_operational() (§3.1 g)
    StartupComplete,           ///< NMT start-up ended (§3.1 i)
    MasterStateChanged,        ///< the master's own NMT state is `state`
    SlaveStateChanged,         ///< the state the master knows of node_id is `state` (nullopt:
                               ///< `missing`, or unknown)
    HeartbeatLost,             ///< heartbeat event of node_id (error handler follows)
    GuardingLost,              ///< node guarding event of node_id (error handler follows)
    ErrorControlResolved,      ///< heartbeat (`heartbeat`) or guarding replies again
    BootUp,                    ///< a boot-up message of node_id (`assigned`: listed in 1F81h)
    NmtCommandSent,            ///< `command` for node_id (nullopt: all nodes) went out
    ApplicationStep,           ///< call configuration_done(node_id, ...) to continue its boot
    ProgramProgress,           ///< software update of node_id: `bytes` of `total` bytes of the
                               ///< 1F50h image confirmed (while it runs, about every 1/32;
                               ///< `bytes` == `total` once, block or segmented)
    SdoFinished,               ///< an application transfer ended (`sdo`)
    // Flying master (§3.7, §5.2-§5.5); `flying` says why, `priority` is node_id's 1F90h sub 3.
    NegotiationBegan,  ///< detection or negotiation started (after power-on, reset, 72h, ...)
    ActiveMaster,      ///< this device (node_id) won and is the active NMT master
    Standby,           ///< node_id is the active master; this device is an NMT slave
    ForceNegotiation,  ///< this device sent 76h: the active master node_id has a lower priority
    MultipleMasters,   ///< a second active master (node_id, nullopt: unknown) was seen
    ActiveMasterLost,  ///< the heartbeat of the active master node_id stopped (§5.5.2)
    MasterDetection,   ///< §5.1 (self-starting device, 1F80h bit 1): the outcome of 75h/74h
    // SDO manager (DSP 302 §7); node_id is the SRD, `connection` the row concerned.
    SrdRegistered,             ///< node_id registered (`srd`); `connection`: its channel to the
                               ///< manager (nullopt when it was granted all default SDOs)
    SrdRegistrationFailed,     ///< 1F10h Cnxn 0 written with `connection_error`, or the SRD did
                               ///< not take the manager's writes (no error); `manager_reason`
    SdoConnectionEstablished,  ///< `connection` from node_id to connection->server is up
    SdoConnectionRefused,      ///< 1F10h Cnxn 0: `connection_error`, `manager_reason`;
                               ///< `connection` as requested
    SdoConnectionReleased,     ///< `connection` was released (`manager_reason`: 1F01h, SRD or
                               ///< slave lost)
    SrdLost,                   ///< node_id's error control failed (or it booted up:
                               ///< `manager_reason`): `released` connections released
    SrdDeregistered,           ///< 1F01h with slave 0: node_id is no longer registered
    SlaveFailedReported,       ///< 1F11h written on SRD node_id: connection->server failed
    // Configuration manager with a store directory (docs/master.md).
    PersistEntry,  ///< make `persist` durable, then call entry_persisted(persist->ticket, ...)
    // Execute LSS (MasterOptions::lss; CiA 305, docs/master.md); `lss_address` is the device's.
    LssAssigned,   ///< the device got node_id by LSS (`lss`: stored or why not)
    LssUnmatched,  ///< an unconfigured device matches no slave (or a slave another device got):
                   ///< left unconfigured
    LssFailed,     ///< the device of slave node_id refused or missed configure node-ID (`lss`)
    LssScanEnded,  ///< a scan ended (`lss_scan`: devices found and given a node-ID)
    /// Software update of node_id: the device refused 1F51h sub 1 = 3 (clear, CiA 302-3) with
    /// `sdo->abort`, one of the refusals of a DSP 302 v3.2.1 device (docs/master.md); the download
    /// goes on. `program->clear_refused` of the boot's SlaveBooted/BootError I says it again.
    ProgramClearRefused,
    // Emergencies (CiA 301 §7.2.7; MasterOptions::emcy): `emergency` holds the message.
    Emergency,       ///< an EMCY of node_id (error code 0000h: error reset or no error; with
                     ///< `emergency->ends_error` it ends the error the node reported)
    EmergencyFlood,  ///< `emergency->suppressed` EMCYs of node_id with that code were not
                     ///< reported (more than the bound in one window); `emcy` is the last
  };
  Kind kind;
  TimePoint at{};
  /// The node the event is about; nullopt for the master's own events (start-up began,
  /// NmtCommandSent to all nodes, MultipleMasters with an unknown node, ...).
  std::optional<cfg::NodeId> node_id{};
  std::optional<BootError> error{};
  BootStep step = BootStep::Idle;
  /// BootStepChanged, ApplicationStep, SlaveBooted, BootError, ProgramClearRefused: the try of
  /// process boot NMT slave (CiA 302-2 §3.3) they belong to, 1 for the first since start-up.
  unsigned boot_try = 0;
  /// BootError: what failed (the letter's reason, the objects and values, the transfer).
  std::optional<BootFailure> failure{};
  std::optional<NmtState> state{};
  bool missing = false;  ///< SlaveStateChanged without `state`: missing (1F82h), else unknown
  std::optional<NmtCommand> command{};
  bool configured = false;  ///< SlaveBooted: the configuration was downloaded
  /// SlaveBooted: the master has no configuration for the node (nothing stored or given for
  /// 1F22h sub node-ID, nothing to restore, 1F26h/1F27h 0): nothing compared, nothing written.
  bool no_configuration = false;
  bool final = false;             ///< BootError: the last try (mandatory, or boot time over)
  bool assigned = false;          ///< BootUp: the node is a slave in 1F81h
  bool entry_written = false;     ///< BootStepChanged Download: an entry was written (`written`)
  bool heartbeat = false;         ///< ErrorControlResolved: heartbeat (false: node guarding)
  std::size_t written = 0;        ///< Download/SlaveBooted: configuration entries written
  std::size_t total = 0;          ///< Download/SlaveBooted: entries to write
  std::uint64_t bytes = 0;        ///< SlaveBooted: bytes of configuration written
  std::uint32_t nmt_startup = 0;  ///< NotMaster: 1F80h (NMT start-up)
  std::vector<MandatoryFailure> halted_by{};  ///< StartupHalted: in node-ID order
  std::optional<SdoResult> sdo{};
  /// SlaveBooted, or BootError I, after the boot began a software update (DSP 302 §9): 1F52h
  /// before it and after it (nullopt when the update failed before 1F52h was read again), the
  /// image's size and when the update began (1F51h stop sent) and ended (start confirmed).
  struct ProgramUpdate {
    cfg::ProgramVersion before;
    std::optional<cfg::ProgramVersion> after;
    /// CiA 302-3 (a 1F55h expectation): 1F56h sub 1 before and after, in place of the versions.
    std::optional<std::uint32_t> identification_before;
    std::optional<std::uint32_t> identification_after;
    std::uint64_t bytes = 0;
    TimePoint began{};
    std::optional<TimePoint> ended;
    /// The abort with which the device refused clear (ProgramClearRefused); nullopt: accepted.
    std::optional<SdoAbort> clear_refused;
    bool operator==(const ProgramUpdate&) const = default;
  };
  std::optional<ProgramUpdate> program{};
  std::optional<std::uint16_t> priority{};  ///< flying master kinds: 1F90h sub 3 of node_id
  /// Flying master kinds and MasterDetection: why, this device's priority (1F90h sub 3), the
  /// detection timeout that passed, the delay or waiting time that follows, and (Standby) the
  /// time the active master's heartbeat is watched with (nullopt: not watched).
  struct FlyingMaster {
    FlyingMasterReason reason = FlyingMasterReason::PowerOn;
    std::uint16_t own_priority = 0;
    Duration timeout{};
    Duration wait{};
    std::optional<Duration> watch{};
  };
  std::optional<FlyingMaster> flying{};
  std::optional<ManagedSdoConnection> connection{};  ///< SDO manager kinds (see Kind)
  std::optional<RegisteredSrd> srd{};                ///< SrdRegistered: what was granted
  /// SrdRegistrationFailed, SdoConnectionRefused: the 1F10h error code (DSP 302 §7.2.3: 00h no
  /// details, 01h no channel SRD <-> manager, 02h no free COB-IDs in the network, 03h no free
  /// server entry on S, 04h S not available); nullopt for the other kinds.
  std::optional<cfg::sdo_manager::DynamicSdoError> connection_error{};
  /// SrdRegistrationFailed, SdoConnectionRefused, SdoConnectionReleased, SrdLost: why.
  SdoManagerReason manager_reason{};
  std::size_t released = 0;  ///< SrdLost: the SDO connections released
  /// PersistEntry: the entry of node_id to write (cfg::ConfigManager::persist) and the ticket
  /// to complete it with. The update stays valid until entry_persisted() for that ticket.
  struct Persist {
    std::uint64_t ticket = 0;
    std::shared_ptr<const cfg::StoreUpdate> update;
  };
  std::optional<Persist> persist{};
  std::optional<LssAddress> lss_address{};  ///< Lss* kinds: the device's LSS address
  /// LssAssigned, LssFailed, LssUnmatched: what became of the device; the LSS error code and
  /// manufacturer-specific error of a refusal, the timeout of an unanswered service.
  struct Lss {
    LssScanOutcome outcome = LssScanOutcome::Stored;
    std::uint8_t error_code = 0;
    std::uint8_t spec_error = 0;
    Duration timeout{};
  };
  std::optional<Lss> lss{};
  /// LssScanEnded: devices found and given a node-ID; `stopped`: the scan ended early (the
  /// device stopped answering in `part` of its address, or the scan could not start).
  struct LssScan {
    std::uint32_t found = 0;
    std::size_t assigned = 0;
    enum class Stop : std::uint8_t { None, DeviceStoppedAnswering, CouldNotStart };
    Stop stopped = Stop::None;
    unsigned part = 0;
  };
  std::optional<LssScan> lss_scan{};
  /// Emergency, EmergencyFlood: the EMCY (error code, error register 1001h, the 5 manufacturer
  /// bytes), the node's device type (1000h) its code is read in where the master knows it (the
  /// profile's words, CiA 402/401), and for a flood the count not reported, the window and bound.
  struct EmergencyReport {
    Emergency emcy{};
    std::optional<std::uint32_t> device_type{};
    bool ends_error = false;       ///< Emergency 0000h after an error of the node
    std::uint32_t suppressed = 0;  ///< EmergencyFlood
    TimePoint window_began{};      ///< EmergencyFlood
    Duration window{};             ///< EmergencyFlood: the window's length
    unsigned max_per_window = 0;   ///< EmergencyFlood: reported at most per window and code
    bool operator==(const EmergencyReport&) const = default;
  };
  std::optional<EmergencyReport> emergency{};
  /// BootError, SlaveBooted: the last EMCY (not an error reset) node_id sent while its boot ran
  /// (since the previous boot report of the node), with its device type; nullopt: none.
  std::optional<EmergencyReport> boot_emergency{};
};
/// "slave_booted", "boot_error", ...: names for logs and JSON.
std::string_view to_string(MasterEvent::Kind kind);

}  // namespace nmt
