#include "nmt/sdo/sdo_client.hpp"

#include <algorithm>
#include <limits>
#include <string>
#include <variant>

#include "cfg/object_index.hpp"
#include "nmt/protocol/frame_bits.hpp"
#include "nmt/slave/local_dictionary.hpp"
#include "sdo/saturating_time.hpp"

namespace nmt {

SdoClientConfig SdoClientConfig::for_node(cfg::NodeId node_id) {
  SdoClientConfig c;
  const auto cob_ids = sdo::default_cob_ids(node_id);
  c.request_cob_id = cob_ids.request;
  c.response_cob_id = cob_ids.response;
  c.node_id = node_id;
  return c;
}

std::optional<SdoClientConfig> SdoClientConfig::from_dictionary(const LocalDictionary& dict,
                                                                std::uint16_t index) {
  if (!cfg::object::is_sdo_client_parameter(index)) return std::nullopt;
  const auto request = dict.get_cob_id(index, 1);
  const auto response = dict.get_cob_id(index, 2);
  if (!request || !response || !cfg::usable_can_id(*request) || !cfg::usable_can_id(*response)) {
    return std::nullopt;
  }
  SdoClientConfig c;
  c.request_cob_id = *request;
  c.response_cob_id = *response;
  c.node_id = cfg::NodeId::from(dict.get_unsigned(index, 3).value_or(0));
  return c;
}

SdoClient::SdoClient(SdoClientConfig config) : config_(config) {}

cfg::Status SdoClient::check_start(const SdoTransferOptions& options,
                                   std::optional<std::size_t> download_size) {
  if (options.timeout <= Duration::zero()) {
    return cfg::Error{"the SDO response timeout must be positive (it is " +
                      std::to_string(options.timeout.count()) + " us)"};
  }
  if (download_size && *download_size > std::numeric_limits<std::uint32_t>::max()) {
    // CiA 301 §7.2.4.3.3: the initiate's size is 32 bits.
    return cfg::Error{"a value of " + std::to_string(*download_size) +
                      " bytes is longer than an SDO download can state (at most 4294967295)"};
  }
  return {};
}

cfg::Result<SdoClient::TransferId> SdoClient::enqueue(std::unique_ptr<Transfer> transfer,
                                                      TimePoint now, Output& out) {
  // Engine rule 5: a transfer that cannot start returns why and puts nothing into `out`.
  if (auto ok = check_start(
          transfer->options,
          transfer->upload ? std::nullopt : std::optional<std::size_t>(transfer->data.size()));
      !ok) {
    return ok.error();
  }
  transfer->id = next_id_++;
  transfer->mode = transfer->options.mode;
  const auto id = transfer->id;
  queue_.push_back(std::move(transfer));
  pump(now, out);  // engine rule 5: an idle channel starts at once
  sync_mux_deadline();
  return id;
}

cfg::Result<SdoClient::TransferId> SdoClient::download(std::uint16_t index, std::uint8_t sub,
                                                       std::vector<std::uint8_t> data,
                                                       TimePoint now, Output& out,
                                                       SdoTransferOptions options) {
  auto t = std::make_unique<Transfer>();
  t->index = index;
  t->sub = sub;
  t->options = options;
  t->data = std::move(data);
  return enqueue(std::move(t), now, out);
}

cfg::Result<SdoClient::TransferId> SdoClient::upload(std::uint16_t index, std::uint8_t sub,
                                                     TimePoint now, Output& out,
                                                     SdoTransferOptions options) {
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
    sync_mux_deadline();
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

std::optional<SdoClient::Progress> SdoClient::download_progress() const {
  if (!active_ || active_->upload) return std::nullopt;
  return Progress{active_->id, active_->offset, active_->data.size()};
}

std::optional<TimePoint> SdoClient::next_deadline() const {
  if (!active_) return std::nullopt;
  if (active_->repeat_at) return std::min(*active_->repeat_at, active_->deadline);
  return active_->deadline;
}

void SdoClient::sync_mux_deadline() {
  if (mux_deadlines_ == nullptr) return;
  const auto deadline = next_deadline();
  mux_deadlines_->move(mux_key_, listed_deadline_, deadline);
  listed_deadline_ = deadline;
}

SdoResult SdoClient::result_of(const Transfer& t, SdoAbort code) const {
  SdoResult r;
  r.id = t.id;
  r.node_id = config_.node_id;
  r.address = {t.index, t.sub};
  r.upload = t.upload;
  r.abort = code;
  r.protocol = t.protocol;
  r.fell_back = t.fell_back;
  r.repeats = t.repeats;
  r.longest_answer = t.longest_answer;
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
  if (send_frame)
    out.send(
        sdo::make_frame(config_.request_cob_id, sdo::encode(sdo::Abort{{t.index, t.sub}, code})));
  finish(code, false, now, out);
}

void SdoClient::send(Transfer& t, const sdo::Payload& d, TimePoint now, Output& out) {
  out.send(sdo::make_frame(config_.request_cob_id, d));
  if (!t.started) t.started = now;
  t.deadline = later(now, t.options.timeout);
  t.request = d;
  t.sent_at = now;
  t.request_repeated = false;
  t.repeat_at.reset();
}

namespace {

// Writes whose repetition is not the same as one write: 1010h/1011h start a store or restore
// with each write (CiA 301 §7.5.2.13/14), 1F50h/1F51h hand a program over or control it
// (CiA 302-3).
bool download_never_repeated(std::uint16_t index) {
  return index == cfg::object::kStoreParameters ||
         index == cfg::object::kRestoreDefaultParameters || index == cfg::object::kProgramData ||
         index == cfg::object::kProgramControl;
}

}  // namespace

// An initiate upload is repeated before the client knows the answer's protocol. A value longer
// than 4 bytes is answered segmented, and a server that refuses a second initiate while its
// segmented upload runs (abort 0504 0001, as SdoServer does) ends a repeated upload whose answer
// was only late with that abort (never with a wrong value): callers repeat uploads of values
// that fit 4 bytes (the master's boot reads only 32-bit objects).
void SdoClient::arm_repeat(Transfer& t, TimePoint now) {
  const auto& after = t.options.repeat_after;
  if (!after || *after <= Duration::zero() || t.repeats >= sdo::kMaxRepeats) return;
  const bool expedited_request = t.upload ? t.state == State::InitiateUpload
                                          : t.state == State::InitiateDownload &&
                                                t.protocol == SdoProtocol::Expedited &&
                                                !download_never_repeated(t.index);
  if (!expedited_request) return;
  const TimePoint at = later(now, *after);
  if (at < t.deadline) t.repeat_at = at;
}

void SdoClient::repeat(Transfer& t, TimePoint now, Output& out) {
  // The same frame again; the timeout keeps running from the first request.
  out.send(sdo::make_frame(config_.request_cob_id, t.request));
  t.request_repeated = true;
  t.repeat_at.reset();
  ++t.repeats;
  stray_ = {{t.index, t.sub}, t.repeats, t.deadline};
  arm_repeat(t, now);
}

void SdoClient::note_answer(Transfer& t, TimePoint now) {
  if (t.request_repeated) return;
  const Duration took = now - t.sent_at;
  t.longest_answer = t.longest_answer ? std::max(*t.longest_answer, took) : took;
}

bool SdoClient::stray_answer(const sdo::ServerFrame& f, TimePoint now) {
  if (stray_.count == 0 || now > stray_.until) return false;
  std::optional<cfg::ObjectAddress> named;
  if (const auto* r = std::get_if<sdo::InitiateUploadResponse>(&f)) named = r->address;
  if (const auto* r = std::get_if<sdo::InitiateDownloadResponse>(&f)) named = r->address;
  if (const auto* r = std::get_if<sdo::Abort>(&f)) named = r->address;
  if (!named || *named != stray_.address) return false;
  --stray_.count;
  return true;
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
  if (active_ && now >= active_->deadline) {
    fail(*active_, SdoAbort::Timeout, true, now, out);
  } else if (active_ && active_->repeat_at && now >= *active_->repeat_at) {
    repeat(*active_, now, out);
  }
  pump(now, out);
  sync_mux_deadline();
}

bool SdoClient::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!sdo::on_channel(frame, config_.response_cob_id)) return false;
  auto d = sdo::sdo_payload(frame);
  if (!d) return false;
  if (active_) handle(*active_, *d, now, out);
  pump(now, out);
  sync_mux_deadline();
  return true;
}

