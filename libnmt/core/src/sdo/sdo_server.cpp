#include "nmt/sdo/sdo_server.hpp"

#include <algorithm>
#include <limits>
#include <variant>

#include "cfg/object_index.hpp"
#include "sdo/saturating_time.hpp"

namespace nmt {

SdoServerConfig SdoServerConfig::for_node(cfg::NodeId node_id) {
  SdoServerConfig c;
  const auto cob_ids = sdo::default_cob_ids(node_id);
  c.request_cob_id = cob_ids.request;
  c.response_cob_id = cob_ids.response;
  return c;
}

SdoServerConfig SdoServerConfig::from_dictionary(const LocalDictionary& dict) {
  // A dictionary built empty has no node-ID: 600h/580h, as SdoServerConfig{} has them.
  auto c = dict.node_id() ? for_node(*dict.node_id()) : SdoServerConfig{};
  // CiA 301 object 1200h sub 1/2: the COB-IDs of the default SDO server channel.
  auto cob = [&](std::uint8_t sub) -> std::optional<cfg::CobId> {
    const auto id = dict.get_cob_id(cfg::object::kSdoServerFirst, sub);
    return id && cfg::usable_can_id(*id) ? id : std::nullopt;
  };
  auto rx = cob(1);
  auto tx = cob(2);
  if (rx && tx) {
    c.request_cob_id = *rx;
    c.response_cob_id = *tx;
  }
  return c;
}

SdoServerConfig SdoServerConfig::from_dictionary(const LocalDictionary& dict, std::uint16_t index) {
  if (index == cfg::object::kSdoServerFirst) return from_dictionary(dict);
  SdoServerConfig c;
  // CiA 301 §7.5.2.33: an additional channel exists only while bit 31 of both COB-IDs is 0;
  // a word that does not fit 32 bits or is absent is taken as "not valid".
  auto cob = [&](std::uint8_t sub) {
    return dict.get_cob_id(index, sub).value_or(cfg::CobId::from_word(cfg::kCobIdInvalidBit));
  };
  c.request_cob_id = cob(1);
  c.response_cob_id = cob(2);
  return c;
}

SdoServer::SdoServer(LocalDictionary& dict, SdoServerConfig config)
    : dict_(&dict), config_(config) {
  config_.block_size = sdo::clamp_block_size(config_.block_size);
}

void SdoServer::set_config(SdoServerConfig config) {
  config_ = config;
  config_.block_size = sdo::clamp_block_size(config_.block_size);
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
  empty_rounds_ = 0;
  sent_in_block_ = 0;
  last_received_ = false;
  block_has_last_ = false;
  held_ticket_ = 0;
  timeout_at_.reset();
}

std::optional<TimePoint> SdoServer::next_deadline() const {
  return timeout_at_;
}

bool SdoServer::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  return on_frame(frame, now, out, HookOutput(out));
}

bool SdoServer::on_frame(const CanFrame& frame, TimePoint now, Output& out, HookOutput hooks) {
  // A channel without a usable response COB-ID cannot answer: it serves nothing.
  if (!sdo::on_channel(frame, config_.request_cob_id) ||
      !cfg::usable_can_id(config_.response_cob_id)) {
    return false;
  }
  auto d = sdo::sdo_payload(frame);
  if (!d) return false;
  stalled_ = false;
  handle(*d, now, hooks, out);
  // A block round that brought nothing forward (an acknowledgement of no segment, sent or
  // received) does not extend the timeout. Otherwise two ends that disagree on the state answer
  // each other for ever: after a lost client abort, this server's block download takes the
  // acknowledgement of the client's next block upload (A2h: c=1, seqno 34) for an out-of-order
  // last segment and acknowledges no segment (A2h), which the client reads the same way.
  if (state_ == State::Idle || state_ == State::ConfirmationHeld) {
    // A held confirmation waits for the owner, not for the client (complete_download).
    timeout_at_.reset();
  } else if (!stalled_ || !timeout_at_) {
    timeout_at_ = later(now, config_.timeout);
  }
  return true;
}

