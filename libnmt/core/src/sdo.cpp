#include "nmt/sdo.hpp"

#include "cfg/object_index.hpp"

#include <algorithm>
#include <limits>

namespace nmt {

namespace {

using Bytes = std::array<std::uint8_t, 8>;

// CiA 301 §7.2.4.3 (SDO protocols): command specifiers in bits 7..5 of byte 0.
constexpr std::uint8_t kCcsDownloadSegment = 0;
constexpr std::uint8_t kCcsInitiateDownload = 1;
constexpr std::uint8_t kCcsInitiateUpload = 2;
constexpr std::uint8_t kCcsUploadSegment = 3;
constexpr std::uint8_t kCsAbort = 4;
constexpr std::uint8_t kCcsBlockUpload = 5;
constexpr std::uint8_t kCcsBlockDownload = 6;
constexpr std::uint8_t kScsUploadSegment = 0;
constexpr std::uint8_t kScsDownloadSegment = 1;
constexpr std::uint8_t kScsInitiateUpload = 2;
constexpr std::uint8_t kScsInitiateDownload = 3;
constexpr std::uint8_t kScsBlockDownload = 5;
constexpr std::uint8_t kScsBlockUpload = 6;

constexpr std::uint8_t kMaxBlockSize = 127;  // CiA 301 block protocols: blksize 1..127
constexpr std::size_t kSegmentBytes = 7;

std::uint8_t command(const Bytes& d) {
  return static_cast<std::uint8_t>(d[0] >> 5);
}
std::uint16_t get_index(const Bytes& d) {
  return static_cast<std::uint16_t>(d[1] | d[2] << 8);
}
std::uint32_t get_u32(const Bytes& d, std::size_t at) {
  return static_cast<std::uint32_t>(d[at] | d[at + 1] << 8 | d[at + 2] << 16) |
         static_cast<std::uint32_t>(d[at + 3]) << 24;
}
void put_u32(Bytes& d, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) d[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_mux(Bytes& d, std::uint16_t index, std::uint8_t sub) {
  d[1] = static_cast<std::uint8_t>(index);
  d[2] = static_cast<std::uint8_t>(index >> 8);
  d[3] = sub;
}
bool same_mux(const Bytes& d, std::uint16_t index, std::uint8_t sub) {
  return get_index(d) == index && d[3] == sub;
}

// An unusable COB-ID (bit 31 set, ill-formed) matches no frame.
bool matches(const CanFrame& f, cfg::CobId cob_id) {
  const auto id = cfg::usable_can_id(cob_id);
  return id && f.id == id->id && f.extended == id->extended;
}
CanFrame make_frame(cfg::CobId cob_id, const Bytes& d) {
  const auto id = cob_id.can_id();
  return CanFrame::make(id.id, d, id.extended);
}
// Frames shorter than 8 bytes are read as if padded with zeros (see sdo.hpp).
std::optional<Bytes> sdo_payload(const CanFrame& f) {
  if (f.rtr || f.error || f.dlc == 0) return std::nullopt;
  Bytes d{};
  std::copy_n(f.data.begin(), std::min<std::size_t>(f.dlc, 8), d.begin());
  return d;
}
Bytes abort_bytes(std::uint16_t index, std::uint8_t sub, SdoAbort code) {
  Bytes d{};
  d[0] = kCsAbort << 5;
  put_mux(d, index, sub);
  put_u32(d, 4, to_u32(code));
  return d;
}
bool valid_block_size(std::uint8_t n) {
  return n >= 1 && n <= kMaxBlockSize;
}
std::uint8_t clamp_block_size(std::uint8_t n) {
  return std::clamp<std::uint8_t>(n, 1, kMaxBlockSize);
}
// Bytes in the last segment of `size` bytes sent in 7-byte segments (an empty value is sent as
// one empty segment).
std::size_t last_segment_bytes(std::size_t size) {
  return size == 0 ? 0 : (size - 1) % kSegmentBytes + 1;
}
// Time arithmetic that saturates instead of overflowing on absurd durations.
TimePoint later(TimePoint now, Duration d) {
  if (d.count() > 0 && now.count() > std::numeric_limits<std::int64_t>::max() - d.count()) {
    return TimePoint::max();
  }
  return now + d;
}

constexpr std::array<std::uint16_t, 256> make_crc_table() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    std::uint16_t crc = static_cast<std::uint16_t>(i << 8);
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

// ================================================================================== server ==

SdoServerConfig SdoServerConfig::for_node(std::uint8_t node_id) {
  SdoServerConfig c;
  c.request_cob_id = cfg::CobId::standard(0x600u + node_id);
  c.response_cob_id = cfg::CobId::standard(0x580u + node_id);
  return c;
}

SdoServerConfig SdoServerConfig::from_dictionary(const LocalDictionary& dict) {
  auto c = for_node(dict.node_id());
  // CiA 301 object 1200h sub 1/2: the COB-IDs of the default SDO server channel.
  auto cob = [&](std::uint8_t sub) -> std::optional<cfg::CobId> {
    const auto word = dict.get_unsigned(cfg::object::kSdoServerFirst, sub);
    if (!word || *word > 0xFFFFFFFFu) return std::nullopt;
    const auto id = cfg::CobId::from_word(static_cast<std::uint32_t>(*word));
    return cfg::usable_can_id(id) ? std::optional(id) : std::nullopt;
  };
  auto rx = cob(1);
  auto tx = cob(2);
  if (rx && tx) {
    c.request_cob_id = *rx;
    c.response_cob_id = *tx;
  }
  return c;
}

SdoServer::SdoServer(LocalDictionary& dict, SdoServerConfig config)
    : dict_(&dict), config_(config) {
  config_.block_size = clamp_block_size(config_.block_size);
}

void SdoServer::set_config(SdoServerConfig config) {
  config_ = config;
  config_.block_size = clamp_block_size(config_.block_size);
  reset();
}

bool SdoServer::busy() const {
  return state_ != State::Idle;
}

void SdoServer::reset() {
  state_ = State::Idle;
  buffer_.clear();
  buffer_.shrink_to_fit();
  size_.reset();
  offset_ = 0;
  toggle_ = false;
  crc_ = false;
  ack_seq_ = 0;
  sent_in_block_ = 0;
  last_received_ = false;
  block_has_last_ = false;
  timeout_at_.reset();
}

std::optional<TimePoint> SdoServer::next_deadline() const {
  return timeout_at_;
}

bool SdoServer::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  // A channel without a usable response COB-ID cannot answer: it serves nothing.
  if (!matches(frame, config_.request_cob_id) || !cfg::usable_can_id(config_.response_cob_id)) {
    return false;
  }
  auto d = sdo_payload(frame);
  if (!d) return false;
  handle(*d, now, out);
  timeout_at_ = state_ == State::Idle ? std::nullopt : std::optional(later(now, config_.timeout));
  return true;
}

void SdoServer::on_timer(TimePoint now, Output& out) {
  if (timeout_at_ && now >= *timeout_at_) send_abort(SdoAbort::Timeout, out);
}

void SdoServer::abort(SdoAbort code, TimePoint /*now*/, Output& out) {
  if (state_ == State::Idle) return;
  send_abort(code, out);
}

void SdoServer::respond(const Bytes& d, Output& out) {
  out.send(make_frame(config_.response_cob_id, d));
}

void SdoServer::send_abort(SdoAbort code, Output& out) {
  respond(abort_bytes(index_, sub_, code), out);
  reset();
}

void SdoServer::handle(const Bytes& d, TimePoint now, Output& out) {
  // In a block download every frame is a segment (byte 0: c | seqno); only 0x80 (c=1 with the
  // invalid sequence number 0) is an abort there. Elsewhere the command specifier 4 is.
  const bool is_abort = state_ == State::BlockDownload ? d[0] == 0x80 : command(d) == kCsAbort;
  if (is_abort) {
    reset();  // CiA 301 SDO abort transfer protocol: not confirmed
    return;
  }
  switch (state_) {
    case State::Idle:
      // Only initiate requests carry a multiplexer; other aborts name 0000h/00h.
      index_ = 0;
      sub_ = 0;
      if (command(d) == kCcsInitiateDownload || command(d) == kCcsInitiateUpload ||
          command(d) == kCcsBlockDownload || command(d) == kCcsBlockUpload) {
        index_ = get_index(d);
        sub_ = d[3];
      }
      switch (command(d)) {
        case kCcsInitiateDownload:
          return initiate_download(d, now, out);
        case kCcsInitiateUpload:
          if (auto code = dict_->read(index_, sub_, buffer_, now); code != SdoAbort::None) {
            return send_abort(code, out);
          }
          return start_upload(out);
        case kCcsBlockDownload:
          return block_download(d, now, out);
        case kCcsBlockUpload:
          return block_upload(d, now, out);
        default:
          return send_abort(SdoAbort::InvalidCommandSpecifier, out);
      }
    case State::DownloadSegment:
      return download_segment(d, now, out);
    case State::UploadSegment:
      return upload_segment(d, out);
    case State::BlockDownload:
      return block_download_segment(d, out);
    case State::BlockDownloadEnd:
    case State::BlockUploadStart:
    case State::BlockUpload:
    case State::BlockUploadEnd:
      if (command(d) == kCcsBlockDownload && state_ == State::BlockDownloadEnd) {
        return block_download(d, now, out);
      }
      if (command(d) == kCcsBlockUpload && state_ != State::BlockDownloadEnd) {
        return block_upload(d, now, out);
      }
      return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  }
}

// CiA 301 §7.2.4.3, SDO download initiate protocol: expedited or segmented.
void SdoServer::initiate_download(const Bytes& d, TimePoint now, Output& out) {
  const bool expedited = (d[0] & 0x02) != 0;
  const bool size_indicated = (d[0] & 0x01) != 0;
  if (expedited) {
    std::size_t size = 4;
    if (size_indicated) {
      size = 4 - (d[0] >> 2 & 0x3);
    } else if (const auto* e = dict_->entry(index_, sub_);
               e && e->fixed_size() && *e->fixed_size() <= 4) {
      size = *e->fixed_size();  // size not indicated: the object's own size
    }
    const auto code = dict_->write(index_, sub_, std::span(d).subspan(4, size), now);
    if (code != SdoAbort::None) return send_abort(code, out);
    Bytes r{};
    r[0] = kScsInitiateDownload << 5;
    put_mux(r, index_, sub_);
    respond(r, out);
    return;
  }
  if (size_indicated) size_ = get_u32(d, 4);
  if (auto code = dict_->check_write(index_, sub_, size_); code != SdoAbort::None) {
    return send_abort(code, out);
  }
  if (size_ && *size_ > config_.max_download_size) return send_abort(SdoAbort::OutOfMemory, out);
  buffer_.clear();
  buffer_.reserve(std::min<std::size_t>(size_.value_or(0), 1 << 16));
  toggle_ = false;
  state_ = State::DownloadSegment;
  Bytes r{};
  r[0] = kScsInitiateDownload << 5;
  put_mux(r, index_, sub_);
  respond(r, out);
}

// CiA 301 §7.2.4.3, SDO download segment protocol: the toggle bit starts at 0 and alternates.
void SdoServer::download_segment(const Bytes& d, TimePoint now, Output& out) {
  if (command(d) != kCcsDownloadSegment) {
    return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  }
  const bool toggle = (d[0] & 0x10) != 0;
  if (toggle != toggle_) return send_abort(SdoAbort::ToggleBitNotAlternated, out);
  const std::size_t len = kSegmentBytes - (d[0] >> 1 & 0x7);
  const bool last = (d[0] & 0x01) != 0;
  if (size_ && buffer_.size() + len > *size_) return send_abort(SdoAbort::LengthMismatch, out);
  if (buffer_.size() + len > config_.max_download_size) {
    return send_abort(SdoAbort::OutOfMemory, out);
  }
  buffer_.insert(buffer_.end(), d.begin() + 1, d.begin() + 1 + static_cast<std::ptrdiff_t>(len));
  Bytes r{};
  r[0] = static_cast<std::uint8_t>(kScsDownloadSegment << 5 | (toggle ? 0x10 : 0));
  if (last) {
    // The response to the last segment confirms the write, so it is sent only after it.
    return finish_download(r[0], now, out);
  }
  toggle_ = !toggle_;
  respond(r, out);
}

void SdoServer::finish_download(std::uint8_t response, TimePoint now, Output& out) {
  if (size_ && buffer_.size() != *size_) return send_abort(SdoAbort::LengthMismatch, out);
  const auto code = dict_->write(index_, sub_, buffer_, now);
  if (code != SdoAbort::None) return send_abort(code, out);
  Bytes r{};
  r[0] = response;
  respond(r, out);
  reset();
}

// CiA 301 §7.2.4.3, SDO upload initiate protocol: the response for the value in buffer_; values
// of 1..4 bytes go expedited.
void SdoServer::start_upload(Output& out) {
  Bytes r{};
  put_mux(r, index_, sub_);
  if (!buffer_.empty() && buffer_.size() <= 4) {
    r[0] = static_cast<std::uint8_t>(kScsInitiateUpload << 5 | (4 - buffer_.size()) << 2 | 0x3);
    std::copy(buffer_.begin(), buffer_.end(), r.begin() + 4);
    respond(r, out);
    reset();
    return;
  }
  if (buffer_.size() > std::numeric_limits<std::uint32_t>::max()) {
    return send_abort(SdoAbort::OutOfMemory, out);
  }
  r[0] = kScsInitiateUpload << 5 | 0x1;  // segmented, size indicated
  put_u32(r, 4, static_cast<std::uint32_t>(buffer_.size()));
  offset_ = 0;
  toggle_ = false;
  state_ = State::UploadSegment;
  respond(r, out);
}

void SdoServer::upload_segment(const Bytes& d, Output& out) {
  if (command(d) != kCcsUploadSegment) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  const bool toggle = (d[0] & 0x10) != 0;
  if (toggle != toggle_) return send_abort(SdoAbort::ToggleBitNotAlternated, out);
  const std::size_t len = std::min(kSegmentBytes, buffer_.size() - offset_);
  const bool last = offset_ + len == buffer_.size();
  Bytes r{};
  r[0] = static_cast<std::uint8_t>(kScsUploadSegment << 5 | (toggle ? 0x10 : 0) |
                                   (kSegmentBytes - len) << 1 | (last ? 1 : 0));
  std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(offset_), len, r.begin() + 1);
  respond(r, out);
  offset_ += len;
  toggle_ = !toggle_;
  if (last) reset();
}

// CiA 301 §7.2.4.3, SDO block download protocol: initiate and end requests.
void SdoServer::block_download(const Bytes& d, TimePoint now, Output& out) {
  if (!config_.block_transfer) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  const bool end = (d[0] & 0x01) != 0;
  if (state_ == State::Idle) {
    if (end) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
    crc_ = (d[0] & 0x04) != 0;
    if ((d[0] & 0x02) != 0) size_ = get_u32(d, 4);
    if (auto code = dict_->check_write(index_, sub_, size_); code != SdoAbort::None) {
      return send_abort(code, out);
    }
    if (size_ && *size_ > config_.max_download_size) {
      return send_abort(SdoAbort::OutOfMemory, out);
    }
    buffer_.clear();
    buffer_.reserve(std::min<std::size_t>(size_.value_or(0), 1 << 20));
    block_size_ = config_.block_size;
    ack_seq_ = 0;
    last_received_ = false;
    state_ = State::BlockDownload;
    Bytes r{};
    r[0] = kScsBlockDownload << 5 | 0x04;  // sc: the server checks the CRC
    put_mux(r, index_, sub_);
    r[4] = block_size_;
    respond(r, out);
    return;
  }
  // State::BlockDownloadEnd: the end request carries n (bytes of the last segment without data)
  // and the CRC of the whole value.
  if (!end) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  const std::size_t n = d[0] >> 2 & 0x7;
  if (n > buffer_.size()) return send_abort(SdoAbort::LengthMismatch, out);
  buffer_.resize(buffer_.size() - n);
  if (crc_) {
    const auto crc = static_cast<std::uint16_t>(d[1] | d[2] << 8);
    if (sdo_block_crc(buffer_) != crc) return send_abort(SdoAbort::CrcError, out);
  }
  finish_download(kScsBlockDownload << 5 | 0x01, now, out);
}

void SdoServer::block_download_segment(const Bytes& d, Output& out) {
  const std::uint8_t seq = d[0] & 0x7F;
  const bool last = (d[0] & 0x80) != 0;
  if (seq == 0 || seq > block_size_) return send_abort(SdoAbort::InvalidSequenceNumber, out);
  // Segments after a lost one are ignored; the acknowledgement names the last one received in
  // order and the client resends from there (CiA 301 block download sub-block).
  if (seq == ack_seq_ + 1 && !last_received_) {
    // Segments carry 7 bytes each, the last one padded: never more than the size needs.
    const std::size_t limit = size_ ? *size_ : config_.max_download_size;
    const std::size_t segments =
        std::max<std::size_t>(1, (limit + kSegmentBytes - 1) / kSegmentBytes);
    if (buffer_.size() + kSegmentBytes > segments * kSegmentBytes) {
      return send_abort(size_ ? SdoAbort::LengthMismatch : SdoAbort::OutOfMemory, out);
    }
    buffer_.insert(buffer_.end(), d.begin() + 1, d.end());
    ack_seq_ = seq;
    last_received_ = last;
  }
  if (last || seq == block_size_) {
    Bytes r{};
    r[0] = kScsBlockDownload << 5 | 0x02;
    r[1] = ack_seq_;
    r[2] = block_size_;
    respond(r, out);
    ack_seq_ = 0;
    if (last_received_) state_ = State::BlockDownloadEnd;
  }
}

// CiA 301 §7.2.4.3, SDO block upload protocol.
void SdoServer::block_upload(const Bytes& d, TimePoint now, Output& out) {
  if (!config_.block_transfer) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  const std::uint8_t sub_command = d[0] & 0x03;
  switch (state_) {
    case State::Idle: {
      if (sub_command != 0) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
      const std::uint8_t block_size = d[4];
      const std::uint8_t pst = d[5];
      if (!valid_block_size(block_size)) return send_abort(SdoAbort::InvalidBlockSize, out);
      if (auto code = dict_->read(index_, sub_, buffer_, now); code != SdoAbort::None) {
        return send_abort(code, out);
      }
      // Protocol switch threshold: small values may go by the normal upload protocol.
      if (pst != 0 && buffer_.size() <= pst) return start_upload(out);
      if (buffer_.size() > std::numeric_limits<std::uint32_t>::max()) {
        return send_abort(SdoAbort::OutOfMemory, out);
      }
      crc_ = (d[0] & 0x04) != 0;
      block_size_ = block_size;
      offset_ = 0;
      state_ = State::BlockUploadStart;
      Bytes r{};
      r[0] = kScsBlockUpload << 5 | 0x04 | 0x02;  // sc, size indicated
      put_mux(r, index_, sub_);
      put_u32(r, 4, static_cast<std::uint32_t>(buffer_.size()));
      respond(r, out);
      return;
    }
    case State::BlockUploadStart:
      if (sub_command != 3) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
      state_ = State::BlockUpload;
      return send_upload_sub_block(out);
    case State::BlockUpload: {
      if (sub_command != 2) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
      const std::uint8_t ack_seq = d[1];
      const std::uint8_t block_size = d[2];
      if (ack_seq > sent_in_block_) return send_abort(SdoAbort::InvalidSequenceNumber, out);
      if (!valid_block_size(block_size)) return send_abort(SdoAbort::InvalidBlockSize, out);
      const bool all_acknowledged = ack_seq == sent_in_block_;
      offset_ = std::min(buffer_.size(), offset_ + ack_seq * kSegmentBytes);
      block_size_ = block_size;
      if (all_acknowledged && block_has_last_) {
        Bytes r{};
        const auto n = kSegmentBytes - last_segment_bytes(buffer_.size());
        r[0] = static_cast<std::uint8_t>(kScsBlockUpload << 5 | n << 2 | 0x01);
        if (crc_) {
          const auto crc = sdo_block_crc(buffer_);
          r[1] = static_cast<std::uint8_t>(crc);
          r[2] = static_cast<std::uint8_t>(crc >> 8);
        }
        state_ = State::BlockUploadEnd;
        respond(r, out);
        return;
      }
      return send_upload_sub_block(out);
    }
    case State::BlockUploadEnd:
      if (sub_command != 1) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
      reset();  // the client confirmed the end: done
      return;
    default:
      return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  }
}

void SdoServer::send_upload_sub_block(Output& out) {
  std::size_t pos = offset_;
  sent_in_block_ = 0;
  block_has_last_ = false;
  for (std::uint8_t seq = 1; seq <= block_size_; ++seq) {
    const std::size_t len = std::min(kSegmentBytes, buffer_.size() - pos);
    const bool last = pos + len == buffer_.size();
    Bytes r{};
    r[0] = static_cast<std::uint8_t>((last ? 0x80 : 0) | seq);
    std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(pos), len, r.begin() + 1);
    respond(r, out);
    pos += len;
    sent_in_block_ = seq;
    if (last) {
      block_has_last_ = true;
      break;
    }
  }
}

