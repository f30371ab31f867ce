// The SDO manager of the NMT master as an engine of its own (CiA DSP 302 v3.2.1 §7, "Dynamic
// establishment of SDO connections"): registration of SDO requesting devices (SRDs) after the
// Dynamic SDO Request (6E0h, §7.2.1), the connections an SRD asks for with 1F00h and gives back
// with 1F01h (§7.2.2, §7.2.3), the error control of SRDs and, for SRDs with Req EC, of their
// slaves (1F11h, §7.2.2), and the manager's objects 1F00h-1F06h (§7.2.3) with the own server
// channels 1201h.. an SRD gets. The choices where §7 leaves room are listed in
// docs/master.md ("SDO manager").
//
// The engine (nmt::Engine, engine.hpp) owns its state: the SRDs, the connections (1F03h-1F06h
// rows), the jobs that set them up and take them down (one at a time; a scan lets the others go
// first between its reads), its own server channels and the slaves it watches for SRDs. It is
// built with a narrow port (SdoManagerPort below) to what it needs of the master, never with the
// master itself; the master (nmt_master_impl.hpp) is router and owner:
//   - frames: the master forwards every frame (on_frame: 6E0h and the own server channels) and
//     time (on_timer / next_deadline);
//   - transfers: a job's SDO access goes out through SdoManagerPort::start_transfer, tagged; the
//     master runs it on its default SDO client and routes the result back with
//     on_transfer_result (the tag tells a stale result from the one the job waits for);
//   - error control: node_lost / node_booted when the master's heartbeat consumer, node guarding
//     or a boot-up says so; watch/unwatch through the port;
//   - reset communication of all nodes: clear() (the SRDs and slaves lost their entries);
//   - default_sdo_given_out: the master holds its own transfers to a node whose default SDO the
//     manager gave to an SRD (§7.1, §7.2.4 guideline 4).
// Events are MasterEvents (SrdRegistered, SdoConnectionEstablished, ...), reported into the
// Output of the call, which is the master's own Output type: reporting needs no port call.
// Work that a frame, a 1F00h/1F01h write or a result queues is due at once (next_deadline() is
// TimePoint{}, engine.hpp rule 5's processing step): it starts from the next on_timer, or from
// pump(), which the master calls where it settles a call, after routing that call's results.
//
// The dictionary it serves is the master's: the engine adds 1F00h-1F06h and the own channels at
// install() and checks their writes in a write hook (value checks, 1F00h/1F01h queue jobs). Its
// sources: sdo_manager_objects.cpp (the dictionary side, the tables and channels, losses) and
// sdo_manager_jobs.cpp (scan, register, connect, release).
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/sdo_manager_objects.hpp"
#include "nmt/engine.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/sdo/sdo_server.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace nmt {

/// One SDO access of an SDO manager job, for the master's default SDO client of `node`.
struct SdoManagerTransfer {
  std::uint64_t tag = 0;  ///< handed back with the result (SdoManagerProcess::on_transfer_result)
  cfg::NodeId node;
  cfg::ObjectAddress address;
  bool upload = false;
  std::vector<std::uint8_t> data{};  ///< download
  Duration timeout{0};               ///< per response (SdoTransferOptions::timeout)
  unsigned retries = 0;              ///< repetitions after a timeout the client detected
};

/// What the SDO manager needs of the NMT master, and nothing else. An abstract interface rather
/// than a struct of std::functions: the calls belong together (one master answers them all),
/// a test fakes them in one small class, and the compiler checks that every one is there.
class SdoManagerPort {
 public:
  virtual ~SdoManagerPort() = default;
  /// §7: "The SDO Manager is active only if the NMT Master residing on the same device is
  /// active" (start-up has run and no other flying master is the active one).
  virtual bool master_active() const = 0;
  /// The master's own NMT state serves SDO (CiA 301: not in Stopped): its channels answer.
  virtual bool serves_sdo() const = 0;
  /// Starts `transfer` on the default SDO of `transfer.node`, at once (the manager's accesses
  /// neither wait for the boot's window nor for a held default SDO: it holds them). Its result
  /// comes back through SdoManagerProcess::on_transfer_result with `transfer.tag`.
  virtual void start_transfer(SdoManagerTransfer transfer, TimePoint now) = 0;
  /// The master's heartbeat consumer time for `node` (its 1016h entry); nullopt without one.
  virtual std::optional<Duration> consumer_time(cfg::NodeId node) const = 0;
  /// Error control of `node` for the manager (§7.2.1 SRDs, §7.2.2 slaves with Req EC): heartbeat
  /// consumption with `heartbeat` (else the master's 1016h entry), else node guarding (1F81h,
  /// else MasterOptions::sdo_manager.srd_guard_time); a node the master watches already stays
  /// watched as it is. Its loss comes back as node_lost() until unwatch(), whatever the master does
  /// with its own error control of the node.
  virtual void watch(cfg::NodeId node, std::optional<Duration> heartbeat, TimePoint now) = 0;
  /// The manager no longer needs `node`'s error control (the master keeps its own).
  virtual void unwatch(cfg::NodeId node) = 0;
};