void SdoServer::on_timer(TimePoint now, Output& out) {
  if (timeout_at_ && now >= *timeout_at_) send_abort(SdoAbort::Timeout, out);
}

bool SdoServer::complete_download(std::uint64_t ticket, SdoAbort code, Output& out) {
  if (state_ != State::ConfirmationHeld || held_ticket_ != ticket) return false;
  if (code != SdoAbort::None) {
    send_abort(code, out);
    return true;
  }
  out.send(held_confirmation_);
  reset();
  return true;
}

void SdoServer::abort(SdoAbort code, TimePoint /*now*/, Output& out) {
  if (state_ == State::Idle) return;
  send_abort(code, out);
}

template <class Frame>
void SdoServer::respond(const Frame& f, Output& out) {
  out.send(sdo::make_frame(config_.response_cob_id, sdo::encode(f)));
}

void SdoServer::send_abort(SdoAbort code, Output& out) {
  out.send(sdo::make_frame(config_.response_cob_id, sdo::encode(sdo::Abort{address_, code})));
  reset();
}

void SdoServer::handle(const sdo::Payload& d, TimePoint now, HookOutput hooks, Output& out) {
  if (state_ == State::BlockDownload) {
    // Inside a sub-block every frame is a segment, except an abort.
    const auto f = sdo::parse_sub_block_frame(d);
    if (const auto* segment = std::get_if<sdo::BlockSegment>(&f)) {
      return block_download_segment(*segment, out);
    }
    return reset();  // CiA 301 SDO abort transfer protocol: not confirmed
  }
  const auto f = sdo::parse_client_frame(d);
  if (f && std::holds_alternative<sdo::Abort>(*f)) return reset();
  // A transfer starts with an initiate request, which names the object; an abort answering
  // any other frame in idle names 0000h sub 00h.
  if (state_ == State::Idle) address_ = {};
  if (!f) return send_abort(SdoAbort::InvalidCommandSpecifier, out);
  handle_command(*f, now, hooks, out);
}

void SdoServer::handle_command(const sdo::ClientFrame& f, TimePoint now, HookOutput hooks,
                               Output& out) {
  switch (state_) {
    case State::Idle:
      if (const auto* r = std::get_if<sdo::InitiateDownloadRequest>(&f)) {
        address_ = r->address;
        return initiate_download(*r, now, hooks, out);
      }
      if (const auto* r = std::get_if<sdo::InitiateUploadRequest>(&f)) {
        address_ = r->address;
        if (auto code = dict_->read(address_.index, address_.sub_index, buffer_, now, hooks);
            code != SdoAbort::None) {
          return send_abort(code, out);
        }
        return start_upload(out);
      }
      // Without block transfer the block commands are unknown to this server: clients fall
      // back. (Other block frames can only come in block states, which need them on.)
      if (const auto* r = std::get_if<sdo::BlockDownloadInitiateRequest>(&f)) {
        address_ = r->address;
        if (!config_.block_transfer) break;
        return block_download_initiate(*r, out);
      }
      if (const auto* r = std::get_if<sdo::BlockUploadInitiateRequest>(&f)) {
        address_ = r->address;
        if (!config_.block_transfer) break;
        return block_upload_initiate(*r, now, hooks, out);
      }
      break;
    case State::DownloadSegment:
      if (const auto* r = std::get_if<sdo::DownloadSegmentRequest>(&f)) {
        return download_segment(*r, now, hooks, out);
      }
      break;
    case State::UploadSegment:
      if (const auto* r = std::get_if<sdo::UploadSegmentRequest>(&f)) {
        return upload_segment(*r, out);
      }
      break;
    case State::BlockDownload:  // handled in handle()
      break;
    case State::BlockDownloadEnd:
      if (const auto* r = std::get_if<sdo::BlockDownloadEndRequest>(&f)) {
        return block_download_end(*r, now, hooks, out);
      }
      break;
    case State::BlockUploadStart:
      if (std::holds_alternative<sdo::BlockUploadStart>(f)) {
        state_ = State::BlockUpload;
        return send_upload_sub_block(out);
      }
      break;
    case State::BlockUpload:
      if (const auto* r = std::get_if<sdo::BlockUploadAck>(&f)) return block_upload_ack(*r, out);
      break;
    case State::BlockUploadEnd:
      if (std::holds_alternative<sdo::BlockUploadEndResponse>(f)) {
        return reset();  // the client confirmed the end: done
      }
      break;
    case State::ConfirmationHeld:  // the client must wait for the confirmation
      break;
  }
  send_abort(SdoAbort::InvalidCommandSpecifier, out);
}