// ================================================================================== client ==

SdoClientConfig SdoClientConfig::for_node(std::uint8_t node_id) {
  SdoClientConfig c;
  c.request_cob_id = cfg::CobId::standard(0x600u + node_id);
  c.response_cob_id = cfg::CobId::standard(0x580u + node_id);
  c.node_id = node_id;
  return c;
}

SdoClient::SdoClient(SdoClientConfig config) : config_(config) {}

SdoClient::TransferId SdoClient::enqueue(std::unique_ptr<Transfer> transfer, TimePoint now,
                                         Output& out) {
  transfer->id = next_id_++;
  transfer->mode = transfer->options.mode;
  const auto id = transfer->id;
  queue_.push_back(std::move(transfer));
  pump(now, out);  // engine rule 5: an idle channel starts at once
  return id;
}

SdoClient::TransferId SdoClient::download(std::uint16_t index, std::uint8_t sub,
                                          std::vector<std::uint8_t> data, TimePoint now,
                                          Output& out, SdoTransferOptions options) {
  auto t = std::make_unique<Transfer>();
  t->index = index;
  t->sub = sub;
  t->options = options;
  t->data = std::move(data);
  return enqueue(std::move(t), now, out);
}

SdoClient::TransferId SdoClient::upload(std::uint16_t index, std::uint8_t sub, TimePoint now,
                                        Output& out, SdoTransferOptions options) {
  auto t = std::make_unique<Transfer>();
  t->upload = true;
  t->index = index;
  t->sub = sub;
  t->options = options;
  return enqueue(std::move(t), now, out);
}

