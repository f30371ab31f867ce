// The SDO client (CiA 301 §7.2.4: expedited, segmented and block transfer) and SdoClientMux for
// many servers, nmt::Engine objects (nmt/engine.hpp is the contract) on top of the frame codec
// (nmt/sdo/sdo_frame.hpp). Implemented from public knowledge of CiA 301.
//
// Protocol choices where CiA 301 leaves room: the client aborts with 0504 0000 when a response
// does not come within SdoTransferOptions::timeout; in a block upload it acknowledges when it
// sees the block's last sequence number or the "no more segments" flag. A block round that
// acknowledges no segment (sent or received) brings nothing forward and does not restart the
// timeout, so a transfer the server reads as another one (after a lost abort) still ends; the
// sdo::kMaxEmptyBlockRounds-th such round in a row of a block upload aborts with 0504 0003.
// Limitation of the protocol: SDO frames carry no transaction number. A response that arrives
// after its transfer ended (a slow server answering after the client's timeout, or the answer to
// a cancelled request) is recognised when it is an initiate response naming another object:
// it is ignored. A late segment response cannot be told apart and can be taken for one of the
// next transfer; keep client timeouts above server response times.
//
// Repeated requests (SdoTransferOptions::repeat_after): CiA 301 leaves the response timeout to
// the application, and on a lossy bus a lost request or answer costs the whole timeout. An
// expedited request (initiate upload, expedited download) can be sent again as it was: reading
// twice reads the same object, and writing the same value twice leaves the same value, so the
// server's second answer is the same as its first. The client re-sends such a request when no
// answer came within repeat_after (at most sdo::kMaxRepeats times) and still ends the transfer
// only at the full timeout from its first request. Never repeated: downloads to 1010h/1011h
// (store/restore: each write starts a store) and 1F50h/1F51h (program download and control),
// downloads that are not expedited, segment and block frames (their toggle and sequence state
// moves on). An answer to a repeated request that arrives after another one was taken (the
// server answered both) is recognised and ignored while the transfer's timeout runs: an initiate
// response or an abort naming the repeated object where the transfer in progress expects no such
// frame, or names another object. One limit: an initiate upload of a value longer than 4 bytes
// whose answer was only late meets a server already in its segmented upload, which may refuse
// the second initiate (0504 0001): the transfer ends with that abort, never with a wrong value
// (the master's boot repeats only uploads of 32-bit objects).
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/deadline_queue.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/sdo/sdo_frame.hpp"

namespace nmt {

class LocalDictionary;

/// How a transfer went over the bus.
enum class SdoProtocol : std::uint8_t { Expedited, Segmented, Block };

struct SdoClientConfig {
  /// client -> server, a CiA 301 COB-ID word (1280h sub 1): bit 29 selects a 29-bit identifier.
  cfg::CobId request_cob_id = cfg::CobId::standard(sdo::kDefaultRequestId);
  /// server -> client (1280h sub 2).
  cfg::CobId response_cob_id = cfg::CobId::standard(sdo::kDefaultResponseId);
  /// The server's node-ID, for reports (SdoResult::node_id); nullopt: unknown.
  std::optional<cfg::NodeId> node_id;

