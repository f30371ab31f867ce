// The inside of nmt::NmtMaster, shared by its files: nmt_master.cpp (NMT start-up, the
// handlers of §4, running the NMT command queue, request NMT/guarding, frame routing),
// master_dictionary.cpp (its objects and their value checks, §6) and boot_port.cpp (the
// master's side of the boot NMT slave engines, BootSlaveProcess in boot_slave_process.hpp, one
// per node-ID). Private to the library.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
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
#include "manager/configuration_store_objects.hpp"
#include "manager/sdo_manager_process.hpp"
#include "master/boot_slave_process.hpp"
#include "master/boot_slave_set.hpp"
#include "master/emcy_consumer.hpp"
#include "master/error_control_service.hpp"
#include "master/execute_lss.hpp"
#include "master/flying_master.hpp"
#include "master/master_support.hpp"
#include "master/master_text.hpp"
#include "master/nmt_command_queue.hpp"
#include "master/sdo_transfer_scheduler.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/protocol/deadline_queue.hpp"
#include "nmt/protocol/error_control.hpp"
#include "nmt/sdo/sdo_server.hpp"

namespace nmt {

/// What the master itself knows of a slave, besides its boot (BootSlaveProcess).
struct SlaveRecord {
  KnownState known_state{};               ///< 1F82h read value (KnownState::to_byte)
  bool held = false;                      ///< state set by request NMT: no automatic re-boot
  std::optional<TimePoint> heartbeat_at;  ///< the last heartbeat seen, for §3.6
};

struct NmtMaster::Impl {
  Impl(cfg::NodeId id, MasterOptions opts, LocalDictionary dictionary);

  cfg::NodeId node_id;
  MasterOptions options;
  LocalDictionary dict;
  SdoServer server;
  /// Heartbeat consumer and node guarding of the slaves (boot's start error control, request
  /// node guarding) and of the SDO manager's nodes, each watched while one of them wants it.
  ErrorControlService error_control;
  HeartbeatProducer producer;

  NmtState own_state = NmtState::Initialising;
  /// Where NMT start-up (CiA 302-2 §3.1, DSP 302 §4 figure 1) is: the state machine of
  /// begin_startup(), check_startup() and finish_startup().
  struct Startup {
    StartupState state = StartupState::Off;
    TimePoint began{};
    std::optional<TimePoint> due;  ///< start-up (again) at this time
    /// Execute LSS's start-up pass ended: begin_startup() goes on to the reset of all nodes.
    bool lss_pass_done = false;
  };
  Startup startup;
  std::array<SlaveRecord, 128> slaves;  ///< by node-ID (index 0 unused)

  // --- the master's side of its processes' ports: one object per port, each reaching into
  // the master only through the calls its port declares --------------------------------
  /// The master's side of the boot engines' port (boot_port.cpp): one serves them all.
  class BootPort final : public BootSlavePort {
   public:
    explicit BootPort(Impl& master) : m_(master) {}
    void transfer(std::uint64_t try_id, SdoTransferScheduler::Request request,
                  TimePoint now) override;
    void cancel_transfers(cfg::NodeId node, TimePoint now) override;
    void queue_nmt(NmtCommand command, cfg::NodeId node) override;
    bool start_error_control(cfg::NodeId node, TimePoint now) override;
    BootSlaveExpectations expectations(cfg::NodeId node) const override;
    std::optional<Duration> heartbeat_time(cfg::NodeId node) const override;
    KnownState known_state(cfg::NodeId node) const override;
    std::optional<TimePoint> last_heartbeat(cfg::NodeId node) const override;
    std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override;
    std::optional<std::vector<std::uint8_t>> program(cfg::NodeId node) const override;
    TimePoint startup_began() const override;
    std::optional<MasterEvent::EmergencyReport> take_boot_emergency(cfg::NodeId node) override;
    void boot_con(cfg::NodeId node, std::optional<BootError> status, bool left_to_application,
                  TimePoint now, Outbox<MasterEvent>& out) override;