void SdoClient::start(Transfer& t, TimePoint now, Output& out) {
  t.toggle = false;
  t.offset = 0;
  t.size.reset();
  t.options.block_size = sdo::clamp_block_size(t.options.block_size);
  const cfg::ObjectAddress address{t.index, t.sub};
  if (!t.upload) {
    const auto size = t.data.size();  // fits 32 bits: check_start
    if (t.mode == SdoMode::Block) {
      t.protocol = SdoProtocol::Block;
      t.state = State::BlockDownloadInit;
      return send(t,
                  sdo::encode(sdo::BlockDownloadInitiateRequest{address, t.options.crc,
                                                                static_cast<std::uint32_t>(size)}),
                  now, out);
    }
    sdo::InitiateDownloadRequest r;
    r.address = address;
    r.size = static_cast<std::uint32_t>(size);
    t.state = State::InitiateDownload;
    if (t.mode == SdoMode::Auto && size >= 1 && size <= 4) {
      // CiA 301 download initiate: e=1, s=1, n = 4 - size.
      t.protocol = SdoProtocol::Expedited;
      r.expedited = true;
      std::copy(t.data.begin(), t.data.end(), r.data.begin());
    } else {
      t.protocol = SdoProtocol::Segmented;
    }
    send(t, sdo::encode(r), now, out);
    return arm_repeat(t, now);
  }
  t.data.clear();
  if (t.mode == SdoMode::Block) {
    t.protocol = SdoProtocol::Block;
    t.state = State::BlockUploadInit;
    return send(
        t,
        sdo::encode(sdo::BlockUploadInitiateRequest{address, t.options.crc, t.options.block_size,
                                                    t.options.protocol_switch_threshold}),
        now, out);
  }
  t.protocol = SdoProtocol::Segmented;  // until the server answers expedited
  t.state = State::InitiateUpload;
  send(t, sdo::encode(sdo::InitiateUploadRequest{address}), now, out);
  arm_repeat(t, now);
}