bool SdoClient::cancel(TransferId id, TimePoint now, Output& out, SdoAbort code) {
  if (code == SdoAbort::None) code = SdoAbort::General;  // None would read as success
  if (active_ && active_->id == id) {
    fail(*active_, code, true, now, out);
    pump(now, out);
    return true;
  }
  for (auto it = queue_.begin(); it != queue_.end(); ++it) {
    if ((*it)->id != id) continue;
    auto t = std::move(*it);
    queue_.erase(it);
    auto r = result_of(*t, code);
    r.started = now;
    r.finished = now;
    out.report(std::move(r));
    return true;
  }
  return false;
}

std::optional<TimePoint> SdoClient::next_deadline() const {
  if (active_) return active_->deadline;
  return std::nullopt;
}

SdoResult SdoClient::result_of(const Transfer& t, SdoAbort code) const {
  SdoResult r;
  r.id = t.id;
  r.node_id = config_.node_id;
  r.index = t.index;
  r.sub_index = t.sub;
  r.upload = t.upload;
  r.abort = code;
  r.protocol = t.protocol;
  r.fell_back = t.fell_back;
  return r;
}

void SdoClient::finish(SdoAbort code, bool by_server, TimePoint now, Output& out) {
  auto t = std::move(active_);
  auto r = result_of(*t, code);
  r.aborted_by_server = by_server;
  if (t->upload && code == SdoAbort::None) r.data = std::move(t->data);
  r.started = t->started.value_or(now);
  r.finished = now;
  out.report(std::move(r));
}