   private:
    Impl& m_;
  };
  /// The SDO transfer scheduler's port (master_transfers.cpp).
  struct TransferPort final : SdoTransferPort {
    explicit TransferPort(Impl& impl) : m(impl) {}
    bool default_sdo_given_out(cfg::NodeId node) const override;
    bool boot_try_runs(cfg::NodeId node, std::uint64_t try_id) const override;
    bool heard_from(cfg::NodeId node) const override;
    Impl& m;
  };
  /// The flying master's port to this master (master_flying_port.cpp).
  struct FlyingPort final : FlyingMasterPort {
    explicit FlyingPort(Impl& master) : m(master) {}
    void became_active(TimePoint now, Output& out) override;
    void set_startup(StartupState state) override;
    void restart(TimePoint now) override;
    void reset_all_nodes() override;
    void queue_nmt(NmtCommand command, NmtTarget target) override;
    void obey(NmtCommand command, TimePoint now, Output& out) override;
    bool master_capable() const override;
    std::optional<Duration> heartbeat_time(cfg::NodeId node) const override;
    std::uint32_t own_heartbeat_ms() const override;
    Impl& m;
  };
  /// Execute LSS's port to this master (lss_port.cpp).
  struct LssPort final : ExecuteLssPort {
    explicit LssPort(Impl& master) : m(master) {}
    std::optional<cfg::NodeId> slave_with(const LssAddress& address) const override;
    std::vector<LssAddress> known_addresses() const override;
    void pass_ended(TimePoint now, Output& out) override;
    bool may_look() const override;
    Impl& m;
  };
  /// The configuration store objects' port (store_port.cpp).
  struct StorePort final : ConfigurationStorePort {
    explicit StorePort(Impl& impl) : m(impl) {}
    bool is_slave(cfg::NodeId node) const override;
    bool boots_slaves() const override;
    void configure(cfg::NodeId node, TimePoint now, Output& out) override;
    void complete_download(std::uint64_t ticket, SdoAbort code, Output& out) override;
    Impl& m;
  };
  /// The master's side of the SDO manager's port (sdo_manager_port.cpp).
  struct ManagerPort final : SdoManagerPort {
    explicit ManagerPort(Impl& impl) : m(impl) {}
    bool master_active() const override;
    bool serves_sdo() const override;
    void start_transfer(SdoManagerTransfer transfer, TimePoint now) override;
    std::optional<Duration> consumer_time(cfg::NodeId node) const override;
    void watch(cfg::NodeId node, std::optional<Duration> heartbeat, TimePoint now) override;
    void unwatch(cfg::NodeId node) override;
    Impl& m;
  };
  struct Ports {
    explicit Ports(Impl& m) : boot(m), transfer(m), flying(m), lss(m), store(m), manager(m) {}
    BootPort boot;
    TransferPort transfer;
    FlyingPort flying;
    LssPort lss;
    StorePort store;
    ManagerPort manager;
  };
  Ports ports{*this};

  /// Boot NMT slave, one engine per node-ID, and the start-up's boot-up gate (boot_slave_set.hpp).
  BootSlaveSet boots{ports.boot, BootSlaveProcess::Options::from(options)};
  /// The SDO transfers of the boots, the application and the SDO manager, one client per slave
  /// (sdo_transfer_scheduler.hpp).
  SdoTransferScheduler transfers{ports.transfer, SdoTransferScheduler::Settings::from(options)};
  /// The outputs of the parts within one call, cleared before each use so that a call
  /// allocates nothing once they have grown.
  struct CallOutputs {
    /// The transfers': their frames leave at the end of settle(), after the call's NMT
    /// commands; their events are routed as they come (route_transfer_events).
    SdoTransferScheduler::Output transfers;
    Outbox<NoEvent> parts;  ///< the server's and the producer's (on_frame/on_timer)
    ErrorControlService::Output error_control;
    NmtCommandQueue::Output nmt;
    EmcyConsumer::Output emcy;
  };
  CallOutputs outputs;