/// The settings of the SDO manager, from MasterOptions and the master's default SDO server.
struct SdoManagerSettings {
  bool enabled = false;        ///< MasterOptions::sdo_manager.enabled (or the DCF has 1F00h)
  std::uint8_t channels = 16;  ///< MasterOptions::sdo_manager.channels
  std::size_t max_queued_requests = 64;
  Duration scan_timeout = std::chrono::milliseconds(50);
  Duration sdo_timeout = std::chrono::milliseconds(1000);  ///< MasterOptions::sdo.timeout
  unsigned sdo_retries = 0;                                ///< MasterOptions::sdo.retries
  /// The own server channels serve with the master's default channel's settings.
  Duration server_timeout = std::chrono::milliseconds(1000);
  bool server_block_transfer = true;
};

/// The SDO manager engine (see the top).
class SdoManagerProcess {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;

  /// Serves its objects from `dict` (the master's dictionary); both must outlive it.
  SdoManagerProcess(LocalDictionary& dict, SdoManagerPort& port, cfg::NodeId node,
                    SdoManagerSettings settings);
  // Its write hook in the dictionary points here.
  SdoManagerProcess(const SdoManagerProcess&) = delete;
  SdoManagerProcess& operator=(const SdoManagerProcess&) = delete;

  /// Adds 1F00h-1F06h, the own server channels and the write hook when the manager is on
  /// (settings.enabled, or the dictionary has 1F00h); nothing otherwise.
  void install();
  bool enabled() const { return enabled_; }

  /// The Dynamic SDO Request (6E0h, §7.2.1) and the frames of its own server channels; true
  /// when the frame was one. Queued work starts from the next on_timer (next_deadline()).
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Its channels' timeouts, and the next SDO access of the front job.
  void on_timer(TimePoint now, Output& out);
  /// A download held on one of the own server channels (a store write waiting for its entry to
  /// be durable, LocalDictionary::WriteVerdict) is confirmed or aborted; false when none has
  /// `ticket`.
  bool complete_download(std::uint64_t ticket, SdoAbort code, SdoServer::Output& out) {
    return channels_.complete_download(ticket, code, out);
  }
  std::optional<TimePoint> next_deadline() const;

  /// Starts the next SDO access (or step) of the jobs while none is in flight: the master calls
  /// it after it routed the results of a call.
  void pump(TimePoint now, Output& out);
  /// The result of the transfer started with `tag`; a stale one (the tables were cleared) is
  /// ignored. The job moves on from the next pump().
  void on_transfer_result(std::uint64_t tag, const SdoResult& result, TimePoint now, Output& out);
  /// Reset communication of all nodes (§7.2.1: the tables are gone on every device).
  void clear();
  /// Error control of `node` failed: an SRD is released and de-registered (§7.2.1), a slave
  /// watched for an SRD with Req EC reported in 1F11h (§7.2.2).
  void node_lost(cfg::NodeId node, TimePoint now, Output& out);
  /// `node` booted up: an SRD forgot its entries (released as lost); a slave lost its additional
  /// server entries (the connections on them are released).
  void node_booted(cfg::NodeId node, TimePoint now, Output& out);

  /// The master's own transfers must not use `node`'s default SDO: a connection holds it, or an
  /// SRD owns all default SDOs (DSP 302 §7.1, §7.2.4 guideline 4).
  bool default_sdo_given_out(cfg::NodeId node) const;
  /// 1F03h-1F06h rows, by row.
  std::vector<ManagedSdoConnection> connections() const;
  /// The registered SRDs, by node-ID.
  std::vector<RegisteredSrd> srds() const;

