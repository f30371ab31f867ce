// The NMT master's SDO transfers: one client per slave (SdoClientMux) and the scheduler in front
// of it. The boot's transfers (CiA 302-2 §3.4-§3.5, DSP 302 §9) share a window of transfers in
// flight and, with the bit rate known, a bus-load budget (MasterOptions::pacing.bitrate,
// bus_load_limit); a transfer that times out is repeated (MasterOptions::sdo.retries) before its
// owner sees it fail; transfers to a slave whose default SDO the SDO manager gave to an SRD wait
// until it is free again (DSP 302 §7.1). The application's and the SDO manager's transfers pass
// the window. Private to the library.
//
// An engine of the shape of nmt/engine.hpp whose events are the finished transfers, each with its
// owner (a boot try, the application, the SDO manager), and the software update's progress. It
// reaches the master only through SdoTransferPort (is a default SDO given out, does a boot try
// still run).
//
// The master settles every call in rounds (NmtMaster::Impl::settle), and the scheduler's calls
// follow them: collect() counts the requests of the round into the pacing and takes the clients'
// results; dispatch_next() hands one result to its owner at a time (its answer may start the next
// transfer before the next result is looked at); release_held() and pump() then start what may
// go; settled() says when a round put nothing new out. The frames go into the Output of each
// call; the master hands them to the bus at the end of its call, after the call's NMT commands
// (§6.1 order: a reset reaches a slave before the request that follows it). Results stay inside
// until collect(): a result the clients report is seen in the next round, with the pacing
// counted first.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <utility>
#include <variant>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/master/master_options.hpp"
#include "nmt/sdo/sdo_client.hpp"

namespace nmt {

/// What the scheduler needs of the NMT master, and nothing else.
class SdoTransferPort {
 public:
  virtual ~SdoTransferPort() = default;
  /// DSP 302 §7.1: the SDO manager gave `node`'s default SDO to an SRD (or is about to): the
  /// master's own transfers to it wait (a second client on it would collide with the SRD's).
  virtual bool default_sdo_given_out(cfg::NodeId node) const = 0;
  /// Boot try `try_id` of `node` still runs: its waiting transfers may start and its results
  /// count; those of an ended try are dropped.
  virtual bool boot_try_runs(cfg::NodeId node, std::uint64_t try_id) const = 0;
  /// The master knows `node`'s NMT state from a frame of its own (boot-up, heartbeat, guarding
  /// reply): it is on the bus, so a read it has not answered was lost, not unheard.
  virtual bool heard_from(cfg::NodeId node) const = 0;
};

class SdoTransferScheduler {
 public:
  /// Owners of transfers (no member initializers: a variant of them is default-constructible
  /// inside the class, value-initialized). A boot try's transfers are windowed, paced and dropped
  /// with the try.
  struct BootTry {
    std::uint64_t try_id;
    bool operator==(const BootTry&) const = default;
  };
  /// The application's (NmtMaster::sdo_upload/sdo_download): `id` is the one the caller got.
  struct Application {
    SdoClient::TransferId id;
    bool operator==(const Application&) const = default;
  };
  /// The SDO manager's: `tag` is handed back with the result (SdoManagerTransfer::tag).
  struct Manager {
    std::uint64_t tag;
    bool operator==(const Manager&) const = default;
  };
  using Owner = std::variant<BootTry, Application, Manager>;

  /// What an owner asks for.
  struct Request {
    cfg::NodeId node;
    cfg::ObjectAddress object;
    bool upload = false;
    std::vector<std::uint8_t> data{};  ///< download: the value (kept for a repetition)
    Duration timeout{0};               ///< per response (SdoTransferOptions::timeout)
    unsigned retries = 0;              ///< repetitions after a timeout the client detected
  };

  /// A transfer ended for its owner (after its repetitions); `result.id` is the client's.
  struct Finished {
    cfg::NodeId node;
    Owner owner;
    SdoResult result;
  };
  /// The software update's 1F50h download (DSP 302 §9) of a boot try: `done` of `total` bytes
  /// confirmed.
  struct ProgramProgress {
    cfg::NodeId node;
    std::size_t done = 0;
    std::size_t total = 0;
    bool operator==(const ProgramProgress&) const = default;
  };
  using Event = std::variant<Finished, ProgramProgress>;
  using Output = Outbox<Event>;

  /// What of MasterOptions the scheduler reads (MasterOptions holds the defaults and reasons).
  struct Settings {
    std::uint32_t bitrate_bps = 0;  ///< 0: unknown, the boot is not paced
    double bus_load_limit = 0.97;   ///< share of the bus the pacing allows (0.05..1)
    Duration sdo_timeout{0};        ///< the application's transfers
    std::size_t block_threshold = kBlockDownloadThreshold;  ///< block download above this size
    /// The boot's repetition of expedited requests: the lower bound (MasterSdoOptions).
    Duration repeat_floor = std::chrono::milliseconds(20);
    static Settings from(const MasterOptions& options);
  };