  /// NMT flying master start-up and master detection (§3.7, §5.1-§5.5; flying_master.hpp).
  FlyingMasterProcess flying{node_id, ports.flying};

  /// Execute LSS (MasterOptions::lss; execute_lss.hpp).
  ExecuteLssProcess execute_lss{ports.lss, options.lss.timing, options.lss.period};
  /// DSP 302 §4 figure 1 step 3: true when the LSS pass started (begin_startup() returns; the
  /// pass's end calls it again).
  bool execute_lss_first(TimePoint now, Output& out);
  /// The LSS address of slave `node` (ExecuteLssOptions::addresses, else 1F85h-1F88h when all
  /// four are non-zero).
  std::optional<LssAddress> lss_address_of(cfg::NodeId node) const;

  /// The NMT commands and their inhibit time (§6.1); run by flush_nmt() from settle().
  NmtCommandQueue nmt_commands;

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
  /// The dictionary's write hook. `out`: the output of the call the write runs in (HookOutput);
  /// nullptr for a write through dictionary() outside any call of the master.
  SdoAbort check_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                       TimePoint now, Output* out);
  std::uint32_t value_of(std::uint16_t index, std::uint8_t sub) const;
  cfg::NmtStartup startup_config() const { return {value_of(cfg::object::kNmtStartup, 0)}; }
  cfg::SlaveAssignment assignment(cfg::NodeId node) const;
  /// 1016h consumer time for `node` (the first active entry), nullopt when not a consumer.
  std::optional<Duration> heartbeat_time(cfg::NodeId node) const;
  Duration nmt_inhibit_time() const;

  // --- configuration manager objects 1F20h-1F27h (manager/configuration_store_objects.hpp) --
  /// 1F20h-1F25h served from MasterOptions::manager, the one owner of 1F26h/1F27h, the
  /// configuration to download to a slave; installed by install_hooks().
  ConfigurationStoreObjects store_objects{dict, ports.store, options.manager,
                                          options.configurations};

  // --- NMT start-up, handlers, NMT queue (nmt_master.cpp) ------------------------------------
  void start(TimePoint now, Output& out);
  void begin_startup(TimePoint now, Output& out);
  void check_startup(TimePoint now, Output& out);
  void finish_startup(TimePoint now, Output& out);
  void set_own_state(NmtState state, TimePoint now, Output& out);
  void queue_nmt(NmtCommand command, NmtTarget target) { nmt_commands.queue(command, target); }
  /// Runs the NMT command queue: its due commands go out, and the slaves' states they set.
  void flush_nmt(TimePoint now, Output& out);
  void apply_own_command(NmtCommand command, TimePoint now, Output& out);
  void set_known_state(cfg::NodeId node, KnownState state, TimePoint now, Output& out);
  void on_error_control(const ErrorControlMessage& message, TimePoint now, Output& out);
  void on_boot_up(cfg::NodeId node, TimePoint now, Output& out);
  void error_handler(cfg::NodeId node, bool heartbeat, TimePoint now, Output& out);
  /// A heartbeat or guarding loss seen: reported, and the node missing (1F82h).
  void report_loss(cfg::NodeId node, bool heartbeat, TimePoint now, Output& out);
  /// The master's own error control of `node` ends (the SDO manager's watch, if any, goes on).
  void stop_error_control(cfg::NodeId node) { error_control.stop(node, Watcher::Master); }
  /// What error_control put into error_control_out: its frames out; a loss to the boot waiting
  /// for the first heartbeat (status K) or the error handler, and to the SDO manager when it
  /// watches the node; a loss's end reported.
  void dispatch_error_control(TimePoint now, Output& out);
  /// 1F82h. A request that applies to the master itself needs `out` (0800 0022 without one).
  SdoAbort request_nmt(NmtTarget target, NmtRequest request, std::optional<cfg::NodeId> requester,
                       TimePoint now, Output* out);
  /// 1F83h: `value` as written (0 stop, 1 start, the rest reserved).
  SdoAbort request_guarding(NmtTarget target, std::uint8_t value, TimePoint now);
  /// Dispatches SDO results, moves frames, sends due NMT commands, moves start-up on: after
  /// every call.
  void settle(TimePoint now, Output& out);
  void report(Output& out, MasterEvent event);
  bool is_slave(cfg::NodeId node) const { return node != node_id && assignment(node).is_slave(); }

