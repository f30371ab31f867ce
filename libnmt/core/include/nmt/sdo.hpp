// SDO client and server (CiA 301 §7.2.4: expedited, segmented and block transfer), sans-I/O.
// Implemented from public knowledge of CiA 301 (not in spec/).
//
// Both engines are fed frames and the current time and answer with frames to send and their next
// deadline; they never read a clock or touch a bus:
//   engine.on_frame(frame, now, out);   // a received frame; frames to send appended to `out`
//   engine.on_timer(now, out);          // call when now >= engine.next_deadline()
//   engine.next_deadline();             // nullopt: nothing to wait for
// Any call may change the deadline; drivers re-read it after every call (SimEngineNode does).
//
// Protocol choices where CiA 301 leaves room:
// - Frames with DLC < 8 are read as if padded with zeros; DLC 0 and RTR frames are ignored.
// - A request that does not fit the server's state (e.g. a new initiate during a segmented
//   transfer) is answered with abort 0504 0001 and the server returns to idle.
// - Block transfer: the receiver acknowledges when it sees the block's last sequence number or
//   the "no more segments" flag, with the last sequence number received in order; the sender
//   then resends from the segment after it. Sequence number 0 or above the block size aborts
//   with 0504 0003.
// Limitation of the protocol: SDO frames carry no transaction number. A response that arrives
// after its transfer ended (server latency above the client's timeout) can be taken for a
// response of the next transfer on the channel; keep client timeouts above server latency.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "nmt/frame.hpp"
#include "nmt/local_dictionary.hpp"
#include "nmt/sdo_abort.hpp"

namespace nmt {

/// CRC-16 of SDO block transfer (CiA 301 block protocols: polynomial x^16 + x^12 + x^5 + 1, initial
/// value 0, no reflection, i.e. CRC-16/XMODEM). Pass the previous result as `crc` to continue.
std::uint16_t sdo_block_crc(std::span<const std::uint8_t> data, std::uint16_t crc = 0);

/// How a transfer went over the bus.
enum class SdoProtocol : std::uint8_t { Expedited, Segmented, Block };

// ================================================================================== server ==

struct SdoServerConfig {
  std::uint32_t request_cob_id = 0x600;   ///< client -> server (1200h sub 1)
  std::uint32_t response_cob_id = 0x580;  ///< server -> client (1200h sub 2)
  /// When false, block requests are answered with abort 0504 0001 (clients fall back).
  bool block_transfer = true;
  /// Every response leaves this long after the request that caused it (fault injection).
  Duration response_latency{0};
  /// A segmented or block transfer with no request for this long is aborted with 0504 0000.
  Duration timeout = std::chrono::milliseconds(2000);
  /// Block size the server asks for in block downloads, 1..127.
  std::uint8_t block_size = 127;
  /// Largest download kept in memory (bigger ones abort with 0504 0005 "out of memory").
  std::size_t max_download_size = std::size_t{16} << 20;

  /// The pre-defined connection set: 0x600 + node_id / 0x580 + node_id.
  static SdoServerConfig for_node(std::uint8_t node_id);
  /// COB-IDs from 1200h sub 1/2 of the dictionary when present and valid (bit 31 clear, 11-bit
  /// or with bit 29 for 29-bit ids), else the pre-defined ones for the dictionary's node-ID.
  static SdoServerConfig from_dictionary(const LocalDictionary& dict);
};

/// The SDO server of one node, serving one LocalDictionary (which must outlive it). One transfer
/// at a time, as CiA 301 defines for one SDO channel.
class SdoServer {
 public:
  SdoServer(LocalDictionary& dict, SdoServerConfig config);

  /// Handles a frame; false (and nothing done) when it is not a request for this server.
  bool on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& out);
  void on_timer(TimePoint now, std::vector<CanFrame>& out);
  std::optional<TimePoint> next_deadline() const;

