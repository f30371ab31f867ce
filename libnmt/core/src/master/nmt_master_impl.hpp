// The inside of nmt::NmtMaster, shared by its files: nmt_master.cpp (NMT start-up, the
// handlers of §4, the NMT queue, request NMT/guarding, frame routing), master_dictionary.cpp
// (its objects and their value checks, §6) and boot_port.cpp (the master's side of the boot
// NMT slave engines, BootSlaveProcess in boot_slave_process.hpp, one per node-ID). Private to
// the library.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "cfg/config_manager.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/object_index.hpp"
#include "cfg/sdo_manager_objects.hpp"
#include "master/boot_slave_process.hpp"
#include "nmt/error_control.hpp"
#include "nmt/nmt_master.hpp"
#include "nmt/sdo_server.hpp"

namespace nmt {

/// What the master itself knows of a slave, besides its boot (BootSlaveProcess).
struct SlaveRecord {
  std::uint8_t known_state = 0;           ///< 1F82h read value: 0 unknown, 1 missing, else NmtState
  bool held = false;                      ///< state set by request NMT: no automatic re-boot
  std::optional<TimePoint> heartbeat_at;  ///< the last heartbeat seen, for §3.6
  /// Boot transfers of the current try that ended (pump_transfers: the slave furthest behind).
  std::size_t transfers_done = 0;
};

/// NMT flying master start-up (CiA 302-2 §3.7, §5.2-§5.5) and the active master's watch
/// (flying_master.cpp).
struct FlyingMaster {
  enum class Phase : std::uint8_t {
    Off,        // 1F80h bit 5 clear, or not a master
    Delay,      // §3.7 b: the negotiation time delay (1F90h sub 2)
    Detect,     // §3.7 c: 73h sent, a 71h within 1F90h sub 1
    Negotiate,  // §5.3: 72h seen, own waiting time running
    Forced,     // §3.7 g/i: 76h sent, waiting for the active master's reset communication
    Active,     // this device is the NMT master
    Standby,    // an NMT slave watching the active master's heartbeat
  };
  Phase phase = Phase::Off;
  bool warm = false;  ///< this start came from a reset communication (§3.7 d/e)
  std::optional<TimePoint> deadline;
  std::optional<TimePoint> cycle_due;  ///< Active: the next 76h (1F90h sub 6)
  std::uint8_t active = 0;             ///< node-ID of the active master, 0: none known
  std::uint16_t active_priority = 0;
  std::optional<TimePoint> heartbeat_due;  ///< Standby: the active master's heartbeat by then
  std::optional<Duration> watch;           ///< Standby: its heartbeat consumer time
  bool forced = false;       ///< sent 76h since it last stood by or won (DSP 302 §5.5.2 hint)
  unsigned force_tries = 0;  ///< 76h sent in a row without the reset they ask for
};

/// NMT master detection of a start-up capable device that starts all nodes (CiA 302-2 §5.1,
/// DSP 302 §5.5.3.1, 1F91h): is there a device that will be the master?
struct MasterDetection {
  enum class Phase : std::uint8_t {
    Off,
    Delay,   // 1F91h sub 2 after entering pre-operational
    Detect,  // 75h sent, a 74h within sub 1
    Wait,    // no answer: node-ID x sub 3, then start all nodes
  };
  Phase phase = Phase::Off;
  std::optional<TimePoint> deadline;
};

/// 1F90h, in the units of the engine.
struct FlyingTiming {
  Duration timeout;        ///< sub 1: answer of the active master
  Duration delay;          ///< sub 2: before the detection
  std::uint16_t priority;  ///< sub 3: 0 high .. 2 low
  Duration priority_slot;  ///< sub 4
  Duration node_slot;      ///< sub 5
  Duration cycle;          ///< sub 6: multiple master detection (0: off)
};

/// The SDO manager (DSP 302 §7, sdo_manager.cpp): its SRDs, connections and the jobs that set
/// them up and take them down, one at a time.
struct SdoManager {
  explicit SdoManager(LocalDictionary& dict) : channels(dict) {}
  struct Srd {
    RegisteredSrd info;
    std::uint16_t own_channel = 0;  ///< this device's server entry 1201h.. (0: none)
  };
  /// A row of 1F03h-1F06h and the pool entries (1F02h subs, 0: none) it took.
  struct Connection {
    ManagedSdoConnection row;
    std::uint8_t pool_request = 0;
    std::uint8_t pool_response = 0;
  };
  /// One SDO access of a job.
  struct Step {
    std::uint8_t node = 0;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    bool upload = false;
    std::uint32_t value = 0;   ///< download
    std::size_t size = 4;      ///< download bytes
    bool must_succeed = true;  ///< a failure ends the job (job-specific handling)
    bool retry = true;         ///< repeated after a timeout (MasterOptions::sdo_retries)
  };
  struct Job {
    enum class Kind : std::uint8_t { Scan, Register, Connect, Release };
    enum class Phase : std::uint8_t {
      Start,
      Scanning,       // 1F10h of `node`
      Confirming,     // registration: the SRD's client entry
      ReadHeartbeat,  // the SRD's 1017h
      ProbeSlave,     // S's 1000h (its default SDO is given)
      SearchChannel,  // S's `probe` sub 1
      Writing,        // connection writes; registration: the 1F10h confirmation
      Releasing,      // release writes (best effort)
      Refusing,       // 1F10h with Cnxn 0 (or S's side undone), then the event
    };
    Kind kind = Kind::Scan;
    Phase phase = Phase::Start;
    std::uint8_t node = 0;      ///< Scan: the node-ID read now; else the SRD
    std::uint32_t request = 0;  ///< Register: 1F10h as read
    std::uint8_t slave = 0;
    std::uint16_t client_index = 0;
    std::uint16_t probe = 0;                    ///< SearchChannel: S's server entry read now
    Connection connection;                      ///< Register/Connect: the connection being set up
    std::vector<Connection> releases;           ///< Release: in order
    std::string why;                            ///< Release: for the events
    bool deregister = false;                    ///< Release: the SRD goes too
    bool srd_lost = false;                      ///< Release: the SRD does not answer (no retries)
    std::uint8_t failed = 0;                    ///< Release: the slave whose failure 1F11h reports
    bool server_gone = false;                   ///< Release: no write to S (failed, or reset)
    cfg::sdo_manager::DynamicSdoError error{};  ///< Refusing: the 1F10h error code
    std::uint32_t confirmation = 0;             ///< Register: the 1F10h value that confirms
    std::optional<Duration> heartbeat;          ///< Register: the SRD's heartbeat consumer time
    std::deque<Step> steps;                     ///< accesses still to do, in order
  };