 private:
  struct Srd {
    RegisteredSrd info;
    std::uint16_t own_channel = 0;  ///< this device's server entry 1201h.. (0: none)
  };
  /// A row of 1F03h-1F06h and the pool entries (1F02h subs, 0: none) it took.
  struct Connection {
    ManagedSdoConnection row;
    std::uint8_t pool_request = 0;
    std::uint8_t pool_response = 0;
    /// The row's SRD and server S. A row is only ever filled from NodeIds (the registration
    /// and the connection jobs): its node bytes are 1..127.
    cfg::NodeId srd() const { return row.srd; }
    cfg::NodeId server() const { return row.server; }
  };
  /// One SDO access of a job.
  struct Step {
    cfg::NodeId node;
    cfg::ObjectAddress address;
    bool upload = false;
    std::uint32_t value = 0;   ///< download
    std::size_t size = 4;      ///< download bytes
    bool must_succeed = true;  ///< a failure ends the job (job-specific handling)
    bool retry = true;         ///< repeated after a timeout (SdoManagerSettings::sdo_retries)
  };
  /// A refusal under way (§7.2.3): 1F10h written with Cnxn state 0 and `error` (for a
  /// connection the SRD did not take, S's side undone instead), then the event.
  struct Refusal {
    cfg::sdo_manager::DynamicSdoError error{};
    SdoManagerReason why;
  };
  /// The scan of 1F10h from node-ID 127 down (§7.2.1); a read with Rq set turns it into the
  /// registration of that node.
  struct ScanJob {
    cfg::NodeId node;          ///< the node-ID read now
    bool started = false;      ///< its first read is out: a new 6E0h may come too late for it
    bool scanned_all = false;  ///< node-ID 1 is passed
  };
  /// The registration of an SRD whose 1F10h the scan read with Rq set (§7.2.1).
  struct RegisterJob {
    enum class Phase : std::uint8_t {
      Confirming,     // the SRD's client entry
      ReadHeartbeat,  // the SRD's 1017h
      Writing,        // the 1F10h confirmation
    };
    cfg::NodeId srd;
    Phase phase = Phase::Confirming;
    std::uint32_t request = 0;            ///< 1F10h as read
    std::uint32_t confirmation = 0;       ///< the 1F10h value that confirms
    std::optional<Duration> heartbeat{};  ///< the SRD's heartbeat consumer time
    /// Its channel to the manager (only `row.srd` for all default SDOs).
    Connection connection{};
    std::optional<Refusal> refusal{};
  };
  /// A connection an SRD asked for with 1F00h (§7.2.2): to S's default SDO or to a free
  /// server entry of S.
  struct ConnectJob {
    enum class Phase : std::uint8_t {
      Start,
      ProbeSlave,     // S's 1000h (its default SDO is given)
      SearchChannel,  // S's `probe` sub 1
      Writing,        // S's server entry, the SRD's client entry, the 1F10h confirmation
    };
    cfg::NodeId srd;
    cfg::NodeId slave;  ///< S
    std::uint16_t client_index = 0;
    Phase phase = Phase::Start;
    std::uint16_t probe = 0;  ///< SearchChannel: S's server entry read now
    Connection connection{};  ///< the connection being set up
    std::optional<Refusal> refusal{};
  };
  /// Connections of an SRD released (1F01h, a lost or booted SRD or slave; §7.2.1, §7.2.3),
  /// best effort: the writes may fail, the rows are gone already.
  struct ReleaseJob {
    cfg::NodeId srd;
    std::vector<Connection> releases{};   ///< in order
    SdoManagerReason why{};               ///< for the events
    bool deregister = false;              ///< the SRD goes too
    bool srd_lost = false;                ///< the SRD does not answer (no retries)
    std::optional<cfg::NodeId> failed{};  ///< the slave whose failure 1F11h reports (first)
    bool server_gone = false;             ///< no write to S (failed, or reset)
    bool started = false;                 ///< its writes are queued
  };
  /// One job of the queue: what it does, and its SDO accesses still to do.
  struct Job {
    std::variant<ScanJob, RegisterJob, ConnectJob, ReleaseJob> work;
    std::deque<Step> steps{};  ///< in order
  };