// CiA 301 §7.2.4.3, SDO download initiate protocol: expedited or segmented.
void SdoServer::initiate_download(const sdo::InitiateDownloadRequest& f, TimePoint now,
                                  HookOutput hooks, Output& out) {
  const auto [index, sub] = address_;
  if (f.expedited) {
    std::size_t size = 4;
    if (f.size) {
      size = *f.size;
    } else if (const auto* e = dict_->entry(index, sub);
               e && e->fixed_size() && *e->fixed_size() <= 4) {
      size = *e->fixed_size();  // size not indicated: the object's own size
    }
    const auto verdict =
        dict_->write_download(index, sub, std::span(f.data).first(size), now, hooks);
    return confirm_download(verdict, sdo::InitiateDownloadResponse{address_}, out);
  }
  if (f.size) size_ = *f.size;
  if (auto code = dict_->check_write(index, sub, size_); code != SdoAbort::None) {
    return send_abort(code, out);
  }
  if (size_ && *size_ > config_.max_download_size) return send_abort(SdoAbort::OutOfMemory, out);
  buffer_.clear();
  buffer_.reserve(std::min<std::size_t>(size_.value_or(0), 1 << 16));
  toggle_ = false;
  state_ = State::DownloadSegment;
  respond(sdo::InitiateDownloadResponse{address_}, out);
}

// CiA 301 §7.2.4.3, SDO download segment protocol: the toggle bit starts at 0 and alternates.
void SdoServer::download_segment(const sdo::DownloadSegmentRequest& f, TimePoint now,
                                 HookOutput hooks, Output& out) {
  if (f.toggle != toggle_) return send_abort(SdoAbort::ToggleBitNotAlternated, out);
  if (size_ && buffer_.size() + f.size > *size_) return send_abort(SdoAbort::LengthMismatch, out);
  if (buffer_.size() + f.size > config_.max_download_size) {
    return send_abort(SdoAbort::OutOfMemory, out);
  }
  if (!size_) {
    if (auto code = check_running_size(buffer_.size() + f.size); code != SdoAbort::None) {
      return send_abort(code, out);
    }
  }
  buffer_.insert(buffer_.end(), f.data.begin(), f.data.begin() + f.size);
  const sdo::DownloadSegmentResponse response{f.toggle};
  // The response to the last segment confirms the write, so it is sent only after it.
  if (f.last) return finish_download(response, now, hooks, out);
  toggle_ = !toggle_;
  respond(response, out);
}

// A download without an indicated size, `size` bytes into its data: the dictionary's verdict
// on a value of that size, except "too short" (more data may follow).
SdoAbort SdoServer::check_running_size(std::size_t size) const {
  const auto code = dict_->check_write(address_.index, address_.sub_index, size);
  return code == SdoAbort::LengthTooLow ? SdoAbort::None : code;
}