void SdoClient::send_download_segment(Transfer& t, TimePoint now, Output& out) {
  const std::size_t len = std::min(sdo::kSegmentBytes, t.data.size() - t.offset);
  sdo::DownloadSegmentRequest r;
  r.toggle = t.toggle;
  r.last = t.offset + len == t.data.size();
  r.size = static_cast<std::uint8_t>(len);
  std::copy_n(t.data.begin() + static_cast<std::ptrdiff_t>(t.offset), len, r.data.begin());
  t.state = State::DownloadSegment;
  send(t, sdo::encode(r), now, out);
}

void SdoClient::send_download_sub_block(Transfer& t, TimePoint now, Output& out) {
  const std::size_t first = out.frames.size();
  std::size_t pos = t.offset;
  t.sent_in_block = 0;
  t.block_has_last = false;
  for (std::uint8_t seq = 1; seq <= t.block_size; ++seq) {
    const std::size_t len = std::min(sdo::kSegmentBytes, t.data.size() - pos);
    sdo::BlockSegment segment;
    segment.last = pos + len == t.data.size();
    segment.seq = seq;
    std::copy_n(t.data.begin() + static_cast<std::ptrdiff_t>(pos), len, segment.data.begin());
    send(t, sdo::encode(segment), now, out);
    pos += len;
    t.sent_in_block = seq;
    if (segment.last) {
      t.block_has_last = true;
      break;
    }
  }
  // Only the sub-block's last segment is answered (the acknowledgement).
  std::uint64_t bits = 0;
  for (std::size_t i = first; i + 1 < out.frames.size(); ++i) {
    bits += frame_bits(out.frames[i]).total();
  }
  unanswered_bits_ += bits;
  if (mux_unanswered_bits_) *mux_unanswered_bits_ += bits;
  t.state = State::BlockDownload;
}