  // --- the flying master's side in the master (master_flying_port.cpp) -----------------------
  /// 1F90h; with `written_sub` (not 0) `written` in place of the dictionary's value (a write
  /// being checked).
  FlyingTiming flying_timing(std::uint8_t written_sub = 0, std::uint32_t written = 0) const;
  /// 1F91h, the same way; nullopt without the object.
  std::optional<DetectionTiming> detection_timing(std::uint8_t written_sub = 0,
                                                  std::uint32_t written = 0) const;
  /// False while a flying master is not the active one (standby or negotiating).
  bool acts_as_master() const { return flying.acts_as_master(); }
  /// Reset communication of all nodes as §3.1 d words it (individually when a slave is kept
  /// alive, never the master itself).
  void queue_reset_all(TimePoint now);

  // --- emergencies (master/emcy_consumer.hpp, CiA 301 §7.2.7; master_emcy.cpp) --------------
  EmcyConsumer emcy{EmcyConsumer::Settings{
      options.emcy.max_per_window,
      std::chrono::duration_cast<std::chrono::milliseconds>(options.emcy.window)}};
  /// By node-ID: the last EMCY (not an error reset) a node sent while its boot ran, until the
  /// boot's report takes it (BootPort::take_boot_emergency).
  std::array<std::optional<MasterEvent::EmergencyReport>, 128> boot_emergencies{};
  /// The COB-ID of each node's EMCY (1028h, else MasterOptions::emcy, else 80h + node-ID) to
  /// the consumer: at start().
  void consume_emergencies();
  /// 1000h of `node` for the words of its EMCY codes: MasterOptions::emcy, else 1F84h (not 0).
  std::optional<std::uint32_t> device_type_of(cfg::NodeId node) const;
  /// What the consumer put into outputs.emcy, as MasterEvent::Emergency / EmergencyFlood.
  void dispatch_emergencies(Output& out);

  // --- SDO manager (manager/sdo_manager_process.hpp, DSP 302 §7) ----------------------------
  SdoManagerProcess sdo_manager;
  static SdoManagerSettings manager_settings(const MasterOptions& options,
                                             const SdoServerConfig& server);

  // --- SDO for boot and application (master_transfers.cpp) ---------------------------------
  /// sdo_upload()/sdo_download() of the application: its id; the error (nothing started) when it
  /// cannot start.
  cfg::Result<SdoClient::TransferId> start_application_transfer(cfg::NodeId node,
                                                                std::uint16_t index,
                                                                std::uint8_t sub, bool upload,
                                                                std::vector<std::uint8_t> data,
                                                                TimePoint now);
  /// The events in transfer_out to their owners: a boot try's result to its BootSlaveProcess,
  /// the application's as MasterEvent::SdoFinished, the SDO manager's to SdoManagerProcess, the
  /// software update's progress as MasterEvent::ProgramProgress.
  void route_transfer_events(TimePoint now, Output& out);

  // --- boot NMT slave: the engines and the master's side of their port (boot_port.cpp) -------
  /// A new try of boot NMT slave for `node`; `after_reset`: it waits for the boot-up first (the
  /// start-up's boot-up gate).
  void start_boot(cfg::NodeId node, bool after_reset, TimePoint now, Output& out);
  /// A boot of `node` the application asks for (boot_slave(), 1F25h 'conf'): request NMT's
  /// hold released, error control stopped, a new try begun at once.
  void boot_as_asked(cfg::NodeId node, TimePoint now, Output& out);
  /// §3.4 part 3 g-l: start remote node after a boot with status OK.
  void start_remote_node(cfg::NodeId node);
};

}  // namespace nmt