  /// How many of a slave's last answer times its repetition time is learnt from.
  static constexpr std::size_t kAnswerWindow = 8;

  /// The window's size at the start and at most: transfers of the boot in flight.
  static constexpr double kMaxWindow = 128;

  SdoTransferScheduler(SdoTransferPort& port, Settings settings);

  // --- frames and time (engine.hpp). Results wait for collect().
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  /// The clients' deadlines; and, when boot transfers wait and the window has room, the end of
  /// the pacing (else an answer frees a place, and the call that brings it starts the next).
  std::optional<TimePoint> next_deadline() const;
  /// Pacing: a frame of another node (heartbeats, PDOs, others' SDO) takes its share of the
  /// load limit too, so the boot's requests leave room for it. The master calls it first for
  /// every frame, before any of its parts may start a transfer on it.
  void pace_frame_of_others(const CanFrame& frame, TimePoint now);

  // --- starting and ending (no frames at once when the transfer waits)
  /// A transfer of boot try `try_id`: held while the default SDO is given out, waits while the
  /// window is full, the pacing runs or others wait (in order); block download above
  /// Settings::block_threshold. A start the client refuses (SdoClient::check_start) ends at once
  /// with its words in SdoResult::refusal, reported at the next dispatch.
  void start_boot(std::uint64_t try_id, Request request, TimePoint now, Output& out);
  /// The application's transfer (Settings::sdo_timeout, no repetition, block download above the
  /// threshold): its id, or the client's words (nothing started) when it cannot start. It may
  /// be held, never windowed.
  cfg::Result<SdoClient::TransferId> start_application(cfg::NodeId node, cfg::ObjectAddress object,
                                                       bool upload, std::vector<std::uint8_t> data,
                                                       TimePoint now, Output& out);
  /// The SDO manager's transfer, started at once (it manages the default SDOs it gives out).
  void start_manager(std::uint64_t tag, Request request, TimePoint now, Output& out);
  /// A boot try of `node` ended: the boot's transfers to `node` stop (abort 0800 0000h on the bus
  /// for the one running, the next queued on its client starts) and their results are forgotten.
  /// Only the boot's: the SDO manager's and the application's to `node` go on and end with a
  /// result for their owner (CiA 302-2 §3.3: the boot runs asynchronously to the other processes;
  /// DSP 302 §7.1: the SDO manager's accesses are its own). Its waiting and held transfers are
  /// dropped when their turn comes (SdoTransferPort::boot_try_runs).
  void cancel_boot(cfg::NodeId node, TimePoint now, Output& out);
  /// The SDO manager's transfers to `node` stop as cancel_boot() stops the boot's, their results
  /// forgotten: for a manager whose tables were cleared (SdoManagerProcess::clear, when the
  /// master resets all nodes), to which they would come stale.
  void cancel_manager(cfg::NodeId node, TimePoint now, Output& out);

  // --- settling a call of the master, in rounds (see the top of this file)
  /// The requests since the last call into the pacing, the clients' results into the queue;
  /// true when results wait for dispatch_next().
  bool collect(TimePoint now);
  /// Takes the next waiting result: the window learns from it, a timeout is repeated, and
  /// otherwise its owner's event goes to `out` (for a boot try that still runs: first the last
  /// ProgramProgress of a 1F50h download, then Finished). False when none waited.
  bool dispatch_next(TimePoint now, Output& out);
  /// Starts the held transfers whose slave's default SDO is free again, in order.
  void release_held(TimePoint now, Output& out);
  /// Starts waiting boot transfers while the window and the pacing allow (paced: one per
  /// round, so that its frames are counted before the next), the slave whose try is furthest
  /// behind first, each slave's own in order.
  void pump(TimePoint now, Output& out);
  /// The round put nothing new out: no new results of the clients, no frames since collect().
  bool settled() const { return client_out_.events.empty() && unpaced_frames_ == 0; }
  /// The software update's progress as the clients have it confirmed, for the live view: about
  /// every 1/32 of the image (a 256 KiB image gives some 32 events).
  void report_progress(Output& out);