void SdoClient::fail(Transfer& t, SdoAbort code, bool send_frame, TimePoint now, Output& out) {
  if (send_frame) out.send(make_frame(config_.request_cob_id, abort_bytes(t.index, t.sub, code)));
  finish(code, false, now, out);
}

void SdoClient::send(Transfer& t, const Bytes& d, TimePoint now, Output& out) {
  out.send(make_frame(config_.request_cob_id, d));
  if (!t.started) t.started = now;
  t.deadline = later(now, t.options.timeout);
}

void SdoClient::pump(TimePoint now, Output& out) {
  // The next queued transfer starts as soon as the channel is free, in the same call.
  while (!active_ && !queue_.empty()) {
    active_ = std::move(queue_.front());
    queue_.pop_front();
    start(*active_, now, out);
  }
}

void SdoClient::on_timer(TimePoint now, Output& out) {
  // CiA 301 abort codes: the client aborts with 0504 0000 when the server does not answer.
  if (active_ && now >= active_->deadline) fail(*active_, SdoAbort::Timeout, true, now, out);
  pump(now, out);
}

bool SdoClient::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!matches(frame, config_.response_cob_id)) return false;
  auto d = sdo_payload(frame);
  if (!d) return false;
  if (active_) handle(*active_, *d, now, out);
  pump(now, out);
  return true;
}