template <class Frame>
void SdoServer::finish_download(const Frame& confirmation, TimePoint now, HookOutput hooks,
                                Output& out) {
  if (size_ && buffer_.size() != *size_) return send_abort(SdoAbort::LengthMismatch, out);
  const auto verdict =
      dict_->write_download(address_.index, address_.sub_index, buffer_, now, hooks);
  confirm_download(verdict, confirmation, out);
}

template <class Frame>
void SdoServer::confirm_download(const WriteVerdict& verdict, const Frame& confirmation,
                                 Output& out) {
  if (verdict.abort != SdoAbort::None) return send_abort(verdict.abort, out);
  if (!verdict.held) {
    respond(confirmation, out);
    return reset();
  }
  // The value is stored; the confirmation leaves when the owner completes the write.
  reset();
  state_ = State::ConfirmationHeld;
  held_ticket_ = *verdict.held;
  held_confirmation_ = sdo::make_frame(config_.response_cob_id, sdo::encode(confirmation));
}

// CiA 301 §7.2.4.3, SDO upload initiate protocol: the response for the value in buffer_; values
// of 1..4 bytes go expedited.
void SdoServer::start_upload(Output& out) {
  sdo::InitiateUploadResponse r;
  r.address = address_;
  if (!buffer_.empty() && buffer_.size() <= 4) {
    r.expedited = true;
    r.size = static_cast<std::uint32_t>(buffer_.size());
    std::copy(buffer_.begin(), buffer_.end(), r.data.begin());
    respond(r, out);
    reset();
    return;
  }
  if (buffer_.size() > std::numeric_limits<std::uint32_t>::max()) {
    return send_abort(SdoAbort::OutOfMemory, out);
  }
  r.size = static_cast<std::uint32_t>(buffer_.size());  // segmented, size indicated
  offset_ = 0;
  toggle_ = false;
  state_ = State::UploadSegment;
  respond(r, out);
}

void SdoServer::upload_segment(const sdo::UploadSegmentRequest& f, Output& out) {
  if (f.toggle != toggle_) return send_abort(SdoAbort::ToggleBitNotAlternated, out);
  const std::size_t len = std::min(sdo::kSegmentBytes, buffer_.size() - offset_);
  sdo::UploadSegmentResponse r;
  r.toggle = f.toggle;
  r.last = offset_ + len == buffer_.size();
  r.size = static_cast<std::uint8_t>(len);
  std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(offset_), len, r.data.begin());
  respond(r, out);
  offset_ += len;
  toggle_ = !toggle_;
  if (r.last) reset();
}

// CiA 301 §7.2.4.3, SDO block download protocol: initiate.
void SdoServer::block_download_initiate(const sdo::BlockDownloadInitiateRequest& f, Output& out) {
  crc_ = f.crc;
  if (f.size) size_ = *f.size;
  if (auto code = dict_->check_write(address_.index, address_.sub_index, size_);
      code != SdoAbort::None) {
    return send_abort(code, out);
  }
  if (size_ && *size_ > config_.max_download_size) return send_abort(SdoAbort::OutOfMemory, out);
  buffer_.clear();
  buffer_.reserve(std::min<std::size_t>(size_.value_or(0), 1 << 20));
  block_size_ = config_.block_size;
  ack_seq_ = 0;
  empty_rounds_ = 0;
  last_received_ = false;
  state_ = State::BlockDownload;
  respond(sdo::BlockDownloadInitiateResponse{address_, true, block_size_}, out);  // sc: CRC
}

