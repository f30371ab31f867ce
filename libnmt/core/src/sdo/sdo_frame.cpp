#include "nmt/sdo/sdo_frame.hpp"

#include <algorithm>

#include "cfg/bytes.hpp"

namespace nmt {

namespace {

constexpr std::array<std::uint16_t, 256> make_crc_table() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    auto crc = static_cast<std::uint16_t>(i << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = static_cast<std::uint16_t>((crc & 0x8000) ? (crc << 1) ^ 0x1021 : crc << 1);
    }
    table[i] = crc;
  }
  return table;
}
constexpr auto kCrcTable = make_crc_table();

}  // namespace

std::uint16_t sdo_block_crc(std::span<const std::uint8_t> data, std::uint16_t crc) {
  for (auto byte : data) {
    crc = static_cast<std::uint16_t>(crc << 8 ^ kCrcTable[(crc >> 8 ^ byte) & 0xFF]);
  }
  return crc;
}

namespace sdo {

namespace {

// CiA 301 §7.2.4.3: the command specifier in bits 7..5 of byte 0.
enum class Ccs : std::uint8_t {
  DownloadSegment = 0,
  InitiateDownload = 1,
  InitiateUpload = 2,
  UploadSegment = 3,
  Abort = 4,
  BlockUpload = 5,
  BlockDownload = 6,
};
enum class Scs : std::uint8_t {
  UploadSegment = 0,
  DownloadSegment = 1,
  InitiateUpload = 2,
  InitiateDownload = 3,
  Abort = 4,
  BlockDownload = 5,
  BlockUpload = 6,
};

// Byte 0 of a frame, field by field. The one place where its bits are named.
struct Byte0 {
  std::uint8_t value = 0;

  constexpr std::uint8_t command() const { return value >> 5; }
  constexpr bool bit(unsigned n) const { return (value >> n & 1) != 0; }
  constexpr unsigned field(unsigned low, unsigned width) const {
    return value >> low & ((1u << width) - 1);
  }