  bool enabled = false;
  std::map<std::uint8_t, Srd> srds;
  std::vector<Connection> connections;  ///< in row order
  std::deque<Job> jobs;
  bool in_flight = false;    ///< a transfer of jobs.front() runs
  std::uint64_t serial = 0;  ///< of the transfer in flight (MasterTransfer::try_id)
  bool rescan = false;       ///< a 6E0h came during a scan
  std::uint8_t writer = 0;   ///< the SRD whose channel carries the SDO request being served
  /// This device's server channels for SRDs (1201h..), served from its dictionary, and the SRD
  /// each was opened for (its sub 3): the writer of a 1F00h/1F01h that arrives on it.
  SdoServerChannels channels;
  std::map<std::uint16_t, std::uint8_t> channel_clients;
  /// Slaves the manager watches for SRDs with Req EC.
  std::set<std::uint8_t> watched;
};

/// An SDO transfer the master runs: for a boot try or for the application.
struct MasterTransfer {
  bool for_application = false;
  bool for_manager = false;                  ///< of SdoManager::jobs.front()
  std::uint64_t try_id = 0;                  ///< boot: the try that started it
  SdoClient::TransferId application_id = 0;  ///< application: the id the caller got
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  bool upload = false;
  std::vector<std::uint8_t> data;  ///< download: kept for a repetition after a timeout
  SdoTransferOptions options;
  unsigned retries_left = 0;
  TimePoint launched{0};  ///< when its (latest) request went out: the window's loss events
};

struct NmtMaster::Impl {
  Impl(cfg::NodeId id, MasterOptions opts, LocalDictionary dictionary);

