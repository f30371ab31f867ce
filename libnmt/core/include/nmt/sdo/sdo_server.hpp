// The SDO server (CiA 301 §7.2.4: expedited, segmented and block transfer), an nmt::Engine
// (nmt/engine.hpp is the contract) on top of the frame codec (nmt/sdo/sdo_frame.hpp). Implemented
// from public knowledge of CiA 301.
//
// Protocol choices where CiA 301 leaves room:
// - Frames with DLC < 8 are read as if padded with zeros; DLC 0 and RTR frames are ignored.
// - A request that does not fit the server's state (e.g. a new initiate during a segmented
//   transfer) is answered with abort 0504 0001 and the server returns to idle. An abort names
//   the transfer's object, or 0000h sub 00h when the request that caused it carries none.
// - A download without an indicated size is checked as its data grows (LocalDictionary::
//   check_write with the size received so far): it is aborted with the code the write of that
//   many bytes would get (0607 0012 above the entry's largest size, or a size hook's code) as
//   soon as it passes the limit, not after the whole value was buffered.
// - Block transfer: the server acknowledges when it sees the block's last sequence number or
//   the "no more segments" flag, with the last sequence number received in order; the client
//   then resends from the segment after it. Sequence number 0 or above the block size aborts
//   with 0504 0003, and so does the sdo::kMaxEmptyBlockRounds-th sub-block in a row that
//   acknowledges no segment.
// - Held confirmations: a write hook may accept a download and hold its confirmation
//   (WriteVerdict::hold, local_dictionary.hpp), e.g. until the value is durable on disk. The
//   confirmation (the expedited or last segment's response, or the block download end
//   response) then leaves only from complete_download(), which may instead abort the transfer
//   with a code. While held, the server runs no timeout (the client has its own) and treats a
//   new request as any request that does not fit its state (0504 0001); a client abort drops
//   the held confirmation, and so does set_config().
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/object_address.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/sdo/sdo_frame.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace nmt {

struct SdoServerConfig {
  /// client -> server (1200h sub 1), a CiA 301 COB-ID word: bit 29 selects a 29-bit
  /// identifier; with bit 31 set (or an ill-formed word) the server answers nothing.
  cfg::CobId request_cob_id = cfg::CobId::standard(sdo::kDefaultRequestId);
  /// server -> client (1200h sub 2).
  cfg::CobId response_cob_id = cfg::CobId::standard(sdo::kDefaultResponseId);
  /// When false, block requests are answered with abort 0504 0001 (clients fall back).
  bool block_transfer = true;
  /// A segmented or block transfer with no request for this long is aborted with 0504 0000.
  /// Block frames that bring nothing forward (a segment out of sequence, an acknowledgement of
  /// no segment) do not restart it.
  Duration timeout = std::chrono::milliseconds(2000);
  /// Block size the server asks for in block downloads, 1..127.
  std::uint8_t block_size = 127;
  /// Largest download kept in memory (bigger ones abort with 0504 0005 "out of memory").
  std::size_t max_download_size = std::size_t{16} << 20;

  /// The pre-defined connection set: 0x600 + node_id / 0x580 + node_id.
  static SdoServerConfig for_node(cfg::NodeId node_id);
  /// COB-IDs from 1200h sub 1/2 of the dictionary when both are present and usable (bit 31
  /// clear, well formed), else the pre-defined ones for the dictionary's node-ID.
  static SdoServerConfig from_dictionary(const LocalDictionary& dict);
  /// The channel of server parameter `index` (1200h-127Fh, CiA 301 §7.5.2.33). 1200h: as
  /// from_dictionary(dict). 1201h-127Fh: sub 1/2 as the dictionary holds them, also when bit 31
  /// is set (the server then answers nothing); a missing sub-index reads as not valid
  /// (80000000h).
  static SdoServerConfig from_dictionary(const LocalDictionary& dict, std::uint16_t index);
};

/// The SDO server of one node, serving one LocalDictionary (which must outlive it). One transfer
/// at a time, as CiA 301 defines for one SDO channel. An nmt::Engine that reports no events:
/// the dictionary's hooks see every access. Responses leave in the call that caused them; a
/// slow device is modelled by wrapping the server (nmt::Delayed in nmt/sim/fault_injection.hpp).
class SdoServer {
 public:
  using Event = NoEvent;
  using Output = Outbox<NoEvent>;

  SdoServer(LocalDictionary& dict, SdoServerConfig config);

  /// Handles a frame; false (and nothing done) when it is not a request for this server. The
  /// dictionary's hooks get `out` as their HookOutput.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// on_frame() for an owner of the dictionary (a slave node, the master): its hooks report into
  /// `hooks`, the output of the owner's call that passes the frame on.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out, HookOutput hooks);
  /// Aborts a segmented or block transfer with 0504 0000 when no request came for
  /// config().timeout.
  void on_timer(TimePoint now, Output& out);
  /// The timeout of the transfer in progress; nullopt when idle.
  std::optional<TimePoint> next_deadline() const;

  const SdoServerConfig& config() const { return config_; }
  /// Takes effect for the next request; a transfer in progress is dropped without a frame.
  void set_config(SdoServerConfig config);
  /// True while a segmented or block transfer is in progress, or a confirmation is held.
  bool busy() const;
  /// Completes the download whose confirmation a write hook held under `ticket`: sends the
  /// confirmation (code SdoAbort::None) or an abort with `code`. False (nothing sent) when no
  /// confirmation is held under that ticket (another, or the client gave up meanwhile).
  bool complete_download(std::uint64_t ticket, SdoAbort code, Output& out);
  /// Ends a transfer in progress by sending an abort with `code` (e.g. on an NMT reset).
  void abort(SdoAbort code, TimePoint now, Output& out);

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
    ConfirmationHeld,  // download stored: its confirmation waits for complete_download()
  };

  void handle(const sdo::Payload& d, TimePoint now, HookOutput hooks, Output& out);
  void handle_command(const sdo::ClientFrame& f, TimePoint now, HookOutput hooks, Output& out);
  void initiate_download(const sdo::InitiateDownloadRequest& f, TimePoint now, HookOutput hooks,
                         Output& out);
  void download_segment(const sdo::DownloadSegmentRequest& f, TimePoint now, HookOutput hooks,
                        Output& out);
  void start_upload(Output& out);
  void upload_segment(const sdo::UploadSegmentRequest& f, Output& out);
  void block_download_initiate(const sdo::BlockDownloadInitiateRequest& f, Output& out);
  void block_download_segment(const sdo::BlockSegment& f, Output& out);
  void block_download_end(const sdo::BlockDownloadEndRequest& f, TimePoint now, HookOutput hooks,
                          Output& out);
  void block_upload_initiate(const sdo::BlockUploadInitiateRequest& f, TimePoint now,
                             HookOutput hooks, Output& out);
  void block_upload_ack(const sdo::BlockUploadAck& f, Output& out);
  void send_upload_sub_block(Output& out);
  template <class Frame>
  void finish_download(const Frame& confirmation, TimePoint now, HookOutput hooks, Output& out);
  template <class Frame>
  void confirm_download(const WriteVerdict& verdict, const Frame& confirmation, Output& out);
  template <class Frame>
  void respond(const Frame& f, Output& out);
  void send_abort(SdoAbort code, Output& out);
  SdoAbort check_running_size(std::size_t size) const;
  void reset();

  LocalDictionary* dict_;
  SdoServerConfig config_;
  State state_ = State::Idle;
  cfg::ObjectAddress address_;  // of the transfer in progress (0000h sub 00h when none)
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
  bool stalled_ = false;            // the frame in hand moved the block transfer nowhere
  int empty_rounds_ = 0;            // download: sub-blocks in a row acknowledging no segment
  std::optional<TimePoint> timeout_at_;
  std::uint64_t held_ticket_ = 0;  // ConfirmationHeld: the write hook's ticket
  CanFrame held_confirmation_{};
};
static_assert(Engine<SdoServer>);