  // --- what tests and the master read
  double window() const { return window_; }
  /// What a boot request of `timeout` to `node` is repeated after now: 2 x the largest of the
  /// slave's last kAnswerWindow answer times, at least Settings::repeat_floor; nullopt while the
  /// slave has not answered or when that is not below `timeout`.
  std::optional<Duration> repeat_after(cfg::NodeId node, Duration timeout) const;
  /// What a boot read (upload) of `timeout` to a slave that has not answered an SDO yet but was
  /// heard from (SdoTransferPort::heard_from) is repeated after: the same rule over the last
  /// kAnswerWindow answers of any slave; nullopt before any slave answered. A read changes
  /// nothing on the device, so a present slave's first request (its 1000h) need not cost a full
  /// timeout when it or its answer is lost; an absent slave's reads are not multiplied.
  std::optional<Duration> unanswered_read_repeat_after(Duration timeout) const;
  std::size_t boot_in_flight() const { return boot_in_flight_; }
  std::size_t waiting() const { return waiting_.size(); }
  std::size_t held() const { return held_.size(); }
  TimePoint paced_until() const { return paced_until_; }

 private:
  struct Transfer {
    Owner owner;
    cfg::ObjectAddress object;
    bool upload = false;
    std::vector<std::uint8_t> data;
    SdoTransferOptions options;
    unsigned retries_left = 0;
    TimePoint launched{};      ///< when its (latest) request went out: the window's loss events
    std::size_t reported = 0;  ///< software update: the bytes the last ProgramProgress reported
  };
  using Key = std::pair<cfg::NodeId, SdoClient::TransferId>;

  static bool is_boot(const Transfer& t) { return std::holds_alternative<BootTry>(t.owner); }
  Transfer transfer(Owner owner, Request& request) const;
  void schedule(cfg::NodeId node, Transfer transfer, TimePoint now, Output& out);
  void launch(cfg::NodeId node, Transfer transfer, TimePoint now, Output& out);
  void forget(std::map<Key, Transfer>::iterator it);
  /// Ends the transfers to `node` of owners of type `O` (cancel_boot, cancel_manager).
  template <class O>
  void cancel_of(cfg::NodeId node, TimePoint now, Output& out);
  void dispatch(const SdoResult& result, TimePoint now, Output& out);
  /// The clients' frames into `out`, counted for the pacing.
  void take_frames(Output& out);
  /// Pacing: the bus time `bits` take within the load limit.
  Duration paced_time(double bits) const;

  SdoTransferPort* port_;
  Settings settings_;
  SdoClientMux clients_;
  /// Scratch output of the clients: frames go out after each call; results wait for collect().
  Outbox<SdoResult> client_out_;
  std::map<Key, Transfer> transfers_;  ///< started, by node and client id
  std::deque<SdoResult> results_;      ///< results not yet dispatched

  // The window of boot transfers in flight: halved once per loss event (unpaced), grown by one
  // per window's worth of answers.
  std::size_t boot_in_flight_ = 0;
  double window_ = kMaxWindow;
  /// When the window was last halved: timeouts of transfers launched before are the same loss
  /// event and do not halve it again.
  std::optional<TimePoint> window_cut_;
  std::deque<std::pair<cfg::NodeId, Transfer>> waiting_;  ///< boot transfers beyond the window
  /// Transfers to a slave whose default SDO is given out (DSP 302 §7.1), in order.
  std::deque<std::pair<cfg::NodeId, Transfer>> held_;
  /// Boot transfers of each node's current try that ended (pump: the slave furthest behind).
  std::array<std::size_t, 128> done_{};
  /// Each slave's last answer times (SdoResult::longest_answer), a ring of kAnswerWindow.
  struct AnswerTimes {
    std::array<Duration, kAnswerWindow> recent{};
    std::size_t count = 0;  ///< answers recorded, up to kAnswerWindow
    std::size_t next = 0;   ///< the slot the next answer time goes to
  };
  std::array<AnswerTimes, 128> answer_times_{};
  AnswerTimes any_slave_answer_times_{};  ///< the same over every slave's answers
  std::optional<Duration> repeat_from(const AnswerTimes& times, Duration timeout) const;

  // Bus-load pacing (Settings::bitrate_bps): no new boot transfer before paced_until_.
  TimePoint paced_until_{};
  std::size_t unpaced_frames_ = 0;  ///< frames out since the last collect()
  double unpaced_bits_ = 0;         ///< their bits and those of the answers they cause
  /// clients_.unanswered_bits() when the pacing last counted: the bits of block segments since.
  std::uint64_t unanswered_bits_paced_ = 0;

  SdoClient::TransferId next_application_id_ = 1;
  /// Keys of boot/manager transfers the client refused, counting down from the top, where the
  /// client's own ids (from 1 up) do not reach.
  SdoClient::TransferId next_refused_id_ = 0xFFFFFFFF;
};

static_assert(Engine<SdoTransferScheduler>);

}  // namespace nmt