  cfg::NodeId node_id;
  MasterOptions options;
  LocalDictionary dict;
  SdoServer server;
  SdoClientMux clients;
  HeartbeatConsumer heartbeats{HeartbeatConsumerOptions{.timeout_from_start = true}};
  NodeGuardingMaster guarding;
  HeartbeatProducer producer;

  NmtState own_state = NmtState::Initialising;
  StartupState startup = StartupState::Off;
  TimePoint startup_began{0};
  std::optional<TimePoint> startup_due;  ///< start-up (again) at this time
  std::array<SlaveRecord, 128> slaves;   ///< by node-ID (index 0 unused)

  /// The master's side of the boot engines' port (boot_port.cpp): one serves them all.
  class BootPort final : public BootSlavePort {
   public:
    explicit BootPort(Impl& master) : m_(master) {}
    void upload(std::uint8_t node, std::uint64_t try_id, std::uint16_t index, std::uint8_t sub,
                TimePoint now) override;
    void download(std::uint8_t node, std::uint64_t try_id, std::uint16_t index, std::uint8_t sub,
                  std::vector<std::uint8_t> data, TimePoint now) override;
    void cancel_transfers(std::uint8_t node, TimePoint now) override;
    void queue_nmt(NmtCommand command, std::uint8_t node) override;
    bool start_error_control(std::uint8_t node, TimePoint now) override;
    BootSlaveExpectations expectations(std::uint8_t node) const override;
    std::optional<Duration> heartbeat_time(std::uint8_t node) const override;
    std::uint8_t known_state(std::uint8_t node) const override;
    std::optional<TimePoint> last_heartbeat(std::uint8_t node) const override;
    std::optional<std::vector<cfg::ObjectWrite>> configuration(std::uint8_t node) const override;
    std::optional<std::vector<std::uint8_t>> program(std::uint8_t node) const override;
    TimePoint startup_began() const override;
    void deadline_changed(std::uint8_t node, std::optional<TimePoint> deadline) override;
    bool boot_up_gate_closed() const override;
    void booted_up_at_gate(std::uint8_t node, TimePoint now, Outbox<MasterEvent>& out) override;
    void boot_up_wait_over() override;
    void boot_con(std::uint8_t node, std::optional<BootError> status, bool left_to_application,
                  TimePoint now, Outbox<MasterEvent>& out) override;

   private:
    Impl& m_;
  };
  BootPort boot_port{*this};
  /// Boot NMT slave, one engine per node-ID 1..127 (boot(node)).
  std::vector<BootSlaveProcess> boots;
  BootSlaveProcess& boot(std::uint8_t node) { return boots[node - 1U]; }
  const BootSlaveProcess& boot(std::uint8_t node) const { return boots[node - 1U]; }
  /// The boot engines' deadlines, earliest first, kept as they change (deadline_changed), so
  /// next_deadline() and on_timer() need no scan of 127 engines.
  std::set<std::pair<TimePoint, std::uint8_t>> boot_deadlines;
  std::array<std::optional<TimePoint>, 128> boot_deadline_of;

