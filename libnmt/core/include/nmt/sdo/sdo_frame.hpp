// The SDO frame codec: the 8 data bytes of every SDO frame of CiA 301 §7.2.4.3 as typed values,
// parsed and encoded in one place for the server and the client. No state, no I/O.
//
// Byte 0 of a frame holds the command specifier in bits 7..5 (ccs from the client, scs from the
// server) and per-command flags below it; the multiplexer (index little-endian, sub-index) is in
// bytes 1..3 of initiate frames, and data, sizes or the abort code in bytes 4..7. Frames with a
// DLC below 8 are read as if padded with zeros (sdo_payload); DLC 0 and RTR frames are no SDO
// frames. Inside a block transfer's sub-block the receiver reads every frame as a segment (byte
// 0 = c | seqno), except 80h, an abort: parse_sub_block_frame.
//
// Round trip: for every payload p that parses to x, parse(encode(x)) == x. Parsing drops bits
// CiA 301 leaves unused (they encode as 0), so encode(parse(p)) may differ from p there.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <variant>

#include "cfg/cob_id.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"

namespace nmt {

/// CRC-16 of SDO block transfer (CiA 301 block protocols: polynomial x^16 + x^12 + x^5 + 1, initial
/// value 0, no reflection, i.e. CRC-16/XMODEM). Pass the previous result as `crc` to continue.
std::uint16_t sdo_block_crc(std::span<const std::uint8_t> data, std::uint16_t crc = 0);

namespace sdo {

/// The 8 data bytes of an SDO frame.
using Payload = std::array<std::uint8_t, 8>;

/// CiA 301 §7.3.5, pre-defined connection set: the default SDO channel of node n uses the
/// CAN identifiers 600h + n (client to server) and 580h + n (server to client).
inline constexpr std::uint32_t kDefaultRequestId = 0x600;
inline constexpr std::uint32_t kDefaultResponseId = 0x580;

/// The COB-IDs of node n's default SDO channel: the one place of 600h + n / 580h + n.
struct DefaultCobIds {
  cfg::CobId request;   ///< client to server, 600h + n
  cfg::CobId response;  ///< server to client, 580h + n
};
constexpr DefaultCobIds default_cob_ids(cfg::NodeId node_id) {
  return {cfg::CobId::standard(kDefaultRequestId + node_id.value()),
          cfg::CobId::standard(kDefaultResponseId + node_id.value())};
}

/// Data bytes in one segment (segmented and block transfer).
inline constexpr std::size_t kSegmentBytes = 7;
/// Block size limits of the block protocols: 1..127 segments per sub-block.
inline constexpr std::uint8_t kMaxBlockSize = 127;
/// Our choice (CiA 301 sets no limit): the receiver of a block transfer aborts with 0504 0003
/// after this many sub-blocks in a row acknowledged no segment. A lost first segment costs one
/// such round; two ends that disagree on the state (after a lost abort, each reads the other's
/// acknowledgement A2h as a last segment out of order) would otherwise answer each other at full
/// bus load until a timeout.
inline constexpr int kMaxEmptyBlockRounds = 4;

/// The payload of an SDO frame: its data padded with zeros to 8 bytes; nullopt for RTR, error
/// and DLC 0 frames.
inline std::optional<Payload> sdo_payload(const CanFrame& frame) {
  if (frame.rtr || frame.error || frame.dlc == 0) return std::nullopt;
  Payload d;
  std::copy_n(frame.data.begin(), d.size(), d.begin());
  for (std::size_t i = frame.dlc; i < d.size(); ++i) d[i] = 0;  // DLC < 8: zero padding
  return d;
}
/// True when `cob_id` is usable (bit 31 clear, well formed) and `frame` has its identifier and
/// frame format (bit 29: 29-bit), through the one conversion of cfg/cob_id.hpp.
inline bool on_channel(const CanFrame& frame, cfg::CobId cob_id) {
  const auto id = cfg::usable_can_id(cob_id);
  return id && frame.id == id->id && frame.extended == id->extended;
}
/// An 8-byte frame with `cob_id`'s identifier and frame format.
inline CanFrame make_frame(cfg::CobId cob_id, const Payload& payload) {
  const auto id = cob_id.can_id();
  return CanFrame::make(id.id, payload, id.extended);
}

/// A block size from a frame or a setting: CiA 301 allows 1..127 segments per sub-block.
constexpr bool valid_block_size(std::uint8_t n) {
  return n >= 1 && n <= kMaxBlockSize;
}
constexpr std::uint8_t clamp_block_size(std::uint8_t n) {
  return n < 1 ? 1 : n > kMaxBlockSize ? kMaxBlockSize : n;
}
/// n of the end block frame: bytes of the last 7-byte segment of a `size`-byte value that carry
/// no data (an empty value is sent as one empty segment: 7).
constexpr std::uint8_t last_segment_empty_bytes(std::size_t size) {
  return static_cast<std::uint8_t>(kSegmentBytes -
                                   (size == 0 ? 0 : (size - 1) % kSegmentBytes + 1));
}

// --- frame layouts shared by two commands (the Tag only makes them distinct types) ----------

/// Initiate download request (ccs 1) and initiate upload response (scs 2).
template <class Tag>
struct InitiateTransfer {
  cfg::ObjectAddress address;
  bool expedited = false;  ///< e: the data is in this frame
  /// s: expedited: bytes of data, 1..4; segmented: bytes of the whole value. nullopt: not
  /// indicated (an expedited frame then carries 4 bytes of which the object takes its size).
  std::optional<std::uint32_t> size;
  std::array<std::uint8_t, 4> data{};  ///< expedited: bytes 4..7; segmented: zero
  bool operator==(const InitiateTransfer&) const = default;
};

/// Initiate download response (scs 3) and initiate upload request (ccs 2): the multiplexer.
template <class Tag>
struct Multiplexed {
  cfg::ObjectAddress address;
  bool operator==(const Multiplexed&) const = default;
};

/// Download segment request (ccs 0) and upload segment response (scs 0).
template <class Tag>
struct Segment {
  bool toggle = false;                             ///< t: 0 in the first segment, then alternating
  bool last = false;                               ///< c: no more segments follow
  std::uint8_t size = kSegmentBytes;               ///< bytes of data, 0..7 (7 - n)
  std::array<std::uint8_t, kSegmentBytes> data{};  ///< bytes 1..7 (beyond `size`: padding)
  bool operator==(const Segment&) const = default;
};

/// Download segment response (scs 1) and upload segment request (ccs 3).
template <class Tag>
struct SegmentToggle {
  bool toggle = false;
  bool operator==(const SegmentToggle&) const = default;
};

/// Block download acknowledgement (scs 5, ss 2) and block upload acknowledgement (ccs 5, cs 2).
template <class Tag>
struct BlockAck {
  std::uint8_t ack_seq = 0;     ///< last segment received in order (0: none)
  std::uint8_t block_size = 0;  ///< segments of the next sub-block
  bool operator==(const BlockAck&) const = default;
};

/// End block download request (ccs 6, cs 1) and end block upload request (scs 6, ss 1).
template <class Tag>
struct BlockEnd {
  std::uint8_t empty_bytes = 0;  ///< n: bytes of the last segment without data, 0..7
  std::uint16_t crc = 0;         ///< CRC of the whole value (0 when CRC is not used)
  bool operator==(const BlockEnd&) const = default;
};

/// End block download response (scs 5, ss 1) and end block upload response (ccs 5, cs 1).
template <class Tag>
struct BlockEndResponse {
  bool operator==(const BlockEndResponse&) const = default;
};

// --- the commands -------------------------------------------------------------------------

using InitiateDownloadRequest = InitiateTransfer<struct InitiateDownloadRequestTag>;
using InitiateDownloadResponse = Multiplexed<struct InitiateDownloadResponseTag>;
using DownloadSegmentRequest = Segment<struct DownloadSegmentRequestTag>;
using DownloadSegmentResponse = SegmentToggle<struct DownloadSegmentResponseTag>;
using InitiateUploadRequest = Multiplexed<struct InitiateUploadRequestTag>;
using InitiateUploadResponse = InitiateTransfer<struct InitiateUploadResponseTag>;
using UploadSegmentRequest = SegmentToggle<struct UploadSegmentRequestTag>;
using UploadSegmentResponse = Segment<struct UploadSegmentResponseTag>;
using BlockDownloadAck = BlockAck<struct BlockDownloadAckTag>;
using BlockUploadAck = BlockAck<struct BlockUploadAckTag>;
using BlockDownloadEndRequest = BlockEnd<struct BlockDownloadEndRequestTag>;
using BlockUploadEndRequest = BlockEnd<struct BlockUploadEndRequestTag>;
using BlockDownloadEndResponse = BlockEndResponse<struct BlockDownloadEndResponseTag>;
using BlockUploadEndResponse = BlockEndResponse<struct BlockUploadEndResponseTag>;

/// Abort transfer (cs 4), either direction.
struct Abort {
  cfg::ObjectAddress address;  ///< the transfer's multiplexer (0000h sub 00h when none)
  SdoAbort code = SdoAbort::General;
  bool operator==(const Abort&) const = default;
};

/// Initiate block download request (ccs 6, cs 0).
struct BlockDownloadInitiateRequest {
  cfg::ObjectAddress address;
  bool crc = false;                   ///< cc: the client can do CRC
  std::optional<std::uint32_t> size;  ///< s: bytes of the value
  bool operator==(const BlockDownloadInitiateRequest&) const = default;
};

/// Initiate block download response (scs 5, ss 0).
struct BlockDownloadInitiateResponse {
  cfg::ObjectAddress address;
  bool crc = false;             ///< sc: the server checks the CRC
  std::uint8_t block_size = 0;  ///< segments per sub-block, 1..127
  bool operator==(const BlockDownloadInitiateResponse&) const = default;
};

/// Initiate block upload request (ccs 5, cs 0).
struct BlockUploadInitiateRequest {
  cfg::ObjectAddress address;
  bool crc = false;             ///< cc: the client checks the CRC
  std::uint8_t block_size = 0;  ///< segments per sub-block, 1..127
  /// pst: values of at most this many bytes may be sent by the normal upload protocol (0: no)
  std::uint8_t protocol_switch_threshold = 0;
  bool operator==(const BlockUploadInitiateRequest&) const = default;
};

/// Initiate block upload response (scs 6, ss 0).
struct BlockUploadInitiateResponse {
  cfg::ObjectAddress address;
  bool crc = false;                   ///< sc: the server sends a CRC
  std::optional<std::uint32_t> size;  ///< s: bytes of the value
  bool operator==(const BlockUploadInitiateResponse&) const = default;
};

/// Start block upload (ccs 5, cs 3).
struct BlockUploadStart {
  bool operator==(const BlockUploadStart&) const = default;
};

/// A segment of a sub-block (either direction): byte 0 = c | seqno, then 7 data bytes.
struct BlockSegment {
  bool last = false;     ///< c: the last segment of the value
  std::uint8_t seq = 1;  ///< 1..127 (0 is invalid; parse keeps it for the receiver to refuse)
  std::array<std::uint8_t, kSegmentBytes> data{};
  bool operator==(const BlockSegment&) const = default;
};

/// Every command frame a client sends (outside sub-blocks).
using ClientFrame =
    std::variant<InitiateDownloadRequest, DownloadSegmentRequest, InitiateUploadRequest,
                 UploadSegmentRequest, Abort, BlockDownloadInitiateRequest, BlockDownloadEndRequest,
                 BlockUploadInitiateRequest, BlockUploadStart, BlockUploadAck,
                 BlockUploadEndResponse>;
/// Every command frame a server sends (outside sub-blocks).
using ServerFrame =
    std::variant<InitiateDownloadResponse, DownloadSegmentResponse, InitiateUploadResponse,
                 UploadSegmentResponse, Abort, BlockDownloadInitiateResponse, BlockDownloadAck,
                 BlockDownloadEndResponse, BlockUploadInitiateResponse, BlockUploadEndRequest>;
/// What a receiver of a sub-block reads.
using SubBlockFrame = std::variant<BlockSegment, Abort>;

/// A client's command frame; nullopt for a command specifier CiA 301 does not define (the
/// server answers those with abort 0504 0001).
std::optional<ClientFrame> parse_client_frame(const Payload& payload);
/// A server's command frame; nullopt for an undefined command specifier.
std::optional<ServerFrame> parse_server_frame(const Payload& payload);
/// A frame inside a sub-block: an abort when byte 0 is 80h, else a segment.
SubBlockFrame parse_sub_block_frame(const Payload& payload);

/// The payload of a frame. Fields out of range are clamped to what the frame can hold (e.g. an
/// expedited size to 1..4, a segment size to 0..7, n to 0..7).
Payload encode(const InitiateDownloadRequest& f);
Payload encode(const InitiateDownloadResponse& f);
Payload encode(const DownloadSegmentRequest& f);
Payload encode(const DownloadSegmentResponse& f);
Payload encode(const InitiateUploadRequest& f);
Payload encode(const InitiateUploadResponse& f);
Payload encode(const UploadSegmentRequest& f);
Payload encode(const UploadSegmentResponse& f);
Payload encode(const Abort& f);
Payload encode(const BlockDownloadInitiateRequest& f);
Payload encode(const BlockDownloadInitiateResponse& f);
Payload encode(const BlockDownloadAck& f);
Payload encode(const BlockDownloadEndRequest& f);
Payload encode(const BlockDownloadEndResponse& f);
Payload encode(const BlockUploadInitiateRequest& f);
Payload encode(const BlockUploadInitiateResponse& f);
Payload encode(const BlockUploadStart& f);
Payload encode(const BlockUploadAck& f);
Payload encode(const BlockUploadEndRequest& f);
Payload encode(const BlockUploadEndResponse& f);
Payload encode(const BlockSegment& f);
Payload encode(const ClientFrame& f);
Payload encode(const ServerFrame& f);
Payload encode(const SubBlockFrame& f);

/// The multiplexer of a client frame that carries one (initiate requests, abort).
std::optional<cfg::ObjectAddress> multiplexer(const ClientFrame& f);

}  // namespace sdo
}  // namespace nmt