void SdoClient::start(Transfer& t, TimePoint now, Output& out) {
  t.toggle = false;
  t.offset = 0;
  t.size.reset();
  t.options.block_size = clamp_block_size(t.options.block_size);
  Bytes d{};
  put_mux(d, t.index, t.sub);
  if (!t.upload) {
    const auto size = t.data.size();
    if (size > std::numeric_limits<std::uint32_t>::max()) {
      return finish(SdoAbort::OutOfMemory, false, now, out);  // cannot be described on the bus
    }
    if (t.mode == SdoMode::Block) {
      t.protocol = SdoProtocol::Block;
      d[0] = static_cast<std::uint8_t>(kCcsBlockDownload << 5 | (t.options.crc ? 0x04 : 0) | 0x02);
      put_u32(d, 4, static_cast<std::uint32_t>(size));
      t.state = State::BlockDownloadInit;
    } else if (t.mode == SdoMode::Auto && size >= 1 && size <= 4) {
      // CiA 301 download initiate: e=1, s=1, n = 4 - size.
      t.protocol = SdoProtocol::Expedited;
      d[0] = static_cast<std::uint8_t>(kCcsInitiateDownload << 5 | (4 - size) << 2 | 0x03);
      std::copy(t.data.begin(), t.data.end(), d.begin() + 4);
      t.state = State::InitiateDownload;
    } else {
      t.protocol = SdoProtocol::Segmented;
      d[0] = kCcsInitiateDownload << 5 | 0x01;
      put_u32(d, 4, static_cast<std::uint32_t>(size));
      t.state = State::InitiateDownload;
    }
  } else {
    t.data.clear();
    if (t.mode == SdoMode::Block) {
      t.protocol = SdoProtocol::Block;
      d[0] = static_cast<std::uint8_t>(kCcsBlockUpload << 5 | (t.options.crc ? 0x04 : 0));
      d[4] = t.options.block_size;
      d[5] = t.options.protocol_switch_threshold;
      t.state = State::BlockUploadInit;
    } else {
      t.protocol = SdoProtocol::Segmented;  // until the server answers expedited
      d[0] = kCcsInitiateUpload << 5;
      t.state = State::InitiateUpload;
    }
  }
  send(t, d, now, out);
}

