// The process boot NMT slave of ONE slave (CiA 302-2 §3.4, with check NMT state §3.6, the
// software version check and update of §3.4 part 2 / DSP 302 §9, check configuration §3.5,
// start error control §4.1, the error status of §3.8 Table 1 and the retries of §3.3), as an
// engine of the one shape (nmt/engine.hpp). The NMT master owns one per node-ID and routes to it
// what concerns its slave; the process owns its state (phase, step, the try and its data, what
// outlives a try) and reaches the rest of the master only through BootSlavePort, in the manner
// of lely-core's co_nmt_boot_t service and its one report call co_nmt_boot_con().
//
// Private to the library (boot_slave.cpp, boot_software.cpp, check_configuration.cpp implement it);
// tests reach it through libnmt/core/src (tests/nmt/boot_slave_process_test.cpp drives one through
// a fake port).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cfg/config_manager.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/program_image.hpp"
#include "master/boot_up_gate.hpp"
#include "master/sdo_transfer_scheduler.hpp"
#include "nmt/engine.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/protocol/error_control.hpp"
#include "nmt/sdo/sdo.hpp"

namespace nmt {

/// The master's values a boot compares the slave against, read when the boot needs them (an SDO
/// write to 1F84h.. between two steps applies to the next step).
struct BootSlaveExpectations {
  cfg::SlaveAssignment assignment;  ///< 1F81h sub node-ID (§6.3)
  std::uint32_t device_type = 0;    ///< 1F84h (0: not checked)
  /// 1F85h-1F88h: vendor-ID, product code, revision number, serial number (0: not checked).
  std::array<std::uint32_t, 4> identity{};
  cfg::ProgramVersion software;  ///< 1F53h/1F54h (DSP 302 §9)
  /// 1F55h (CiA 302-3): the software identification expected in the slave's 1F56h sub 1; when
  /// non-zero it is checked instead of `software` (0: not given).
  std::uint32_t software_identification = 0;
  cfg::ConfigurationStamp configuration;  ///< 1F26h/1F27h, or the configuration manager's stamp
  std::uint8_t restore_sub = 0;           ///< 1F8Ah (§6.12; 0: no restore)
  std::uint32_t boot_time_ms = 0;         ///< 1F89h (§6.11; 0: no limit)
};

/// What a BootSlaveProcess needs of the NMT master, and nothing else. One port serves every
/// process (the node-ID names the slave). The master implements it (NmtMaster::Impl::BootPort);
/// a test implements it with a fake.
class BootSlavePort {
 public:
  virtual ~BootSlavePort() = default;

  // --- SDO: the master runs the transfers (SdoTransferScheduler: window, pacing, repetition
  // after a timeout, held while the SDO manager gave the default SDO away).
  /// Every SDO access of a try (identify, software check and update, check configuration): an
  /// upload, or a download of `request.data`, to `request.node` with its wait for each response
  /// and its repetitions after a timeout (each from the start of the value; the software
  /// update's as MasterOptions::program_*_timeout give them). The result comes back through
  /// BootSlaveProcess::on_sdo_result while try `try_id` runs.
  virtual void transfer(std::uint64_t try_id, SdoTransferScheduler::Request request,
                        TimePoint now) = 0;
  /// A try ended: stop its transfers (on the bus too) and forget their results. Only the boot's:
  /// the SDO manager's and the application's to the node go on (SdoTransferScheduler::cancel_boot).
  virtual void cancel_transfers(cfg::NodeId node, TimePoint now) = 0;

  // --- NMT and error control.
  /// Queues an NMT command for the node (the master's NMT queue keeps order and inhibit time).
  virtual void queue_nmt(NmtCommand command, cfg::NodeId node) = 0;
  /// §4.1: starts the heartbeat consumer (1016h) or node guarding (1F81h bytes 1-3) of the node;
  /// true when the heartbeat consumer runs and its first heartbeat ends the step
  /// (BootSlaveProcess::on_heartbeat, or on_heartbeat_timeout: status K). Puts nothing out: the
  /// first guarding request is due at `now` and leaves at the end of the master's call, after
  /// the NMT start that follows a boot (NodeGuardingMaster::guard).
  virtual bool start_error_control(cfg::NodeId node, TimePoint now) = 0;