  static SdoClientConfig for_node(cfg::NodeId node_id);
  /// The channel of client parameter `index` (1280h-12FFh, CiA 301 §7.5.2.34): sub 1 request,
  /// sub 2 response, sub 3 the server's node-ID (none when absent, 0 or above 127). nullopt when
  /// `index` is no client entry of `dict`, or when either COB-ID is not usable (bit 31 set,
  /// ill-formed).
  static std::optional<SdoClientConfig> from_dictionary(const LocalDictionary& dict,
                                                        std::uint16_t index);
};

enum class SdoMode : std::uint8_t {
  /// Downloads of 1..4 bytes expedited, others segmented; uploads as the server answers.
  Auto,
  /// Downloads segmented even when they would fit expedited (testing); uploads as Auto.
  Segmented,
  /// Block transfer; when the server answers the block initiate with abort 0504 0001, the
  /// transfer is retried once as Auto.
  Block,
};

/// Downloads of more bytes than this go by block transfer (falling back to segmented) where the
/// caller does not choose: MasterOptions::sdo.block_threshold's default and `cfgmgr sdo` writes.
/// CiA 301 leaves the protocol to the client. A download of n segments of 7 bytes takes 2n + 2
/// frames segmented (each segment confirmed) and about n + 5 by block (§7.2.4.3.9: initiate, one
/// confirmation per sub-block, end); above 64 bytes (10 segments) block saves a third of the
/// frames, while shorter values stay in the protocol every SDO server has.
inline constexpr std::size_t kBlockDownloadThreshold = 64;

struct SdoTransferOptions {
  /// Longest wait for each server response; then abort 0504 0000 is sent and the transfer
  /// ends with Timeout. It runs from when the client hands its frames out; a block download's
  /// sub-block of up to 127 frames spends about 127 x 120 bit times on the bus first (1.5 s at
  /// 10 kbit/s), so choose the timeout (or the server's block size) for the bit rate.
  Duration timeout = std::chrono::milliseconds(1000);
  SdoMode mode = SdoMode::Auto;
  /// Block size the client asks for in block uploads, 1..127.
  std::uint8_t block_size = 127;
  /// Block upload: protocol switch threshold sent to the server (0: never switch). A server may
  /// answer with a normal upload when the value has at most this many bytes.
  std::uint8_t protocol_switch_threshold = 0;
  /// Block transfers check the CRC when the server supports it.
  bool crc = true;
  /// Largest upload accepted; a server sending more is aborted with 0504 0005.
  std::size_t max_size = std::size_t{16} << 20;
  /// When set (and positive): an expedited request (initiate upload, expedited download) not
  /// answered within this time is sent again, identically, up to sdo::kMaxRepeats times, each
  /// repeat_after after the one before while that is before the timeout; the transfer still
  /// ends with Timeout only `timeout` after its first request. Never for downloads to
  /// 1010h/1011h/1F50h/1F51h nor for segment or block frames (see the top of this file).
  /// nullopt: no repetition (the default).
  std::optional<Duration> repeat_after;
};

namespace sdo {
/// How often one request is sent again at most (SdoTransferOptions::repeat_after): with a frame
/// loss rate p each try loses its request or answer with about 2p, so 1 + 3 tries all fail with
/// about (2p)^4 (1.6e-7 at 1 % loss).
inline constexpr unsigned kMaxRepeats = 3;
}  // namespace sdo

/// The outcome of one transfer.
struct SdoResult {
  std::uint32_t id = 0;  ///< the TransferId
  /// The server's node-ID (SdoClientConfig::node_id); nullopt for a channel that names none.
  std::optional<cfg::NodeId> node_id;
  cfg::ObjectAddress address;
  bool upload = false;
  SdoAbort abort = SdoAbort::None;  ///< None on success
  /// True when the server sent the abort; false when the client detected the problem (and sent
  /// the abort frame itself) or on success.
  bool aborted_by_server = false;
  SdoProtocol protocol = SdoProtocol::Expedited;  ///< the protocol the transfer ended with
  bool fell_back = false;          ///< Block mode retried as Auto after abort 0504 0001
  std::vector<std::uint8_t> data;  ///< upload: the value
  TimePoint started{};             ///< time of the first request frame
  TimePoint finished{};
  /// Not empty: the transfer never reached the bus, and this says why (SdoClient::check_start's
  /// words); `abort` is None then, as no abort was sent or received. Only a driver that queues
  /// transfers before it gives them to the client reports such a result (NmtMaster's boot).
  std::string refusal;
  /// How often a request of the transfer was sent again (SdoTransferOptions::repeat_after).
  unsigned repeats = 0;
  /// The longest time the server took to answer one of the transfer's requests (from when the
  /// client handed the request out to when its answer came), over the expedited and segment
  /// requests sent once; nullopt when none such was answered (a repeated request's answer may
  /// answer either copy and is not counted). What a caller learns a server's answer times from.
  std::optional<Duration> longest_answer;

  bool ok() const { return abort == SdoAbort::None && refusal.empty(); }
  bool operator==(const SdoResult&) const = default;
};

/// Client side of one SDO channel (one server). Transfers are queued and run one at a time, in
/// order; use one client per server (or SdoClientMux) to talk to many nodes at once.
///
/// An nmt::Engine whose events are the results: every transfer download() or upload() started
/// (returned an id for) ends with exactly one SdoResult reported into the Output of the call in
/// which it ended (on_frame, on_timer, cancel). That is the only way results come back: there is
/// no per-transfer callback and no result store, so a driver's event handler (SimEngineNode,
/// EngineRef) sees every result. A handler may start the next transfer through the driver's
/// apply(). A transfer that cannot start (check_start) returns the error and puts nothing into
/// `out` (engine.hpp rule 5).
class SdoClient {
 public:
  using TransferId = std::uint32_t;
  using Event = SdoResult;
  using Output = Outbox<SdoResult>;

  explicit SdoClient(SdoClientConfig config);