void SdoClient::handle(Transfer& t, const sdo::Payload& d, TimePoint now, Output& out) {
  if (t.state == State::BlockUpload) {
    // Inside a sub-block every frame is a segment, except an abort.
    const auto f = sdo::parse_sub_block_frame(d);
    if (const auto* segment = std::get_if<sdo::BlockSegment>(&f)) {
      return block_upload_segment(t, *segment, now, out);
    }
    return aborted(t, std::get<sdo::Abort>(f), now, out);
  }
  const auto f = sdo::parse_server_frame(d);
  if (!f) return fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
  if (const auto* a = std::get_if<sdo::Abort>(&*f)) {
    // The second abort of a repeated request of the transfer before: not this transfer's.
    if (a->address != cfg::ObjectAddress{t.index, t.sub} && stray_answer(*f, now)) return;
    return aborted(t, *a, now, out);
  }
  handle_response(t, *f, now, out);
}

void SdoClient::aborted(Transfer& t, const sdo::Abort& abort, TimePoint now, Output& out) {
  auto code = abort.code;
  if (code == SdoAbort::None) code = SdoAbort::General;  // 0 would read as success
  const bool block_init = t.state == State::BlockDownloadInit || t.state == State::BlockUploadInit;
  if (block_init && code == SdoAbort::InvalidCommandSpecifier && !t.fell_back) {
    // The server does not do block transfer: retry with expedited/segmented.
    t.fell_back = true;
    t.mode = SdoMode::Auto;
    return start(t, now, out);
  }
  finish(code, true, now, out);
}