  // --- What the master knows.
  /// Its objects the boot compares the slave against (read at each step: a write between two
  /// steps applies to the next).
  virtual BootSlaveExpectations expectations(cfg::NodeId node) const = 0;
  /// 1016h: the consumer time for the node, nullopt when the master consumes no heartbeat of it.
  virtual std::optional<Duration> heartbeat_time(cfg::NodeId node) const = 0;
  /// 1F82h as the master knows it (0 unknown, 1 missing, else NmtState): check NMT state (§3.6).
  virtual KnownState known_state(cfg::NodeId node) const = 0;
  /// When the master last saw a heartbeat of the node (§3.6: a heartbeat within the consumer
  /// time is the answer, no guarding request is needed).
  virtual std::optional<TimePoint> last_heartbeat(cfg::NodeId node) const = 0;
  /// §3.5 d: the configuration to download (manager, source, or 1F22h), nullopt: none.
  virtual std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const = 0;
  /// CiA 302-3: the program image for 1F50h, nullopt: none.
  virtual std::optional<std::vector<std::uint8_t>> program(cfg::NodeId node) const = 0;
  /// When NMT start-up began (§3.3: 1F89h counts from there).
  virtual TimePoint startup_began() const = 0;
  /// The last EMCY (not an error reset) the node sent while this boot ran, taken: the next call
  /// returns nullopt until another comes. For the boot's report (MasterEvent::boot_emergency).
  virtual std::optional<MasterEvent::EmergencyReport> take_boot_emergency(cfg::NodeId /*node*/) {
    return std::nullopt;
  }

  /// The ONE report (lely's co_nmt_boot_con): the try ended with `status` (nullopt: OK, the node
  /// is to be started per §3.4 part 3 g-l; `left_to_application`: 1F81h bit 2 clear, neither
  /// configured nor started). Called before the process reports the event; the master does what
  /// follows from the status (stop error control, "missing" after B, start remote node).
  virtual void boot_con(cfg::NodeId node, std::optional<BootError> status, bool left_to_application,
                        TimePoint now, Outbox<MasterEvent>& out) = 0;
};

/// Boot NMT slave of one slave. Events (BootStepChanged, SlaveBooted, BootError,
/// ApplicationStep) and the guarding request of §3.6 go to the caller's Output.
class BootSlaveProcess {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;

  /// What of MasterOptions the process reads; built with from() (MasterOptions holds the
  /// defaults and their reasons, master_options.hpp).
  struct Options {
    Duration reboot_timeout{};
    Duration guarding_reply_timeout{};
    Duration retry_interval{};
    bool force_download = false;
    bool save_configuration = false;
    bool application_step = false;
    Duration program_control_timeout{};
    Duration program_clear_timeout{};
    Duration program_data_timeout{};
    Duration sdo_timeout{};  ///< every other SDO access: the wait for each response
    unsigned sdo_retries = 0;
    static Options from(const MasterOptions& options);
  };

  /// Where the try waits; each phase names the answer it waits for.
  enum class Phase : std::uint8_t {
    Idle,
    AwaitBootUp,          // boot-up after the start-up's reset communication (or its timer)
    ReadDeviceType,       // 1000h
    ReadIdentity,         // 1018h sub identity_sub
    CheckStateHeartbeat,  // §3.6: a heartbeat within the consumer time
    CheckStateGuarding,   // §3.6: the reply to one RTR within 100 ms
    AwaitResetBootUp,     // keep-alive slave not operational: reset communication sent
    ReadSoftwareDate,     // 1F52h sub 1
    ReadSoftwareTime,     // 1F52h sub 2
    ReadSoftwareId,       // 1F56h sub 1 (CiA 302-3, against 1F55h)
    ProgramStop,          // 1F51h sub 1 = 0
    ProgramClear,         // 1F51h sub 1 = 3
    ProgramData,          // 1F50h sub 1 = image
    ReadFlashStatus,      // 1F57h sub 1 after the image (CiA 302-3)
    FlashStatusWait,      // 1F57h bit 0 said "in progress": read again at the deadline
    ProgramStart,         // 1F51h sub 1 = 1
    ReadVerifyDate,       // 1020h sub 1
    ReadVerifyTime,       // 1020h sub 2
    RestoreLoad,          // 1011h sub n = 'load'
    AwaitRestoreBootUp,   // reset after the restore
    ReadPdoCobId,         // a PDO COB-ID the configuration does not carry
    Write,                // plan[next]
    WriteVerifyDate,      // 1020h sub 1
    WriteVerifyTime,      // 1020h sub 2
    WriteSave,            // 1010h sub 1 = 'save'
    Application,          // configuration_done()
    AwaitFirstHeartbeat,  // §4.1
    RetryWait,            // §3.3: the next try
  };