  /// Starts a download of `data` to (index, sub): when no transfer runs, its first frame is in
  /// `out` when the call returns; otherwise it is queued behind the running ones. The error of
  /// check_start (nothing in `out`) when it cannot start.
  cfg::Result<TransferId> download(std::uint16_t index, std::uint8_t sub,
                                   std::vector<std::uint8_t> data, TimePoint now, Output& out,
                                   SdoTransferOptions options = {});
  /// Starts (or queues) an upload of (index, sub); the value arrives in SdoResult::data. The
  /// error of check_start (nothing in `out`) when it cannot start.
  cfg::Result<TransferId> upload(std::uint16_t index, std::uint8_t sub, TimePoint now, Output& out,
                                 SdoTransferOptions options = {});
  /// Why a transfer with `options` (a download: of `download_size` bytes) cannot start: a
  /// response timeout that is not positive (every response would be overdue when it is asked
  /// for), or a value longer than the 32-bit size of a download initiate can state (CiA 301
  /// §7.2.4.3.3). Block sizes outside 1..127 are taken as the nearest (sdo::clamp_block_size).
  static cfg::Status check_start(const SdoTransferOptions& options,
                                 std::optional<std::size_t> download_size);
  /// Ends a transfer with `code` (None is taken as General): a running one sends its abort frame
  /// into `out` and the next queued one starts; a queued one is removed. Either reports its
  /// result into `out`. False (nothing done) when `id` is not queued or running.
  bool cancel(TransferId id, TimePoint now, Output& out, SdoAbort code = SdoAbort::General);

  /// Handles a frame; false when it is not a response for this client.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Times out the running transfer (abort 0504 0000) when its response is overdue.
  void on_timer(TimePoint now, Output& out);
  /// The response timeout of the running transfer; nullopt when idle. Queued transfers start
  /// when the one before ends, in the same call, so they never wait for a timer.
  std::optional<TimePoint> next_deadline() const;

  /// How far the running download has come: the bytes the server confirmed so far (each
  /// segment's response, each sub-block's acknowledgement, CiA 301 §7.2.4.3) of all of them.
  /// nullopt when no transfer runs or the running one is an upload. For progress displays.
  struct Progress {
    TransferId id = 0;
    std::size_t done = 0;
    std::size_t total = 0;
  };
  std::optional<Progress> download_progress() const;

  /// Bus bits (nmt::frame_bits) of the frames this client sent that no frame answers: the
  /// segments of a download sub-block but its last, which the acknowledgement follows
  /// (CiA 301 §7.2.4.3.11). A sender that paces the bus by counting each request together with
  /// its answer (the NMT master) subtracts these. Only grows.
  std::uint64_t unanswered_bits() const { return unanswered_bits_; }

  /// True while a transfer runs or is queued.
  bool busy() const { return active_ != nullptr || !queue_.empty(); }
  std::size_t queued() const { return queue_.size() + (active_ ? 1 : 0); }
  const SdoClientConfig& config() const { return config_; }

 private:
  enum class State : std::uint8_t {
    InitiateDownload,  // initiate sent (expedited or segmented)
    DownloadSegment,   // segment sent
    InitiateUpload,
    UploadSegment,      // segment request sent
    BlockDownloadInit,  // block initiate sent
    BlockDownload,      // sub-block sent, waiting for the acknowledgement
    BlockDownloadEnd,   // end request sent
    BlockUploadInit,    // block initiate sent
    BlockUpload,        // receiving a sub-block
    BlockUploadEnd,     // waiting for the server's end request
  };
  struct Transfer {
    TransferId id = 0;
    bool upload = false;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;  // download: value; upload: received bytes
    SdoTransferOptions options;
    State state = State::InitiateDownload;
    SdoMode mode = SdoMode::Auto;
    bool fell_back = false;
    SdoProtocol protocol = SdoProtocol::Expedited;
    bool toggle = false;
    std::size_t offset = 0;           // download: bytes acknowledged; upload: unused
    std::optional<std::size_t> size;  // upload: indicated size
    bool crc = false;
    std::uint8_t block_size = 0;
    std::uint8_t sent_in_block = 0;  // block download: segments on the wire
    std::uint8_t ack_seq = 0;        // block upload: last in-order sequence number
    bool last_received = false;      // block upload: c=1 received in order
    int empty_rounds = 0;            // block upload: sub-blocks in a row acknowledging nothing
    bool block_has_last = false;     // block download: the sub-block on the wire ends the data
    std::optional<TimePoint> started;
    TimePoint deadline{};
    // Repetition (SdoTransferOptions::repeat_after) of the request on the wire.
    sdo::Payload request{};              // the last request frame sent
    TimePoint sent_at{};                 // when it was handed out
    bool request_repeated = false;       // it was sent again: its answer's time is ambiguous
    std::optional<TimePoint> repeat_at;  // when it is sent again; nullopt: never
    unsigned repeats = 0;                // repetitions sent in the transfer
    std::optional<Duration> longest_answer;
  };
  // Answers still possible to the repeated requests of a transfer that took one answer already
  // (the server answered two copies): ignored while `until` (that transfer's full timeout) runs.
  struct StrayAnswers {
    cfg::ObjectAddress address;
    unsigned count = 0;
    TimePoint until{};
  };