  static constexpr Byte0 make(Ccs c) { return {static_cast<std::uint8_t>(to_bits(c) << 5)}; }
  static constexpr Byte0 make(Scs s) { return {static_cast<std::uint8_t>(to_bits(s) << 5)}; }
  template <class E>
  static constexpr unsigned to_bits(E e) {
    return static_cast<unsigned>(e);
  }
  constexpr Byte0& set(unsigned n, bool on) {
    if (on) value = static_cast<std::uint8_t>(value | 1u << n);
    return *this;
  }
  constexpr Byte0& set_field(unsigned low, unsigned width, unsigned v) {
    value = static_cast<std::uint8_t>(value | (v & ((1u << width) - 1)) << low);
    return *this;
  }
};

// Flag positions in byte 0 (CiA 301 §7.2.4.3).
constexpr unsigned kSizeIndicated = 0;  // s: initiate download/upload
constexpr unsigned kExpedited = 1;      // e: initiate download/upload
constexpr unsigned kInitiateN = 2;      // n (2 bits): initiate, bytes without data
constexpr unsigned kLast = 0;           // c: segments
constexpr unsigned kSegmentN = 1;       // n (3 bits): segments, bytes without data
constexpr unsigned kToggle = 4;         // t: segments and their responses
constexpr unsigned kBlockCrc = 2;       // cc / sc: block initiate
constexpr unsigned kBlockSize = 1;      // s: block initiate
constexpr unsigned kBlockEndN = 2;      // n (3 bits): end block
constexpr unsigned kSeqLast = 7;        // c: sub-block segments (seqno in bits 6..0)

// Sub-commands of the block protocols: ccs 6 and scs 6 in bit 0, ccs 5 and scs 5 in bits 1..0.
constexpr unsigned kBlockInitiate = 0;
constexpr unsigned kBlockEnd = 1;
constexpr unsigned kBlockAck = 2;
constexpr unsigned kBlockStart = 3;

cfg::ObjectAddress get_address(const Payload& d) {
  return {cfg::load_le16(std::span(d).subspan(1, 2)), d[3]};
}
void put_address(Payload& d, cfg::ObjectAddress a) {
  cfg::store_le(a.index, std::span(d).subspan(1, 2), 2);
  d[3] = a.sub_index;
}
std::uint32_t get_u32(const Payload& d) {
  return cfg::load_le32(std::span(d).subspan(4, 4));
}
void put_u32(Payload& d, std::uint32_t v) {
  cfg::store_le(v, std::span(d).subspan(4, 4), 4);
}

template <class F>
F parse_initiate(const Payload& d, Byte0 b) {
  F f;
  f.address = get_address(d);
  f.expedited = b.bit(kExpedited);
  if (f.expedited) {
    // n is only meaningful with s = 1: the data is 4 - n bytes.
    if (b.bit(kSizeIndicated)) f.size = 4 - b.field(kInitiateN, 2);
    std::copy(d.begin() + 4, d.end(), f.data.begin());
  } else if (b.bit(kSizeIndicated)) {
    f.size = get_u32(d);
  }
  return f;
}
template <class F, class Cs>
Payload encode_initiate(const F& f, Cs cs) {
  Payload d{};
  auto b = Byte0::make(cs).set(kExpedited, f.expedited).set(kSizeIndicated, f.size.has_value());
  if (f.expedited) {
    if (f.size) b.set_field(kInitiateN, 2, 4 - std::clamp<std::uint32_t>(*f.size, 1, 4));
    std::copy(f.data.begin(), f.data.end(), d.begin() + 4);
  } else if (f.size) {
    put_u32(d, *f.size);
  }
  d[0] = b.value;
  put_address(d, f.address);
  return d;
}

template <class F>
F parse_segment(const Payload& d, Byte0 b) {
  F f;
  f.toggle = b.bit(kToggle);
  f.last = b.bit(kLast);
  f.size = static_cast<std::uint8_t>(kSegmentBytes - b.field(kSegmentN, 3));
  std::copy(d.begin() + 1, d.end(), f.data.begin());
  return f;
}
template <class F, class Cs>
Payload encode_segment(const F& f, Cs cs) {
  Payload d{};
  const auto size = std::min<std::size_t>(f.size, kSegmentBytes);
  d[0] = Byte0::make(cs)
             .set(kToggle, f.toggle)
             .set(kLast, f.last)
             .set_field(kSegmentN, 3, static_cast<unsigned>(kSegmentBytes - size))
             .value;
  std::copy(f.data.begin(), f.data.end(), d.begin() + 1);
  return d;
}

template <class F>
F parse_block_end(const Payload& d, Byte0 b) {
  return F{static_cast<std::uint8_t>(b.field(kBlockEndN, 3)),
           cfg::load_le16(std::span(d).subspan(1, 2))};
}
template <class F, class Cs>
Payload encode_block_end(const F& f, Cs cs, unsigned sub_command) {
  Payload d{};
  d[0] = Byte0::make(cs).set_field(0, 1, sub_command).set_field(kBlockEndN, 3, f.empty_bytes).value;
  cfg::store_le(f.crc, std::span(d).subspan(1, 2), 2);
  return d;
}

template <class F, class Cs>
Payload encode_block_ack(const F& f, Cs cs) {
  Payload d{};
  d[0] = Byte0::make(cs).set_field(0, 2, kBlockAck).value;
  d[1] = f.ack_seq;
  d[2] = f.block_size;
  return d;
}

// Block download initiate request and block upload initiate response: cc/sc, s, multiplexer,
// size (the block sub-command 0 is the zero bit 0).
template <class F>
F parse_block_initiate_with_size(const Payload& d, Byte0 b) {
  F f{get_address(d), b.bit(kBlockCrc), std::nullopt};
  if (b.bit(kBlockSize)) f.size = get_u32(d);
  return f;
}
template <class F, class Cs>
Payload encode_block_initiate_with_size(const F& f, Cs cs) {
  Payload d{};
  d[0] = Byte0::make(cs).set(kBlockCrc, f.crc).set(kBlockSize, f.size.has_value()).value;
  put_address(d, f.address);
  if (f.size) put_u32(d, *f.size);
  return d;
}

Abort parse_abort(const Payload& d) {
  return {get_address(d), static_cast<SdoAbort>(get_u32(d))};
}

}  // namespace

std::optional<ClientFrame> parse_client_frame(const Payload& d) {
  const Byte0 b{d[0]};
  switch (static_cast<Ccs>(b.command())) {
    case Ccs::DownloadSegment:
      return parse_segment<DownloadSegmentRequest>(d, b);
    case Ccs::InitiateDownload:
      return parse_initiate<InitiateDownloadRequest>(d, b);
    case Ccs::InitiateUpload:
      return InitiateUploadRequest{get_address(d)};
    case Ccs::UploadSegment:
      return UploadSegmentRequest{b.bit(kToggle)};
    case Ccs::Abort:
      return parse_abort(d);
    case Ccs::BlockUpload:
      switch (b.field(0, 2)) {
        case kBlockInitiate:
          return BlockUploadInitiateRequest{get_address(d), b.bit(kBlockCrc), d[4], d[5]};
        case kBlockEnd:
          return BlockUploadEndResponse{};
        case kBlockAck:
          return BlockUploadAck{d[1], d[2]};
        default:
          return BlockUploadStart{};
      }
    case Ccs::BlockDownload: {
      if (b.field(0, 1) == kBlockEnd) return parse_block_end<BlockDownloadEndRequest>(d, b);
      return parse_block_initiate_with_size<BlockDownloadInitiateRequest>(d, b);
    }
  }
  return std::nullopt;  // ccs 7
}

std::optional<ServerFrame> parse_server_frame(const Payload& d) {
  const Byte0 b{d[0]};
  switch (static_cast<Scs>(b.command())) {
    case Scs::UploadSegment:
      return parse_segment<UploadSegmentResponse>(d, b);
    case Scs::DownloadSegment:
      return DownloadSegmentResponse{b.bit(kToggle)};
    case Scs::InitiateUpload:
      return parse_initiate<InitiateUploadResponse>(d, b);
    case Scs::InitiateDownload:
      return InitiateDownloadResponse{get_address(d)};
    case Scs::Abort:
      return parse_abort(d);
    case Scs::BlockDownload:
      switch (b.field(0, 2)) {
        case kBlockInitiate:
          return BlockDownloadInitiateResponse{get_address(d), b.bit(kBlockCrc), d[4]};
        case kBlockEnd:
          return BlockDownloadEndResponse{};
        case kBlockAck:
          return BlockDownloadAck{d[1], d[2]};
        default:
          return std::nullopt;  // ss 3 is not defined
      }
    case Scs::BlockUpload: {
      if (b.field(0, 1) == kBlockEnd) {
        // Bit 1 of the end request is not used; a frame with it set is not one (as the
        // client has always read it).
        if (b.bit(1)) return std::nullopt;
        return parse_block_end<BlockUploadEndRequest>(d, b);
      }
      return parse_block_initiate_with_size<BlockUploadInitiateResponse>(d, b);
    }
  }
  return std::nullopt;  // scs 7
}

SubBlockFrame parse_sub_block_frame(const Payload& d) {
  // 80h would be segment 0 with c = 1, an invalid sequence number: it is an abort (ccs 4).
  if (d[0] == 0x80) return parse_abort(d);
  const Byte0 b{d[0]};
  BlockSegment f;
  f.last = b.bit(kSeqLast);
  f.seq = static_cast<std::uint8_t>(b.field(0, 7));
  std::copy(d.begin() + 1, d.end(), f.data.begin());
  return f;
}

Payload encode(const InitiateDownloadRequest& f) {
  return encode_initiate(f, Ccs::InitiateDownload);
}
Payload encode(const InitiateUploadResponse& f) {
  return encode_initiate(f, Scs::InitiateUpload);
}
Payload encode(const InitiateDownloadResponse& f) {
  Payload d{};
  d[0] = Byte0::make(Scs::InitiateDownload).value;
  put_address(d, f.address);
  return d;
}
Payload encode(const InitiateUploadRequest& f) {
  Payload d{};
  d[0] = Byte0::make(Ccs::InitiateUpload).value;
  put_address(d, f.address);
  return d;
}
Payload encode(const DownloadSegmentRequest& f) {
  return encode_segment(f, Ccs::DownloadSegment);
}
Payload encode(const UploadSegmentResponse& f) {
  return encode_segment(f, Scs::UploadSegment);
}
Payload encode(const DownloadSegmentResponse& f) {
  return {Byte0::make(Scs::DownloadSegment).set(kToggle, f.toggle).value};
}
Payload encode(const UploadSegmentRequest& f) {
  return {Byte0::make(Ccs::UploadSegment).set(kToggle, f.toggle).value};
}
Payload encode(const Abort& f) {
  Payload d{};
  d[0] = Byte0::make(Ccs::Abort).value;
  put_address(d, f.address);
  put_u32(d, to_u32(f.code));
  return d;
}
Payload encode(const BlockDownloadInitiateRequest& f) {
  return encode_block_initiate_with_size(f, Ccs::BlockDownload);
}
Payload encode(const BlockDownloadInitiateResponse& f) {
  Payload d{};
  d[0] =
      Byte0::make(Scs::BlockDownload).set(kBlockCrc, f.crc).set_field(0, 2, kBlockInitiate).value;
  put_address(d, f.address);
  d[4] = f.block_size;
  return d;
}
Payload encode(const BlockDownloadAck& f) {
  return encode_block_ack(f, Scs::BlockDownload);
}
Payload encode(const BlockUploadAck& f) {
  return encode_block_ack(f, Ccs::BlockUpload);
}
Payload encode(const BlockDownloadEndRequest& f) {
  return encode_block_end(f, Ccs::BlockDownload, kBlockEnd);
}
Payload encode(const BlockUploadEndRequest& f) {
  return encode_block_end(f, Scs::BlockUpload, kBlockEnd);
}
Payload encode(const BlockDownloadEndResponse&) {
  return {Byte0::make(Scs::BlockDownload).set_field(0, 2, kBlockEnd).value};
}
Payload encode(const BlockUploadEndResponse&) {
  return {Byte0::make(Ccs::BlockUpload).set_field(0, 2, kBlockEnd).value};
}
Payload encode(const BlockUploadInitiateRequest& f) {
  Payload d{};
  d[0] = Byte0::make(Ccs::BlockUpload).set(kBlockCrc, f.crc).set_field(0, 2, kBlockInitiate).value;
  put_address(d, f.address);
  d[4] = f.block_size;
  d[5] = f.protocol_switch_threshold;
  return d;
}
Payload encode(const BlockUploadInitiateResponse& f) {
  return encode_block_initiate_with_size(f, Scs::BlockUpload);
}
Payload encode(const BlockUploadStart&) {
  return {Byte0::make(Ccs::BlockUpload).set_field(0, 2, kBlockStart).value};
}
Payload encode(const BlockSegment& f) {
  Payload d{};
  d[0] = Byte0{}.set(kSeqLast, f.last).set_field(0, 7, f.seq).value;
  std::copy(f.data.begin(), f.data.end(), d.begin() + 1);
  return d;
}
Payload encode(const ClientFrame& f) {
  return std::visit([](const auto& x) { return encode(x); }, f);
}
Payload encode(const ServerFrame& f) {
  return std::visit([](const auto& x) { return encode(x); }, f);
}
Payload encode(const SubBlockFrame& f) {
  return std::visit([](const auto& x) { return encode(x); }, f);
}

std::optional<cfg::ObjectAddress> multiplexer(const ClientFrame& f) {
  return std::visit(
      [](const auto& x) -> std::optional<cfg::ObjectAddress> {
        if constexpr (requires { x.address; }) {
          return x.address;
        } else {
          return std::nullopt;
        }
      },
      f);
}

}  // namespace sdo
}  // namespace nmt