void SdoClient::send_download_segment(Transfer& t, TimePoint now, Output& out) {
  const std::size_t len = std::min(kSegmentBytes, t.data.size() - t.offset);
  const bool last = t.offset + len == t.data.size();
  Bytes d{};
  d[0] = static_cast<std::uint8_t>(kCcsDownloadSegment << 5 | (t.toggle ? 0x10 : 0) |
                                   (kSegmentBytes - len) << 1 | (last ? 1 : 0));
  std::copy_n(t.data.begin() + static_cast<std::ptrdiff_t>(t.offset), len, d.begin() + 1);
  t.state = State::DownloadSegment;
  send(t, d, now, out);
}

void SdoClient::send_download_sub_block(Transfer& t, TimePoint now, Output& out) {
  std::size_t pos = t.offset;
  t.sent_in_block = 0;
  t.block_has_last = false;
  for (std::uint8_t seq = 1; seq <= t.block_size; ++seq) {
    const std::size_t len = std::min(kSegmentBytes, t.data.size() - pos);
    const bool last = pos + len == t.data.size();
    Bytes d{};
    d[0] = static_cast<std::uint8_t>((last ? 0x80 : 0) | seq);
    std::copy_n(t.data.begin() + static_cast<std::ptrdiff_t>(pos), len, d.begin() + 1);
    send(t, d, now, out);
    pos += len;
    t.sent_in_block = seq;
    if (last) {
      t.block_has_last = true;
      break;
    }
  }
  t.state = State::BlockDownload;
}