  // --- objects and tables (sdo_manager_objects.cpp) ---
  bool active() const;
  std::uint32_t value_of(std::uint16_t index, std::uint8_t sub) const;
  SdoAbort check_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  // 1F00h and 1F01h with the node-IDs check_write parsed (§7.2.3).
  SdoAbort request_connection(cfg::NodeId srd, cfg::NodeId slave, std::uint16_t client_index);
  /// `client_index` 0: every connection of `srd` to `slave`.
  SdoAbort release_connections(cfg::NodeId srd, cfg::NodeId slave, std::uint16_t client_index);
  /// 1F01h with slave node-ID 0: everything of `srd` released, and it de-registers.
  SdoAbort deregister(cfg::NodeId srd);
  std::vector<std::uint8_t> free_pool() const;
  void mark_pool(std::uint8_t sub, bool in_use);
  /// The COB-ID of 1F02h sub `sub` without the manager's bits.
  cfg::CobId pool_cob_id(std::uint8_t sub) const;
  std::uint16_t free_own_channel() const;
  void open_channel(std::uint16_t index, const Connection& c);
  void close_channel(std::uint16_t index);
  std::uint16_t free_row() const;
  void set_row(std::uint16_t row, std::uint32_t word);
  void add_row(const Connection& c);
  /// Removes the connections `match` selects from the tables (rows cleared), in row order.
  std::vector<Connection> take_connections(
      const std::function<bool(const ManagedSdoConnection&)>& match);
  bool default_sdo_taken(cfg::NodeId node) const;
  bool all_default_sdos_owned() const;
  // Losses and the jobs they (and 6E0h, 1F01h) queue.
  void queue_scan();
  /// A boot-up of slave `node`: the connections on its additional server entries are released.
  void slave_booted(cfg::NodeId node);
  void srd_gone(cfg::NodeId node, bool boot_up, TimePoint now, Output& out);
  /// One release job per SRD for `rows` whose server side is gone; with `failed`: 1F11h first.
  void release_per_srd(const std::vector<Connection>& rows, std::optional<cfg::NodeId> failed,
                       const SdoManagerReason& why);
  void release_job(cfg::NodeId srd, std::vector<Connection> rows, bool deregister, bool lost,
                   SdoManagerReason why);

  // --- jobs (sdo_manager_jobs.cpp) ---
  void advance(TimePoint now, Output& out);
  // One step of the front job, by its kind (advance dispatches).
  void report_refusal(const Job& job, TimePoint now, Output& out);
  void advance_scan(Job& job, ScanJob& scan);
  /// A scan of 1F10h from node-ID 127 down (§7.2.1).
  static Job scan_job();
  /// The scan moves to the node-ID below (scanned_all after 1).
  static void scan_next(ScanJob& scan);
  void advance_register(Job& job, RegisterJob& reg, TimePoint now, Output& out);
  void advance_connect(Job& job, ConnectJob& connect, TimePoint now, Output& out);
  void advance_release(Job& job, ReleaseJob& release, TimePoint now, Output& out);
  void finish_job();
  void job_failed(const SdoResult& result, TimePoint now, Output& out);
  /// The scan `job` found an SRD with an open request: the job becomes its registration.
  void start_register(Job& job, cfg::NodeId srd, std::uint32_t request);
  void start_connect(Job& job, ConnectJob& connect);
  void connect_with(Job& job, ConnectJob& connect, std::uint16_t server_index);
  /// Ends `job` (a registration or a connection) with 1F10h Cnxn 0 and `error`, then its event.
  void refuse(Job& job, cfg::sdo_manager::DynamicSdoError error, SdoManagerReason why);

  static Step write_step(cfg::NodeId node, cfg::ObjectAddress address, std::uint32_t value,
                         std::size_t size, bool must_succeed = true, bool retry = true);
  static Step read_step(cfg::NodeId node, cfg::ObjectAddress address, bool retry = true);

  LocalDictionary& dict_;
  SdoManagerPort& port_;
  cfg::NodeId node_id_;
  SdoManagerSettings settings_;
  bool enabled_ = false;
  /// By node-ID.
  std::map<cfg::NodeId, Srd, std::less<>> srds_;
  std::vector<Connection> connections_;  ///< in row order
  std::deque<Job> jobs_;
  bool in_flight_ = false;    ///< a transfer of jobs_.front() runs
  std::uint64_t serial_ = 0;  ///< of the transfer in flight (its tag)
  bool rescan_ = false;       ///< a 6E0h came during a scan
  /// The SRD whose channel carries the SDO request being served.
  std::optional<cfg::NodeId> writer_;
  /// This device's server channels for SRDs (1201h..), served from its dictionary, and the SRD
  /// each was opened for (its sub 3): the writer of a 1F00h/1F01h that arrives on it.
  SdoServerChannels channels_;
  std::map<std::uint16_t, cfg::NodeId> channel_clients_;
  /// Slaves the manager watches for SRDs with Req EC.
  std::set<cfg::NodeId> watched_;
};
static_assert(Engine<SdoManagerProcess>);

}  // namespace nmt