void SdoServer::block_download_segment(const sdo::BlockSegment& f, Output& out) {
  if (f.seq == 0 || f.seq > block_size_) return send_abort(SdoAbort::InvalidSequenceNumber, out);
  // Segments after a lost one are ignored; the acknowledgement names the last one received in
  // order and the client resends from there (CiA 301 block download sub-block).
  if (f.seq == ack_seq_ + 1 && !last_received_) {
    // Segments carry 7 bytes each, the last one padded: never more than the size needs.
    const std::size_t limit = size_ ? *size_ : config_.max_download_size;
    const std::size_t segments =
        std::max<std::size_t>(1, (limit + sdo::kSegmentBytes - 1) / sdo::kSegmentBytes);
    if (buffer_.size() + sdo::kSegmentBytes > segments * sdo::kSegmentBytes) {
      return send_abort(size_ ? SdoAbort::LengthMismatch : SdoAbort::OutOfMemory, out);
    }
    // The last segment may carry padding (the end request says how much): only the bytes
    // before this segment are surely data.
    if (!size_) {
      if (auto code = check_running_size(buffer_.size() + 1); code != SdoAbort::None) {
        return send_abort(code, out);
      }
    }
    buffer_.insert(buffer_.end(), f.data.begin(), f.data.end());
    ack_seq_ = f.seq;
    last_received_ = f.last;
  }
  if (f.last || f.seq == block_size_) {
    stalled_ = ack_seq_ == 0;
    empty_rounds_ = stalled_ ? empty_rounds_ + 1 : 0;
    if (empty_rounds_ >= sdo::kMaxEmptyBlockRounds) {
      return send_abort(SdoAbort::InvalidSequenceNumber, out);
    }
    respond(sdo::BlockDownloadAck{ack_seq_, block_size_}, out);
    ack_seq_ = 0;
    if (last_received_) state_ = State::BlockDownloadEnd;
  }
}

// CiA 301 §7.2.4.3, SDO block download protocol: the end request carries n (bytes of the last
// segment without data) and the CRC of the whole value.
void SdoServer::block_download_end(const sdo::BlockDownloadEndRequest& f, TimePoint now,
                                   HookOutput hooks, Output& out) {
  if (f.empty_bytes > buffer_.size()) return send_abort(SdoAbort::LengthMismatch, out);
  buffer_.resize(buffer_.size() - f.empty_bytes);
  if (crc_ && sdo_block_crc(buffer_) != f.crc) return send_abort(SdoAbort::CrcError, out);
  finish_download(sdo::BlockDownloadEndResponse{}, now, hooks, out);
}

// CiA 301 §7.2.4.3, SDO block upload protocol: initiate.
void SdoServer::block_upload_initiate(const sdo::BlockUploadInitiateRequest& f, TimePoint now,
                                      HookOutput hooks, Output& out) {
  if (!sdo::valid_block_size(f.block_size)) return send_abort(SdoAbort::InvalidBlockSize, out);
  if (auto code = dict_->read(address_.index, address_.sub_index, buffer_, now, hooks);
      code != SdoAbort::None) {
    return send_abort(code, out);
  }
  // Protocol switch threshold: small values may go by the normal upload protocol.
  if (f.protocol_switch_threshold != 0 && buffer_.size() <= f.protocol_switch_threshold) {
    return start_upload(out);
  }
  if (buffer_.size() > std::numeric_limits<std::uint32_t>::max()) {
    return send_abort(SdoAbort::OutOfMemory, out);
  }
  crc_ = f.crc;
  block_size_ = f.block_size;
  offset_ = 0;
  state_ = State::BlockUploadStart;
  // sc: this server sends a CRC; s: size indicated.
  respond(
      sdo::BlockUploadInitiateResponse{address_, true, static_cast<std::uint32_t>(buffer_.size())},
      out);
}

void SdoServer::block_upload_ack(const sdo::BlockUploadAck& f, Output& out) {
  if (f.ack_seq > sent_in_block_) return send_abort(SdoAbort::InvalidSequenceNumber, out);
  if (!sdo::valid_block_size(f.block_size)) return send_abort(SdoAbort::InvalidBlockSize, out);
  const bool all_acknowledged = f.ack_seq == sent_in_block_;
  stalled_ = f.ack_seq == 0 && !all_acknowledged;  // the same sub-block again
  offset_ = std::min(buffer_.size(), offset_ + f.ack_seq * sdo::kSegmentBytes);
  block_size_ = f.block_size;
  if (all_acknowledged && block_has_last_) {
    const std::uint16_t crc = crc_ ? sdo_block_crc(buffer_) : 0;
    state_ = State::BlockUploadEnd;
    respond(sdo::BlockUploadEndRequest{sdo::last_segment_empty_bytes(buffer_.size()), crc}, out);
    return;
  }
  send_upload_sub_block(out);
}