  void start(Transfer& t, TimePoint now, Output& out);
  void handle(Transfer& t, const sdo::Payload& d, TimePoint now, Output& out);
  void handle_response(Transfer& t, const sdo::ServerFrame& f, TimePoint now, Output& out);
  void aborted(Transfer& t, const sdo::Abort& abort, TimePoint now, Output& out);
  void block_upload_segment(Transfer& t, const sdo::BlockSegment& f, TimePoint now, Output& out);
  void send_download_segment(Transfer& t, TimePoint now, Output& out);
  void send_download_sub_block(Transfer& t, TimePoint now, Output& out);
  void send(Transfer& t, const sdo::Payload& d, TimePoint now, Output& out);
  /// Arms the repetition of the request just sent when the transfer may repeat it.
  void arm_repeat(Transfer& t, TimePoint now);
  void repeat(Transfer& t, TimePoint now, Output& out);
  /// The answer to the request on the wire arrived: its time counts unless it was repeated.
  static void note_answer(Transfer& t, TimePoint now);
  /// True (and the stray answer consumed) when `f` answers an earlier copy of a repeated
  /// request: an initiate response or abort naming the repeated object.
  bool stray_answer(const sdo::ServerFrame& f, TimePoint now);
  void fail(Transfer& t, SdoAbort code, bool send_frame, TimePoint now, Output& out);
  void finish(SdoAbort code, bool by_server, TimePoint now, Output& out);
  void pump(TimePoint now, Output& out);
  SdoResult result_of(const Transfer& t, SdoAbort code) const;
  cfg::Result<TransferId> enqueue(std::unique_ptr<Transfer> transfer, TimePoint now, Output& out);

  SdoClientConfig config_;
  TransferId next_id_ = 1;
  std::unique_ptr<Transfer> active_;
  std::deque<std::unique_ptr<Transfer>> queue_;
  StrayAnswers stray_;
  std::uint64_t unanswered_bits_ = 0;
  // The running sum of the mux that owns this client (SdoClientMux::unanswered_bits); null for
  // a client of its own. Points into the mux's heap cell, so it survives moves of the mux.
  std::uint64_t* mux_unanswered_bits_ = nullptr;
  // Tells the owning mux's deadline queue (SdoClientMux::deadlines_) when next_deadline()
  // changed; every public call that can change it ends with it. Null for a client of its own.
  void sync_mux_deadline();
  DeadlineQueue<std::uint32_t>* mux_deadlines_ = nullptr;
  std::uint32_t mux_key_ = 0;                 // this client's key in clients_ and the queue
  std::optional<TimePoint> listed_deadline_;  // this client's deadline in the queue
  friend class SdoClientMux;
};
static_assert(Engine<SdoClient>);

/// Many SdoClients on one bus, one per server node, for transfers to many nodes at once. Frames
/// are routed by response COB-ID; the deadline is the earliest of all clients'. An nmt::Engine
/// with the clients' results as its events (SdoResult::node_id says whose); start transfers on
/// client(n) with the Output of the mux's call.
class SdoClientMux {
 public:
  using Event = SdoResult;
  using Output = Outbox<SdoResult>;

  /// The client for `node_id` with the pre-defined COB-IDs, created on first use. The
  /// reference stays valid for the mux's lifetime.
  SdoClient& client(cfg::NodeId node_id);
  /// Adds (or returns the existing) client for a channel with other COB-IDs, keyed by its
  /// response identifier.
  SdoClient& add(SdoClientConfig config);

  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;
  bool busy() const;
  /// The sum of the clients' SdoClient::unanswered_bits(): a running figure each client adds
  /// to as its own grows, so the master's settle pass asks it in O(1), not per client.
  std::uint64_t unanswered_bits() const;

 private:
  // By the response identifier as a COB-ID word (cfg::CobId::of), so 11- and 29-bit ids differ.
  std::map<std::uint32_t, std::unique_ptr<SdoClient>> clients_;
  // Added to by the clients as their figures grow (SdoClient::mux_unanswered_bits_).
  std::unique_ptr<std::uint64_t> unanswered_bits_ = std::make_unique<std::uint64_t>(0);
  // The clients' deadlines, kept by the clients (SdoClient::mux_deadlines_), so next_deadline()
  // and on_timer do not visit every client; a heap cell like unanswered_bits_.
  std::unique_ptr<DeadlineQueue<std::uint32_t>> deadlines_ =
      std::make_unique<DeadlineQueue<std::uint32_t>>();
  std::vector<std::uint32_t> due_;  // on_timer's scratch: the keys of the due clients
};
static_assert(Engine<SdoClientMux>);

}  // namespace nmt