  std::map<std::pair<std::uint8_t, SdoClient::TransferId>, MasterTransfer> transfers;
  /// Boot transfers in `transfers`, the window they may fill, and those waiting for a place.
  static constexpr double kMaxWindow = 128;
  std::size_t boot_transfers = 0;
  double window = kMaxWindow;
  /// When the window was last halved (unpaced): timeouts of transfers launched before are the
  /// same loss event and do not halve it again.
  std::optional<TimePoint> window_cut;
  std::deque<std::pair<std::uint8_t, MasterTransfer>> waiting;
  /// Boot and application transfers to a slave whose default SDO the SDO manager gave to an SRD
  /// (DSP 302 §7.1): they wait here, in order, until it is free again (release_held).
  std::deque<std::pair<std::uint8_t, MasterTransfer>> held;
  /// With MasterOptions::bitrate: no new boot transfer before this time (bus load pacing).
  TimePoint paced_until{0};
  /// Start-up: SDO requests wait until every reset slave booted up, or until this time.
  std::optional<TimePoint> boot_up_gate;
  /// Paced: the gate also opens for the slaves that booted up when no boot-up came for
  /// kBootUpQuiet (the others' were lost or are late; pacing leaves room for them).
  static constexpr Duration kBootUpQuiet = std::chrono::milliseconds(20);
  std::optional<TimePoint> boot_up_quiet;
  SdoClient::TransferId next_application_id = 1;
  Outbox<SdoResult> sdo_out;      ///< scratch output of the SDO client calls
  std::deque<SdoResult> results;  ///< SDO results not yet dispatched
  /// Scratch outputs of the parts in on_frame/on_timer (server, producer; error control),
  /// cleared before each use so that a call allocates nothing once they have grown.
  Outbox<NoEvent> part_out;
  Outbox<HeartbeatEvent> heartbeat_out;
  Outbox<NodeGuardingEvent> guarding_out;

  FlyingMaster flying;
  MasterDetection detection;
  SdoManager sdo_manager;

  std::deque<std::pair<NmtCommand, std::uint8_t>> nmt_queue;
  std::optional<TimePoint> last_nmt;

  /// The Output of the public call in progress; events of dictionary hooks that run outside one
  /// (a write through dictionary()) wait in `deferred` until the next call.
  Output* current = nullptr;
  Output deferred;
  /// Where this call's frames begin in `current`, and how many NMT commands it put first.
  std::size_t call_frames_begin = 0;
  std::size_t nmt_frames_in_call = 0;
  Output& sink() { return current != nullptr ? *current : deferred; }

  // --- dictionary (master_dictionary.cpp) ----------------------------------------------------
  static void add_missing_objects(LocalDictionary& dict);
  static cfg::Status check_configuration_values(const LocalDictionary& dict);
  /// 1F90h and 1F91h with their CiA 302-2 §6.13-§6.14 defaults (1F90h sub 6: 4000 + 10 x
  /// node-ID; 1F91h: DSP 302 §5.5.6, 100, 500, 15 ms).
  static void add_flying_master_objects(LocalDictionary& dict, cfg::NodeId node);
  /// Why a 1F90h value is refused (priority above 2, priority slot not above 127 x node slot).
  static std::optional<std::string> flying_value_problem(const LocalDictionary& dict,
                                                         std::uint8_t sub, std::uint32_t value);
  void install_hooks();
  SdoAbort check_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                       TimePoint now);
  std::uint32_t value_of(std::uint16_t index, std::uint8_t sub) const;
  cfg::NmtStartup startup_config() const { return {value_of(cfg::object::kNmtStartup, 0)}; }
  cfg::SlaveAssignment assignment(std::uint8_t node) const;
  /// 1016h consumer time for `node` (the first active entry), nullopt when not a consumer.
  std::optional<Duration> heartbeat_time(std::uint8_t node) const;
  cfg::ConfigurationStamp expected_configuration(std::uint8_t node) const;
  Duration nmt_inhibit_time() const;