void SdoClient::handle(Transfer& t, const Bytes& d, TimePoint now, Output& out) {
  // While a block upload's segments arrive only 0x80 is an abort (see the server).
  const bool is_abort = t.state == State::BlockUpload ? d[0] == 0x80 : command(d) == kCsAbort;
  if (is_abort) {
    auto code = static_cast<SdoAbort>(get_u32(d, 4));
    if (code == SdoAbort::None) code = SdoAbort::General;  // 0 would read as success
    const bool block_init =
        t.state == State::BlockDownloadInit || t.state == State::BlockUploadInit;
    if (block_init && code == SdoAbort::InvalidCommandSpecifier && !t.fell_back) {
      // The server does not do block transfer: retry with expedited/segmented.
      t.fell_back = true;
      t.mode = SdoMode::Auto;
      return start(t, now, out);
    }
    return finish(code, true, now, out);
  }
  const auto cs = command(d);
  switch (t.state) {
    case State::InitiateDownload:
      if (cs != kScsInitiateDownload)
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      if (!same_mux(d, t.index, t.sub)) return fail(t, SdoAbort::General, true, now, out);
      if (t.protocol == SdoProtocol::Expedited) return finish(SdoAbort::None, false, now, out);
      return send_download_segment(t, now, out);

    case State::DownloadSegment: {
      if (cs != kScsDownloadSegment)
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      if (((d[0] & 0x10) != 0) != t.toggle) {
        return fail(t, SdoAbort::ToggleBitNotAlternated, true, now, out);
      }
      const std::size_t len = std::min(kSegmentBytes, t.data.size() - t.offset);
      t.offset += len;
      if (t.offset == t.data.size()) return finish(SdoAbort::None, false, now, out);
      t.toggle = !t.toggle;
      return send_download_segment(t, now, out);
    }

    case State::BlockUploadInit:
      if (cs == kScsBlockUpload && (d[0] & 0x01) == 0) {
        if (!same_mux(d, t.index, t.sub)) return fail(t, SdoAbort::General, true, now, out);
        t.crc = t.options.crc && (d[0] & 0x04) != 0;
        if ((d[0] & 0x02) != 0) {
          t.size = get_u32(d, 4);
          if (*t.size > t.options.max_size) return fail(t, SdoAbort::OutOfMemory, true, now, out);
        }
        t.block_size = t.options.block_size;
        t.ack_seq = 0;
        t.last_received = false;
        t.state = State::BlockUpload;
        Bytes r{};
        r[0] = kCcsBlockUpload << 5 | 0x03;  // start upload
        return send(t, r, now, out);
      }
      if (cs != kScsInitiateUpload)
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      // The server switched protocols (protocol switch threshold): a normal upload response.
      t.protocol = SdoProtocol::Segmented;
      [[fallthrough]];
    case State::InitiateUpload: {
      if (cs != kScsInitiateUpload)
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      if (!same_mux(d, t.index, t.sub)) return fail(t, SdoAbort::General, true, now, out);
      const bool expedited = (d[0] & 0x02) != 0;
      const bool size_indicated = (d[0] & 0x01) != 0;
      if (expedited) {
        const std::size_t size = size_indicated ? 4 - (d[0] >> 2 & 0x3) : 4;
        t.data.assign(d.begin() + 4, d.begin() + 4 + static_cast<std::ptrdiff_t>(size));
        t.protocol = SdoProtocol::Expedited;
        return finish(SdoAbort::None, false, now, out);
      }
      if (size_indicated) {
        t.size = get_u32(d, 4);
        if (*t.size > t.options.max_size) return fail(t, SdoAbort::OutOfMemory, true, now, out);
        t.data.reserve(std::min<std::size_t>(*t.size, 1 << 16));
      }
      t.protocol = SdoProtocol::Segmented;
      t.toggle = false;
      t.state = State::UploadSegment;
      Bytes r{};
      r[0] = kCcsUploadSegment << 5;
      return send(t, r, now, out);
    }

    case State::UploadSegment: {
      if (cs != kScsUploadSegment)
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      if (((d[0] & 0x10) != 0) != t.toggle) {
        return fail(t, SdoAbort::ToggleBitNotAlternated, true, now, out);
      }
      const std::size_t len = kSegmentBytes - (d[0] >> 1 & 0x7);
      const bool last = (d[0] & 0x01) != 0;
      if (t.data.size() + len > t.options.max_size) {
        return fail(t, SdoAbort::OutOfMemory, true, now, out);
      }
      t.data.insert(t.data.end(), d.begin() + 1, d.begin() + 1 + static_cast<std::ptrdiff_t>(len));
      if (t.size && t.data.size() > *t.size)
        return fail(t, SdoAbort::LengthMismatch, true, now, out);
      if (last) {
        if (t.size && t.data.size() != *t.size) {
          return fail(t, SdoAbort::LengthMismatch, true, now, out);
        }
        return finish(SdoAbort::None, false, now, out);
      }
      t.toggle = !t.toggle;
      Bytes r{};
      r[0] = static_cast<std::uint8_t>(kCcsUploadSegment << 5 | (t.toggle ? 0x10 : 0));
      return send(t, r, now, out);
    }

    case State::BlockDownloadInit: {
      if (cs != kScsBlockDownload || (d[0] & 0x03) != 0) {
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      }
      if (!same_mux(d, t.index, t.sub)) return fail(t, SdoAbort::General, true, now, out);
      if (!valid_block_size(d[4])) return fail(t, SdoAbort::InvalidBlockSize, true, now, out);
      t.crc = t.options.crc && (d[0] & 0x04) != 0;
      t.block_size = d[4];
      t.offset = 0;
      return send_download_sub_block(t, now, out);
    }

    case State::BlockDownload: {
      if (cs != kScsBlockDownload || (d[0] & 0x03) != 2) {
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      }
      const std::uint8_t ack_seq = d[1];
      if (ack_seq > t.sent_in_block)
        return fail(t, SdoAbort::InvalidSequenceNumber, true, now, out);
      if (!valid_block_size(d[2])) return fail(t, SdoAbort::InvalidBlockSize, true, now, out);
      t.offset = std::min(t.data.size(), t.offset + ack_seq * kSegmentBytes);
      t.block_size = d[2];
      if (ack_seq == t.sent_in_block && t.block_has_last) {
        // CiA 301 end block download: n and the CRC over the whole value.
        Bytes r{};
        const auto n = kSegmentBytes - last_segment_bytes(t.data.size());
        r[0] = static_cast<std::uint8_t>(kCcsBlockDownload << 5 | n << 2 | 0x01);
        if (t.crc) {
          const auto crc = sdo_block_crc(t.data);
          r[1] = static_cast<std::uint8_t>(crc);
          r[2] = static_cast<std::uint8_t>(crc >> 8);
        }
        t.state = State::BlockDownloadEnd;
        return send(t, r, now, out);
      }
      // Resend from the segment after the last one acknowledged, numbering from 1 again.
      return send_download_sub_block(t, now, out);
    }

    case State::BlockDownloadEnd:
      if (cs != kScsBlockDownload || (d[0] & 0x03) != 1) {
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      }
      return finish(SdoAbort::None, false, now, out);

    case State::BlockUpload: {
      const std::uint8_t seq = d[0] & 0x7F;
      const bool last = (d[0] & 0x80) != 0;
      if (seq == 0 || seq > t.block_size) {
        return fail(t, SdoAbort::InvalidSequenceNumber, true, now, out);
      }
      if (seq == t.ack_seq + 1 && !t.last_received) {
        if (t.data.size() + kSegmentBytes > t.options.max_size + kSegmentBytes) {
          return fail(t, SdoAbort::OutOfMemory, true, now, out);
        }
        t.data.insert(t.data.end(), d.begin() + 1, d.end());
        t.ack_seq = seq;
        t.last_received = last;
      }
      if (last || seq == t.block_size) {
        Bytes r{};
        r[0] = kCcsBlockUpload << 5 | 0x02;
        r[1] = t.ack_seq;
        r[2] = t.options.block_size;
        t.block_size = t.options.block_size;
        t.ack_seq = 0;
        if (t.last_received) t.state = State::BlockUploadEnd;
        return send(t, r, now, out);
      }
      t.deadline = later(now, t.options.timeout);  // segments keep the transfer alive
      return;
    }

    case State::BlockUploadEnd: {
      if (cs != kScsBlockUpload || (d[0] & 0x03) != 1) {
        return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
      }
      const std::size_t n = d[0] >> 2 & 0x7;
      if (n > t.data.size()) return fail(t, SdoAbort::LengthMismatch, true, now, out);
      t.data.resize(t.data.size() - n);
      if (t.size && t.data.size() != *t.size)
        return fail(t, SdoAbort::LengthMismatch, true, now, out);
      if (t.crc && sdo_block_crc(t.data) != static_cast<std::uint16_t>(d[1] | d[2] << 8)) {
        return fail(t, SdoAbort::CrcError, true, now, out);
      }
      Bytes r{};
      r[0] = kCcsBlockUpload << 5 | 0x01;  // end response
      out.send(make_frame(config_.request_cob_id, r));
      return finish(SdoAbort::None, false, now, out);
    }
  }
}