  /// `gate`: the start-up's boot-up gate, which every process of the master shares (a try after
  /// the start-up's reset waits at it; the wait's end opens it).
  BootSlaveProcess(cfg::NodeId node, BootSlavePort& port, BootUpGate& gate, Options options);

  // --- time (engine.hpp rules 3 and 4). No on_frame: the master routes its node's error control
  // messages to the typed inputs below, as it updates 1F82h (and reports it) before the boot
  // sees the state. The master reads next_deadline() after each call.
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const { return deadline_; }

  // --- starting and ending ---
  /// Who asks for a try: AskedBy::Application (the application or 1F25h) means 1F81h bit 2
  /// clear does not leave the slave to the application.
  enum class AskedBy : std::uint8_t { Master, Application };
  /// A new try (§3.3, §4.3). A running try is cancelled.
  void start(AskedBy asker, TimePoint now, Output& out);
  void start(TimePoint now, Output& out) { start(AskedBy::Master, now, out); }
  /// After the start-up's reset communication: the try waits for the boot-up until `wait_until`
  /// (the start-up's boot-up gate), then identifies.
  void start_after_reset(TimePoint wait_until, TimePoint now, Output& out);
  /// Ends the try without a verdict (its transfers stop).
  void cancel(TimePoint now);
  /// NMT start-up (again): cancels and forgets all it knew of the slave (1F82h is the master's).
  void reset(TimePoint now);
  /// 1F25h: the next tries download even when 1020h matches, until one ends with status OK.
  void request_reconfiguration() { reconfigure_ = true; }

  // --- inputs the master routes ---
  void on_sdo_result(const SdoResult& result, TimePoint now, Output& out);
  /// A boot-up of the node; true when the try took it (it was waiting for one, or may go on).
  bool on_boot_up(TimePoint now, Output& out);
  /// A heartbeat (bit 7 clear) of the node with `state`.
  void on_heartbeat(NmtState state, TimePoint now, Output& out);
  /// §3.6: the reply to the guarding request while awaits_guard_reply().
  void on_guard_reply(NmtState state, TimePoint now, Output& out);
  /// §4.1: the consumer time passed without the first heartbeat (status K).
  void on_heartbeat_timeout(TimePoint now, Output& out);
  /// MasterOptions::boot.application_step ended (NmtMaster::configuration_done).
  void configuration_done(bool ok, TimePoint now, Output& out);
  /// The start-up's boot-up gate opened: a try waiting at it that saw its boot-up identifies.
  void pass_boot_up_gate(TimePoint now, Output& out);

  // --- what the master reads ---
  cfg::NodeId node() const { return node_; }
  Phase phase() const { return phase_; }
  BootStep step() const { return step_; }
  bool running() const { return running_; }
  std::uint64_t try_id() const { return try_id_; }
  bool awaits_guard_reply() const { return phase_ == Phase::CheckStateGuarding; }
  bool awaits_heartbeat() const {
    return phase_ == Phase::CheckStateHeartbeat || phase_ == Phase::AwaitFirstHeartbeat;
  }
  bool awaits_first_heartbeat() const { return phase_ == Phase::AwaitFirstHeartbeat; }
  /// Waiting at the start-up's boot-up gate: `seen` whether its boot-up came.
  bool at_boot_up_gate() const { return running_ && phase_ == Phase::AwaitBootUp; }
  bool boot_up_seen() const { return boot_up_seen_; }
  bool tried() const { return tried_; }    ///< at least one try ended (the §3.3 signal)
  bool booted() const { return booted_; }  ///< the last try ended with status OK (or L)
  std::optional<BootError> last_error() const { return last_error_; }
  bool final_error() const { return final_error_; }  ///< the last error ends the process