// An initiate response that names another object than the transfer's is a late answer to an
// earlier request on the channel (one that timed out or was cancelled): it is ignored, and the
// transfer waits for its own answer (or its timeout).
void SdoClient::handle_response(Transfer& t, const sdo::ServerFrame& f, TimePoint now,
                                Output& out) {
  const cfg::ObjectAddress address{t.index, t.sub};
  const auto named = std::visit(
      [](const auto& frame) -> std::optional<cfg::ObjectAddress> {
        if constexpr (requires { frame.address; }) {
          return frame.address;
        } else {
          return std::nullopt;
        }
      },
      f);
  if (named && *named != address) return;
  switch (t.state) {
    case State::InitiateDownload: {
      const auto* r = std::get_if<sdo::InitiateDownloadResponse>(&f);
      if (r == nullptr) break;
      if (r->address != address) return fail(t, SdoAbort::General, true, now, out);
      note_answer(t, now);
      if (t.protocol == SdoProtocol::Expedited) return finish(SdoAbort::None, false, now, out);
      return send_download_segment(t, now, out);
    }

    case State::DownloadSegment: {
      const auto* r = std::get_if<sdo::DownloadSegmentResponse>(&f);
      if (r == nullptr) break;
      if (r->toggle != t.toggle) return fail(t, SdoAbort::ToggleBitNotAlternated, true, now, out);
      note_answer(t, now);
      t.offset += std::min(sdo::kSegmentBytes, t.data.size() - t.offset);
      if (t.offset == t.data.size()) return finish(SdoAbort::None, false, now, out);
      t.toggle = !t.toggle;
      return send_download_segment(t, now, out);
    }

    case State::BlockUploadInit:
      if (const auto* r = std::get_if<sdo::BlockUploadInitiateResponse>(&f)) {
        if (r->address != address) return fail(t, SdoAbort::General, true, now, out);
        t.crc = t.options.crc && r->crc;
        if (r->size) {
          t.size = *r->size;
          if (*t.size > t.options.max_size) return fail(t, SdoAbort::OutOfMemory, true, now, out);
        }
        t.block_size = t.options.block_size;
        t.ack_seq = 0;
        t.empty_rounds = 0;
        t.last_received = false;
        t.state = State::BlockUpload;
        return send(t, sdo::encode(sdo::BlockUploadStart{}), now, out);
      }
      // The server switched protocols (protocol switch threshold): a normal upload response.
      if (std::holds_alternative<sdo::InitiateUploadResponse>(f)) {
        t.protocol = SdoProtocol::Segmented;
      }
      [[fallthrough]];
    case State::InitiateUpload: {
      const auto* r = std::get_if<sdo::InitiateUploadResponse>(&f);
      if (r == nullptr) break;
      if (r->address != address) return fail(t, SdoAbort::General, true, now, out);
      note_answer(t, now);
      if (r->expedited) {
        const std::size_t size = r->size.value_or(4);
        t.data.assign(r->data.begin(), r->data.begin() + static_cast<std::ptrdiff_t>(size));
        t.protocol = SdoProtocol::Expedited;
        return finish(SdoAbort::None, false, now, out);
      }
      if (r->size) {
        t.size = *r->size;
        if (*t.size > t.options.max_size) return fail(t, SdoAbort::OutOfMemory, true, now, out);
        t.data.reserve(std::min<std::size_t>(*t.size, 1 << 16));
      }
      t.protocol = SdoProtocol::Segmented;
      t.toggle = false;
      t.state = State::UploadSegment;
      return send(t, sdo::encode(sdo::UploadSegmentRequest{false}), now, out);
    }

    case State::UploadSegment: {
      const auto* r = std::get_if<sdo::UploadSegmentResponse>(&f);
      if (r == nullptr) break;
      if (r->toggle != t.toggle) return fail(t, SdoAbort::ToggleBitNotAlternated, true, now, out);
      note_answer(t, now);
      if (t.data.size() + r->size > t.options.max_size) {
        return fail(t, SdoAbort::OutOfMemory, true, now, out);
      }
      t.data.insert(t.data.end(), r->data.begin(), r->data.begin() + r->size);
      if (t.size && t.data.size() > *t.size) {
        return fail(t, SdoAbort::LengthMismatch, true, now, out);
      }
      if (r->last) {
        if (t.size && t.data.size() != *t.size) {
          return fail(t, SdoAbort::LengthMismatch, true, now, out);
        }
        return finish(SdoAbort::None, false, now, out);
      }
      t.toggle = !t.toggle;
      return send(t, sdo::encode(sdo::UploadSegmentRequest{t.toggle}), now, out);
    }

    case State::BlockDownloadInit: {
      const auto* r = std::get_if<sdo::BlockDownloadInitiateResponse>(&f);
      if (r == nullptr) break;
      if (r->address != address) return fail(t, SdoAbort::General, true, now, out);
      if (!sdo::valid_block_size(r->block_size)) {
        return fail(t, SdoAbort::InvalidBlockSize, true, now, out);
      }
      t.crc = t.options.crc && r->crc;
      t.block_size = r->block_size;
      t.offset = 0;
      return send_download_sub_block(t, now, out);
    }

    case State::BlockDownload: {
      const auto* r = std::get_if<sdo::BlockDownloadAck>(&f);
      if (r == nullptr) break;
      if (r->ack_seq > t.sent_in_block) {
        return fail(t, SdoAbort::InvalidSequenceNumber, true, now, out);
      }
      if (!sdo::valid_block_size(r->block_size)) {
        return fail(t, SdoAbort::InvalidBlockSize, true, now, out);
      }
      t.offset = std::min(t.data.size(), t.offset + r->ack_seq * sdo::kSegmentBytes);
      t.block_size = r->block_size;
      if (r->ack_seq == t.sent_in_block && t.block_has_last) {
        // CiA 301 end block download: n and the CRC over the whole value.
        const std::uint16_t crc = t.crc ? sdo_block_crc(t.data) : 0;
        t.state = State::BlockDownloadEnd;
        return send(t,
                    sdo::encode(sdo::BlockDownloadEndRequest{
                        sdo::last_segment_empty_bytes(t.data.size()), crc}),
                    now, out);
      }
      // Resend from the segment after the last one acknowledged, numbering from 1 again. An
      // acknowledgement of no segment is no progress: the timeout keeps running (see
      // block_upload_segment).
      const auto deadline = t.deadline;
      send_download_sub_block(t, now, out);
      if (r->ack_seq == 0) t.deadline = deadline;
      return;
    }

    case State::BlockDownloadEnd:
      if (!std::holds_alternative<sdo::BlockDownloadEndResponse>(f)) break;
      return finish(SdoAbort::None, false, now, out);

    case State::BlockUploadEnd: {
      const auto* r = std::get_if<sdo::BlockUploadEndRequest>(&f);
      if (r == nullptr) break;
      if (r->empty_bytes > t.data.size()) return fail(t, SdoAbort::LengthMismatch, true, now, out);
      t.data.resize(t.data.size() - r->empty_bytes);
      if (t.size && t.data.size() != *t.size) {
        return fail(t, SdoAbort::LengthMismatch, true, now, out);
      }
      if (t.crc && sdo_block_crc(t.data) != r->crc) {
        return fail(t, SdoAbort::CrcError, true, now, out);
      }
      out.send(sdo::make_frame(config_.request_cob_id, sdo::encode(sdo::BlockUploadEndResponse{})));
      return finish(SdoAbort::None, false, now, out);
    }

    case State::BlockUpload:  // handled in handle()
      break;
  }
  // The server's answer to another copy of a repeated request, after one was taken.
  if (stray_answer(f, now)) return;
  fail(t, SdoAbort::InvalidCommandSpecifier, true, now, out);
}