// ===================================================================================== mux ==

SdoClient& SdoClientMux::client(std::uint8_t node_id) {
  return add(SdoClientConfig::for_node(node_id));
}

SdoClient& SdoClientMux::add(SdoClientConfig config) {
  auto& slot = clients_[cfg::CobId::of(config.response_cob_id.can_id()).word()];
  if (!slot) slot = std::make_unique<SdoClient>(config);
  return *slot;
}

bool SdoClientMux::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto it = clients_.find(cfg::CobId::of({frame.id, frame.extended}).word());
  return it != clients_.end() && it->second->on_frame(frame, now, out);
}

void SdoClientMux::on_timer(TimePoint now, Output& out) {
  for (auto& [cob, c] : clients_) {
    if (auto t = c->next_deadline(); t && *t <= now) c->on_timer(now, out);
  }
}

std::optional<TimePoint> SdoClientMux::next_deadline() const {
  std::optional<TimePoint> best;
  for (const auto& [cob, c] : clients_) {
    if (auto t = c->next_deadline(); t && (!best || *t < *best)) best = t;
  }
  return best;
}

bool SdoClientMux::busy() const {
  return std::any_of(clients_.begin(), clients_.end(),
                     [](const auto& kv) { return kv.second->busy(); });
}

}  // namespace nmt