  // --- configuration manager objects 1F20h-1F27h (master_store_objects.cpp) ---------------
  /// With MasterOptions::manager: the master DCF's own 1F22h streams by node-ID, used for a
  /// node the manager holds no configuration for.
  std::map<std::uint8_t, std::vector<std::uint8_t>> file_concise;
  /// The entry whose value a read of 1F20h/1F22h/1F23h filled last (emptied at the next read, so
  /// the dictionary keeps at most one copy of a stored file).
  std::optional<std::pair<std::uint16_t, std::uint8_t>> store_read_entry;
  /// Adds 1F20h-1F25h served from MasterOptions::manager and its hooks; nothing without one.
  void install_store_objects();
  /// The manager's 1F26h/1F27h of `node` when it holds anything for the node (a stamp or a
  /// configuration); nullopt without a manager or when it holds nothing (the dictionary's
  /// values apply).
  std::optional<cfg::ConfigurationStamp> stored_stamp(std::uint8_t node) const;
  SdoAbort store_read(std::uint16_t index, std::uint8_t sub);
  /// A read's value, or the abort that answers it.
  struct StoreValue {
    SdoAbort abort = SdoAbort::None;
    std::vector<std::uint8_t> data;
  };
  /// 1F20h-1F22h of a node the manager stores no configuration for: the configuration source's
  /// concise DCF and DCF, else the master DCF's own 1F22h (nmt_master.hpp). nullopt: the
  /// manager's answer applies.
  std::optional<StoreValue> unstored_read(std::uint16_t index, cfg::NodeId node) const;
  /// 1F25h: the nodes with a configuration that is not stored join the manager's answer.
  void add_unstored_configurations(std::uint8_t sub, cfg::ConfigWrite& written) const;
  SdoAbort store_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                       TimePoint now);
  /// 1F25h: boot (and download to) every slave the manager named.
  SdoAbort configure_slaves(std::uint8_t sub, const std::vector<cfg::NodeId>& nodes, TimePoint now);
  /// The master's own 1F22h stream of `node` (the DCF's value); empty when none.
  std::span<const std::uint8_t> own_concise_dcf(std::uint8_t node) const;

  // --- NMT start-up, handlers, NMT queue (nmt_master.cpp) ------------------------------------
  void power_on(TimePoint now, Output& out);
  void begin_startup(TimePoint now, Output& out);
  void check_startup(TimePoint now, Output& out);
  void finish_startup(TimePoint now, Output& out);
  void set_own_state(NmtState state, TimePoint now, Output& out);
  void queue_nmt(NmtCommand command, std::uint8_t node);
  void flush_nmt(TimePoint now, Output& out);
  void apply_own_command(NmtCommand command, TimePoint now, Output& out);
  void set_known_state(std::uint8_t node, std::uint8_t state, TimePoint now, Output& out);
  void on_error_control(const ErrorControlMessage& message, TimePoint now, Output& out);
  void on_boot_up(std::uint8_t node, TimePoint now, Output& out);
  void error_handler(std::uint8_t node, bool heartbeat, TimePoint now, Output& out);
  void stop_error_control(std::uint8_t node);
  SdoAbort request_nmt(std::uint8_t sub, std::uint8_t value, std::optional<cfg::NodeId> requester,
                       TimePoint now);
  SdoAbort request_guarding(std::uint8_t sub, std::uint8_t value, TimePoint now);
  /// Dispatches SDO results, moves frames, sends due NMT commands, moves start-up on: after
  /// every call.
  void settle(TimePoint now, Output& out);
  void report(Output& out, MasterEvent event);
  bool is_slave(std::uint8_t node) const {
    return node != node_id.value() && cfg::is_node_id(node) && assignment(node).is_slave();
  }

  // --- flying master (flying_master.cpp) ----------------------------------------------------
  FlyingTiming flying_timing() const;
  /// §3.1 b with 1F80h bit 5: flying master start-up instead of NMT start-up.
  void flying_begin(TimePoint now, Output& out);
  /// Frames of the flying master protocols and the NMT commands a standby master obeys; true
  /// when the frame was taken.
  bool flying_frame(const CanFrame& frame, TimePoint now, Output& out);
  void flying_timer(TimePoint now, Output& out);
  std::optional<TimePoint> flying_deadline() const;
  /// §5.1: a self-starting device with 1F80h bit 1 starts all nodes only when no master-capable
  /// device answers (with 1F91h; without it at once).
  void start_all_when_no_master(TimePoint now);
  bool detection_frame(const CanFrame& frame, TimePoint now, Output& out);
  void detection_timer(TimePoint now, Output& out);
  void flying_restart(TimePoint now);
  void flying_wait(TimePoint now, Output& out, const std::string& why);
  void flying_win(TimePoint now, Output& out);
  void flying_standby(std::uint8_t node, std::uint16_t priority, TimePoint now, Output& out,
                      const std::string& why);
  void flying_force(TimePoint now, Output& out, std::uint8_t node, std::uint16_t priority);
  void flying_master_response(std::uint16_t priority, std::uint8_t node, TimePoint now,
                              Output& out);
  /// False while a flying master is not the active one (standby or negotiating).
  bool acts_as_master() const {
    return flying.phase == FlyingMaster::Phase::Off || flying.phase == FlyingMaster::Phase::Active;
  }
  /// Reset communication of all nodes as §3.1 d words it (individually when a slave is kept
  /// alive, never the master itself).
  void queue_reset_all(TimePoint now);

  // --- SDO manager (sdo_manager.cpp, DSP 302 §7) ---------------------------------------------
  /// Adds 1F00h-1F06h, the own server channels and the hooks when the manager is on.
  void install_sdo_manager();
  bool manager_active() const;
  /// The Dynamic SDO Request (6E0h); true when the frame was one.
  bool manager_frame(const CanFrame& frame, TimePoint now);
  /// Frames for the own server channels (the writer of 1F00h/1F01h is known there).
  bool manager_servers_frame(const CanFrame& frame, TimePoint now, Output& out);
  void manager_servers_timer(TimePoint now, Output& out);
  std::optional<TimePoint> manager_deadline() const;
  SdoAbort manager_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  /// Reset communication of all nodes: the tables are gone on every device.
  void manager_clear();
  /// Error control of `node` failed, or it booted up: an SRD is released, a slave reported.
  void manager_node_lost(std::uint8_t node, bool boot_up, TimePoint now, Output& out);
  /// A boot-up of slave `node`: the connections on its additional server entries are released.
  void manager_slave_booted(std::uint8_t node);
  /// Removes the connections `match` selects from the tables (rows cleared), in row order.
  std::vector<SdoManager::Connection> manager_take_connections(
      const std::function<bool(const ManagedSdoConnection&)>& match);
  /// One release job per SRD for `rows` whose server side is gone; `failed` (not 0): 1F11h first.
  void manager_release_per_srd(std::vector<SdoManager::Connection> rows, std::uint8_t failed,
                               const std::string& why);
  void manager_pump(TimePoint now, Output& out);
  void manager_result(const SdoResult& result, TimePoint now, Output& out);
  void manager_advance(TimePoint now, Output& out);
  // One step of the front job, by its kind (manager_advance dispatches).
  void manager_report_refusal(TimePoint now, Output& out);
  void manager_advance_scan();
  void manager_advance_register(TimePoint now, Output& out);
  void manager_advance_connect(TimePoint now, Output& out);
  void manager_advance_release(TimePoint now, Output& out);
  void manager_finish_job();
  void manager_job_failed(const SdoResult& result, TimePoint now, Output& out);
  void manager_start_register(std::uint32_t request);
  void manager_start_connect();
  void manager_connect_with(std::uint16_t server_index);
  /// Ends the front job with 1F10h Cnxn 0 and `error`, then its event.
  void manager_refuse(cfg::sdo_manager::DynamicSdoError error, const std::string& why);
  void manager_release_job(std::uint8_t srd, std::vector<SdoManager::Connection> rows,
                           bool deregister, bool lost, std::string why);
  void manager_watch(std::uint8_t node, std::optional<Duration> heartbeat, TimePoint now);
  std::vector<std::uint8_t> manager_free_pool() const;
  void manager_mark_pool(std::uint8_t sub, bool in_use);
  void manager_open_channel(std::uint16_t index, const SdoManager::Connection& c);
  void manager_close_channel(std::uint16_t index);
  std::uint16_t manager_free_row() const;
  bool default_sdo_taken(std::uint8_t node) const;
  /// The master's own transfers must not use `node`'s default SDO: a connection holds it, or an
  /// SRD owns all default SDOs (DSP 302 §7.1, §7.2.4 guideline 4).
  bool default_sdo_given_out(std::uint8_t node) const;

  // --- SDO for boot and application ------------------------------------------------------------
  SdoClient::TransferId start_transfer(std::uint8_t node, MasterTransfer transfer, TimePoint now);
  void dispatch(const SdoResult& result, TimePoint now, Output& out);
  void forget_transfer(
      std::map<std::pair<std::uint8_t, SdoClient::TransferId>, MasterTransfer>::iterator it);
  void pump_transfers(TimePoint now);
  /// Starts the `held` transfers whose slave's default SDO is free again.
  void release_held(TimePoint now);
  SdoClient::TransferId launch_transfer(std::uint8_t node, MasterTransfer transfer, TimePoint now);
  /// Starts the slaves waiting at the gate that booted up: when every one did, or (`quiet`) when
  /// no boot-up came for kBootUpQuiet.
  void open_boot_up_gate(TimePoint now, Output& out, bool quiet = false);
  /// Pacing (MasterOptions::bitrate): the bus time `bits` take within bus_load_limit.
  Duration paced_time(double bits) const;
  /// Pacing: a frame of another node (heartbeats, PDOs, others' SDO) takes its share of the
  /// load limit too, so the boot's requests leave room for it.
  void pace_frame_of_others(const CanFrame& frame, TimePoint now);

  // --- boot NMT slave: the engines and the master's side of their port (boot_port.cpp) -------
  /// A new try of boot NMT slave for `node`; `after_reset`: it waits for the boot-up first (the
  /// start-up's boot-up gate).
  void start_boot(std::uint8_t node, bool after_reset, TimePoint now, Output& out,
                  bool asked_by_application = false);
  /// §3.4 part 3 g-l: start remote node after a boot with status OK.
  void start_remote_node(std::uint8_t node);
  /// The configuration to download to `node` (§3.5 d): the manager's, the source's, or 1F22h.
  std::optional<std::vector<cfg::ObjectWrite>> configuration_of(std::uint8_t node) const;
};

/// An entry of the master's own objects with `value` in the type's size (0 bytes for DOMAIN).
DictionaryEntry make_entry(std::uint16_t index, std::uint8_t sub, std::string name,
                           cfg::DataType type, cfg::AccessType access, std::uint64_t value);
/// "node 3" (messages).
std::string node_text(std::uint8_t node);
/// The first up to 4 bytes of `data`, little-endian, 0 when empty: the low 32 bits of a number
/// from the bus, whose length the bus decides (cfg::load_le asserts 1..8 bytes).
std::uint32_t low_u32(std::span<const std::uint8_t> data);
/// The first up to 4 bytes of an upload, little-endian (UNSIGNED32 objects); 0 when empty.
std::uint32_t uploaded_u32(const SdoResult& result);
/// "1018h sub 01h upload failed: 0x05040000 (SDO protocol timed out)".
std::string transfer_failure(const SdoResult& result);
/// An UNSIGNED32 value as download bytes.
std::vector<std::uint8_t> u32_bytes(std::uint32_t value);
/// An event with the fields every kind has.
MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, std::uint8_t node, std::string text);

}  // namespace nmt