void SdoClient::block_upload_segment(Transfer& t, const sdo::BlockSegment& f, TimePoint now,
                                     Output& out) {
  if (f.seq == 0 || f.seq > t.block_size) {
    return fail(t, SdoAbort::InvalidSequenceNumber, true, now, out);
  }
  if (f.seq == t.ack_seq + 1 && !t.last_received) {
    if (t.data.size() + sdo::kSegmentBytes > t.options.max_size + sdo::kSegmentBytes) {
      return fail(t, SdoAbort::OutOfMemory, true, now, out);
    }
    t.data.insert(t.data.end(), f.data.begin(), f.data.end());
    t.ack_seq = f.seq;
    t.last_received = f.last;
  }
  if (f.last || f.seq == t.block_size) {
    const sdo::BlockUploadAck ack{t.ack_seq, t.options.block_size};
    t.block_size = t.options.block_size;
    t.ack_seq = 0;
    if (t.last_received) t.state = State::BlockUploadEnd;
    if (ack.ack_seq != 0) {
      t.empty_rounds = 0;
      return send(t, sdo::encode(ack), now, out);
    }
    if (++t.empty_rounds >= sdo::kMaxEmptyBlockRounds) {
      return fail(t, SdoAbort::InvalidSequenceNumber, true, now, out);
    }
    // A sub-block with no segment in sequence brought nothing: the timeout keeps running.
    // Otherwise a server still in an earlier block download (the client's abort lost) and this
    // client acknowledge each other's acknowledgements for ever (A2h reads as c=1, seqno 34).
    out.send(sdo::make_frame(config_.request_cob_id, sdo::encode(ack)));
    return;
  }
  t.deadline = later(now, t.options.timeout);  // segments keep the transfer alive
}

// ===================================================================================== mux ==

SdoClient& SdoClientMux::client(cfg::NodeId node_id) {
  return add(SdoClientConfig::for_node(node_id));
}

SdoClient& SdoClientMux::add(SdoClientConfig config) {
  const auto key = cfg::CobId::of(config.response_cob_id.can_id()).word();
  auto& slot = clients_[key];
  if (!slot) {
    slot = std::make_unique<SdoClient>(config);
    slot->mux_unanswered_bits_ = unanswered_bits_.get();
    slot->mux_deadlines_ = deadlines_.get();
    slot->mux_key_ = key;
  }
  return *slot;
}

bool SdoClientMux::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto it = clients_.find(cfg::CobId::of({frame.id, frame.extended}).word());
  return it != clients_.end() && it->second->on_frame(frame, now, out);
}

void SdoClientMux::on_timer(TimePoint now, Output& out) {
  if (!deadlines_) return;  // a moved-from mux
  // Only the due clients, each once as the scan of all of them did, earliest first.
  due_.clear();
  deadlines_->due(now, due_);
  for (const auto key : due_) {
    auto& c = *clients_.at(key);
    if (auto t = c.next_deadline(); t && *t <= now) c.on_timer(now, out);
  }
}

std::optional<TimePoint> SdoClientMux::next_deadline() const {
  return deadlines_ ? deadlines_->earliest() : std::nullopt;  // null only in a moved-from mux
}

bool SdoClientMux::busy() const {
  return std::any_of(clients_.begin(), clients_.end(),
                     [](const auto& kv) { return kv.second->busy(); });
}

std::uint64_t SdoClientMux::unanswered_bits() const {
  return unanswered_bits_ ? *unanswered_bits_ : 0;  // null only in a moved-from mux
}

}  // namespace nmt