/// The SDO server channels of one dictionary (CiA 301 §7.5.2.33: 1200h and 1201h-127Fh), each
/// its own SdoServer (one transfer per channel, so clients on different channels never disturb
/// each other), kept in index order; a frame goes to the first channel that takes it. SlaveNode
/// serves every channel its dictionary has; NmtMaster's SDO manager the ones it opens for SRDs.
/// The dictionary must outlive it (the servers point at it).
class SdoServerChannels {
 public:
  explicit SdoServerChannels(LocalDictionary& dict) : dict_(&dict) {}

  /// Serves channel `index` (1200h-127Fh) with `config`; an open channel of that index is
  /// replaced (its transfer dropped without a frame).
  void open(std::uint16_t index, SdoServerConfig config);
  /// Channel `index` from the dictionary (SdoServerConfig::from_dictionary) with `timeout`,
  /// unless it is open already.
  void open_from_dictionary(std::uint16_t index, Duration timeout);
  void close(std::uint16_t index);
  /// Every open channel again from the dictionary, with `timeout`. `restart_all` false: only a
  /// channel whose COB-IDs or timeout changed restarts (its transfer is dropped).
  void reconfigure(Duration timeout, bool restart_all);
  bool is_open(std::uint16_t index) const { return find(index) != nullptr; }
  /// The open channels, in index order.
  std::vector<std::uint16_t> indices() const;
  /// nullptr when `index` is not open. Valid until the next open().
  const SdoServer* find(std::uint16_t index) const;

  /// The channel that took `frame` (nullopt: none). `hooks`: the output of the owner's call,
  /// for the dictionary's hooks (SdoServer::on_frame). `before`, when given, runs with each
  /// channel's index before that channel sees the frame (a hook may need to know the channel).
  std::optional<std::uint16_t> on_frame(const CanFrame& frame, TimePoint now,
                                        SdoServer::Output& out, HookOutput hooks,
                                        const std::function<void(std::uint16_t)>& before = {});
  void on_timer(TimePoint now, SdoServer::Output& out);
  std::optional<TimePoint> next_deadline() const;
  /// SdoServer::complete_download on the channel that holds `ticket`; false when none does.
  bool complete_download(std::uint64_t ticket, SdoAbort code, SdoServer::Output& out);

 private:
  struct Channel {
    std::uint16_t index;
    SdoServer server;
  };
  LocalDictionary* dict_;
  std::vector<Channel> channels_;
};

}  // namespace nmt