void SdoServer::send_upload_sub_block(Output& out) {
  std::size_t pos = offset_;
  sent_in_block_ = 0;
  block_has_last_ = false;
  for (std::uint8_t seq = 1; seq <= block_size_; ++seq) {
    const std::size_t len = std::min(sdo::kSegmentBytes, buffer_.size() - pos);
    sdo::BlockSegment segment;
    segment.last = pos + len == buffer_.size();
    segment.seq = seq;
    std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(pos), len, segment.data.begin());
    out.send(sdo::make_frame(config_.response_cob_id, sdo::encode(segment)));
    pos += len;
    sent_in_block_ = seq;
    if (segment.last) {
      block_has_last_ = true;
      break;
    }
  }
}

// --- SdoServerChannels ---

void SdoServerChannels::open(std::uint16_t index, SdoServerConfig config) {
  const auto at = std::find_if(channels_.begin(), channels_.end(),
                               [index](const Channel& c) { return c.index >= index; });
  if (at != channels_.end() && at->index == index) {
    at->server = SdoServer(*dict_, config);
    return;
  }
  channels_.insert(at, {index, SdoServer(*dict_, config)});
}

void SdoServerChannels::open_from_dictionary(std::uint16_t index, Duration timeout) {
  if (is_open(index)) return;
  auto config = SdoServerConfig::from_dictionary(*dict_, index);
  config.timeout = timeout;
  open(index, config);
}

void SdoServerChannels::close(std::uint16_t index) {
  std::erase_if(channels_, [index](const Channel& c) { return c.index == index; });
}

void SdoServerChannels::reconfigure(Duration timeout, bool restart_all) {
  for (auto& c : channels_) {
    auto config = SdoServerConfig::from_dictionary(*dict_, c.index);
    config.timeout = timeout;
    const auto& current = c.server.config();
    if (restart_all || config.request_cob_id != current.request_cob_id ||
        config.response_cob_id != current.response_cob_id || config.timeout != current.timeout) {
      c.server.set_config(config);
    }
  }
}

std::vector<std::uint16_t> SdoServerChannels::indices() const {
  std::vector<std::uint16_t> out;
  out.reserve(channels_.size());
  for (const auto& c : channels_) out.push_back(c.index);
  return out;
}

const SdoServer* SdoServerChannels::find(std::uint16_t index) const {
  for (const auto& c : channels_) {
    if (c.index == index) return &c.server;
  }
  return nullptr;
}

std::optional<std::uint16_t> SdoServerChannels::on_frame(
    const CanFrame& frame, TimePoint now, SdoServer::Output& out, HookOutput hooks,
    const std::function<void(std::uint16_t)>& before) {
  for (auto& c : channels_) {
    if (before) before(c.index);
    if (c.server.on_frame(frame, now, out, hooks)) return c.index;
  }
  return std::nullopt;
}

void SdoServerChannels::on_timer(TimePoint now, SdoServer::Output& out) {
  for (auto& c : channels_) c.server.on_timer(now, out);
}

bool SdoServerChannels::complete_download(std::uint64_t ticket, SdoAbort code,
                                          SdoServer::Output& out) {
  for (auto& c : channels_) {
    if (c.server.complete_download(ticket, code, out)) return true;
  }
  return false;
}

std::optional<TimePoint> SdoServerChannels::next_deadline() const {
  std::optional<TimePoint> next;
  for (const auto& c : channels_) next = earliest(next, c.server.next_deadline());
  return next;
}

}  // namespace nmt