 private:
  void set_deadline(std::optional<TimePoint> deadline);
  void begin(std::optional<TimePoint> boot_up_until, bool asked_by_application, TimePoint now,
             Output& out);
  void set_step(BootStep step, TimePoint now, Output& out);
  void upload(Phase phase, std::uint16_t index, std::uint8_t sub, TimePoint now);
  void download(Phase phase, std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
                TimePoint now);
  void identify(TimePoint now, Output& out);
  void failed(BootError error, BootFailure failure, TimePoint now, Output& out);
  void succeeded(TimePoint now, Output& out);
  void next_identity(TimePoint now, Output& out);
  void after_identity(TimePoint now, Output& out);
  void keep_alive_state(NmtState state, TimePoint now, Output& out);
  // boot_software.cpp (§3.4 part 2, DSP 302 §9)
  void check_software(TimePoint now, Output& out);
  void software_checked(TimePoint now, Output& out);
  void program_step(Phase phase, TimePoint now);
  /// The answers of the software phases (ReadSoftware*, Program*).
  /// Reads the slave's software identity: 1F56h sub 1 with a 1F55h expectation, else 1F52h.
  void read_software(TimePoint now);
  /// CiA 302-3: the flash status 1F57h sub 1 read after the image (lely-core's
  /// co_nmt_boot_wait_flash), and what follows its value.
  void flash_status_read(const SdoResult& result, TimePoint now, Output& out);
  void software_sdo_result(const SdoResult& result, TimePoint now, Output& out);
  void start_error_control(TimePoint now, Output& out);
  void error_control_started(TimePoint now, Output& out);
  // check_configuration.cpp (§3.5)
  void check_configuration(TimePoint now, Output& out);
  void begin_download(TimePoint now, Output& out);
  void plan_download(TimePoint now, Output& out);
  void write_next(TimePoint now, Output& out);
  void configuration_sdo_result(const SdoResult& result, TimePoint now, Output& out);

  cfg::NodeId node_;
  BootSlavePort* port_;  // never null (pointers: the process is assignable)
  BootUpGate* gate_;
  Options options_;

  Phase phase_ = Phase::Idle;
  BootStep step_ = BootStep::Idle;
  bool running_ = false;      ///< a try is in progress (or waits for its retry)
  std::uint64_t try_id_ = 0;  ///< results of older tries are ignored
  unsigned tries_ = 0;        ///< tries begun since the start-up (MasterEvent::boot_try)
  std::optional<TimePoint> deadline_;
  bool expect_boot_up_ = false;  ///< the master reset the node and has not seen its boot-up
  bool boot_up_seen_ = false;    ///< AwaitBootUp: seen, waiting for the others (boot-up gate)
  bool software_updated_ = false;

  // Data of the current try.
  std::uint8_t identity_sub_ = 0;
  cfg::ProgramVersion software_;   ///< 1F52h as read
  std::uint32_t software_id_ = 0;  ///< 1F56h sub 1 as read (CiA 302-3)
  /// The image went down at this time: 1F57h's "in progress" is waited for until the program
  /// data timeout passed since then.
  TimePoint image_sent_{};
  std::optional<MasterEvent::ProgramUpdate> update_;  ///< the software update of this try
  cfg::ConfigurationStamp verify_;                    ///< 1020h as read
  std::vector<std::uint16_t> cob_ids_to_read_;
  std::map<std::uint16_t, std::uint32_t> cob_ids_read_;
  std::vector<cfg::ObjectWrite> configuration_;  ///< as the source gave it (before ordering)
  std::vector<cfg::ObjectWrite> plan_;           ///< in download order
  std::size_t next_ = 0;
  std::uint64_t bytes_ = 0;
  bool configured_ = false;
  /// The master has nothing to configure the node with (no configuration, no restore, 1F26h/
  /// 1F27h 0): booted without a download that is no "up to date".
  bool no_configuration_ = false;
  bool keep_alive_operational_ = false;
  bool left_to_application_ = false;  ///< 1F81h bit 2 clear: booted without configuration
  bool cob_ids_checked_ = false;

  // Between tries.
  /// 1F25h 'conf' asked for a download even when 1020h matches (DSP 302 §6.4 "request
  /// re-configuration"); kept by the tries that follow until one ends with status OK.
  bool reconfigure_ = false;
  bool tried_ = false;
  bool booted_ = false;
  std::optional<BootError> last_error_;
  bool final_error_ = false;
  std::optional<BootError> reported_error_;  ///< the error last reported (retries repeat silently)
};

}  // namespace nmt