  const SdoServerConfig& config() const { return config_; }
  /// Takes effect for the next request; a transfer in progress is dropped without a frame.
  void set_config(SdoServerConfig config);
  /// True while a segmented or block transfer is in progress.
  bool busy() const;
  /// Ends a transfer in progress by sending an abort with `code` (e.g. on an NMT reset).
  void abort(SdoAbort code, TimePoint now, std::vector<CanFrame>& out);

 private:
  enum class State : std::uint8_t {
    Idle,
    DownloadSegment,   // segmented download: waiting for the next segment
    UploadSegment,     // segmented upload: waiting for the next segment request
    BlockDownload,     // receiving sub-block segments
    BlockDownloadEnd,  // all data received: waiting for the end request
    BlockUploadStart,  // initiate answered: waiting for the start request
    BlockUpload,       // sub-block sent: waiting for the acknowledgement
    BlockUploadEnd,    // end sent: waiting for the end response
  };
  struct Pending {
    TimePoint due;
    CanFrame frame;
  };

  void handle(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void initiate_download(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void download_segment(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void start_upload(TimePoint now);
  void upload_segment(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void block_download(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void block_download_segment(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void block_upload(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void send_upload_sub_block(TimePoint now);
  void finish_download(TimePoint now, std::uint8_t command);
  void respond(const std::array<std::uint8_t, 8>& d, TimePoint now);
  void send_abort(SdoAbort code, TimePoint now);
  void reset();

  LocalDictionary* dict_;
  SdoServerConfig config_;
  State state_ = State::Idle;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  bool toggle_ = false;
  std::optional<std::size_t> size_;  // indicated size (download) / value size (upload)
  std::vector<std::uint8_t> buffer_;
  std::size_t offset_ = 0;  // upload: bytes sent and acknowledged
  // block transfer
  bool crc_ = false;
  std::uint8_t block_size_ = 0;
  std::uint8_t ack_seq_ = 0;        // download: last segment received in order
  std::uint8_t sent_in_block_ = 0;  // upload: segments in the sub-block on the wire
  bool last_received_ = false;      // download: segment with c=1 received in order
  bool block_has_last_ = false;     // upload: the sub-block on the wire ends the data
  std::optional<TimePoint> timeout_at_;
  std::deque<Pending> pending_;  // responses waiting out response_latency
};

// ================================================================================== client ==

struct SdoClientConfig {
  std::uint32_t request_cob_id = 0x600;   ///< client -> server
  std::uint32_t response_cob_id = 0x580;  ///< server -> client
  std::uint8_t node_id = 0;               ///< the server's node-ID, for reports (0: unknown)

  static SdoClientConfig for_node(std::uint8_t node_id);
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
};

/// The outcome of one transfer.
struct SdoResult {
  std::uint32_t id = 0;  ///< the TransferId
  std::uint8_t node_id = 0;
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  bool upload = false;
  SdoAbort abort = SdoAbort::None;  ///< None on success
  /// True when the server sent the abort; false when the client detected the problem (and sent
  /// the abort frame itself) or on success.
  bool aborted_by_server = false;
  SdoProtocol protocol = SdoProtocol::Expedited;  ///< the protocol the transfer ended with
  bool fell_back = false;          ///< Block mode retried as Auto after abort 0504 0001
  std::vector<std::uint8_t> data;  ///< upload: the value
  TimePoint started{0};            ///< time of the first request frame
  TimePoint finished{0};

  bool ok() const { return abort == SdoAbort::None; }
};

/// Client side of one SDO channel (one server). Transfers are queued and run one at a time, in
/// order; use one client per server (or SdoClientMux) to talk to many nodes at once.
class SdoClient {
 public:
  using TransferId = std::uint32_t;
  /// Called once when a transfer ends, from inside on_frame/on_timer (or cancel). It may start
  /// new transfers.
  using Callback = std::function<void(const SdoResult&)>;

  explicit SdoClient(SdoClientConfig config);

  /// Queues a download of `data` to (index, sub). It starts at the next on_timer (the deadline
  /// becomes "now"). Without a callback the result is kept for result()/take_result().
  TransferId download(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
                      SdoTransferOptions options = {}, Callback done = {});
  /// Queues an upload of (index, sub); the value arrives in SdoResult::data.
  TransferId upload(std::uint16_t index, std::uint8_t sub, SdoTransferOptions options = {},
                    Callback done = {});
  /// Ends a transfer: a running one sends an abort frame with `code` at the next on_timer, a
  /// queued one is removed; either reports `code`. False when `id` is not queued or running.
  bool cancel(TransferId id, SdoAbort code = SdoAbort::General);

  /// Handles a frame; false when it is not a response for this client.
  bool on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& out);
  void on_timer(TimePoint now, std::vector<CanFrame>& out);
  /// TimePoint{0} ("as soon as possible") while a queued transfer waits to start or a cancel
  /// waits to be sent; the response timeout of the running transfer; nullopt when idle.
  std::optional<TimePoint> next_deadline() const;

  /// The result of a finished transfer started without a callback; nullopt while it runs.
  const SdoResult* result(TransferId id) const;
  std::optional<SdoResult> take_result(TransferId id);
  /// True while a transfer runs or is queued.
  bool busy() const { return active_ != nullptr || !queue_.empty(); }
  std::size_t queued() const { return queue_.size() + (active_ ? 1 : 0); }
  const SdoClientConfig& config() const { return config_; }

 private:
  enum class State : std::uint8_t {
    Start,             // queued: initiate at the next on_timer
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
    Cancel,             // abort frame to send at the next on_timer
  };
  struct Transfer {
    TransferId id = 0;
    bool upload = false;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;  // download: value; upload: received bytes
    SdoTransferOptions options;
    Callback done;
    State state = State::Start;
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
    bool block_has_last = false;     // block download: the sub-block on the wire ends the data
    std::optional<TimePoint> started;
    TimePoint deadline{0};
    SdoAbort cancel_code = SdoAbort::None;
  };

  void start(Transfer& t, TimePoint now, std::vector<CanFrame>& out);
  void handle(Transfer& t, const std::array<std::uint8_t, 8>& d, TimePoint now,
              std::vector<CanFrame>& out);
  void send_download_segment(Transfer& t, TimePoint now, std::vector<CanFrame>& out);
  void send_download_sub_block(Transfer& t, TimePoint now, std::vector<CanFrame>& out);
  void send(Transfer& t, const std::array<std::uint8_t, 8>& d, TimePoint now,
            std::vector<CanFrame>& out);
  void fail(Transfer& t, SdoAbort code, bool send_frame, TimePoint now, std::vector<CanFrame>& out);
  void finish(SdoAbort code, bool by_server, TimePoint now);
  void pump(TimePoint now, std::vector<CanFrame>& out);
  void report(SdoResult result, Callback& done);
  std::unique_ptr<Transfer> new_transfer(std::uint16_t index, std::uint8_t sub,
                                         SdoTransferOptions options, Callback done);
  TransferId enqueue(std::unique_ptr<Transfer> transfer);

  SdoClientConfig config_;
  TransferId next_id_ = 1;
  std::unique_ptr<Transfer> active_;
  std::deque<std::unique_ptr<Transfer>> queue_;
  std::map<TransferId, SdoResult> results_;
};

/// Many SdoClients on one bus, one per server node, for transfers to many nodes at once. Frames
/// are routed by response COB-ID; the deadline is the earliest of all clients'.
class SdoClientMux {
 public:
  /// The client for `node_id` with the pre-defined COB-IDs, created on first use. The
  /// reference stays valid for the mux's lifetime.
  SdoClient& client(std::uint8_t node_id);
  /// Adds (or returns the existing) client for a channel with other COB-IDs, keyed by its
  /// response COB-ID.
  SdoClient& add(SdoClientConfig config);

  bool on_frame(const CanFrame& frame, TimePoint now, std::vector<CanFrame>& out);
  void on_timer(TimePoint now, std::vector<CanFrame>& out);
  std::optional<TimePoint> next_deadline() const;
  bool busy() const;

 private:
  std::map<std::uint32_t, std::unique_ptr<SdoClient>> clients_;  // by response COB-ID
};

}  // namespace nmt
