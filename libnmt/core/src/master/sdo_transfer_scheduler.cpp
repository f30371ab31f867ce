// The NMT master's SDO transfer scheduler (sdo_transfer_scheduler.hpp): the boot's window, its
// bus-load pacing, the repetition after a timeout, the transfers held while the SDO manager gave
// a default SDO away, and the dispatch of results to their owners.
#include "master/sdo_transfer_scheduler.hpp"

#include <algorithm>
#include <bitset>
#include <cmath>
#include <utility>

#include "cfg/object_index.hpp"
#include "master/master_text.hpp"
#include "nmt/protocol/frame_bits.hpp"

namespace nmt {

SdoTransferScheduler::Settings SdoTransferScheduler::Settings::from(const MasterOptions& options) {
  return {.bitrate_bps = options.pacing.bitrate,
          .bus_load_limit = options.pacing.bus_load_limit,
          .sdo_timeout = options.sdo.timeout,
          .block_threshold = options.sdo.block_threshold,
          .repeat_floor = options.sdo.repeat_floor};
}

// CiA 301 leaves the SDO response timeout to the application (the client "may" abort), and
// CiA 302-2 §3.4/§3.5 bound a slave's boot by 1F89h boot time, not by a per-request time: a
// timeout long enough for the slowest device (500 ms) is the cost of every lost frame. A slave's
// own answer times say how long its answer takes under the present bus load: twice the largest
// of its last few is a margin a healthy slave keeps, the floor keeps a fast slave's jitter (a
// full bus, a busy device) from repeating what is only late, and the full timeout still decides
// failure, so a slave that slows down costs repeated frames, never a failed boot.
std::optional<Duration> SdoTransferScheduler::repeat_after(cfg::NodeId node,
                                                           Duration timeout) const {
  return repeat_from(answer_times_[node.value()], timeout);
}

std::optional<Duration> SdoTransferScheduler::unanswered_read_repeat_after(Duration timeout) const {
  return repeat_from(any_slave_answer_times_, timeout);
}

std::optional<Duration> SdoTransferScheduler::repeat_from(const AnswerTimes& times,
                                                          Duration timeout) const {
  if (times.count == 0) return std::nullopt;
  const Duration largest = *std::max_element(
      times.recent.begin(), times.recent.begin() + static_cast<std::ptrdiff_t>(times.count));
  const Duration after = std::max(2 * largest, settings_.repeat_floor);
  if (after >= timeout) return std::nullopt;
  return after;
}

SdoTransferScheduler::SdoTransferScheduler(SdoTransferPort& port, Settings settings)
    : port_(&port), settings_(settings) {}

// --- frames and time ---

bool SdoTransferScheduler::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  const bool mine = clients_.on_frame(frame, now, client_out_);
  take_frames(out);
  return mine;
}

void SdoTransferScheduler::on_timer(TimePoint now, Output& out) {
  clients_.on_timer(now, client_out_);
  take_frames(out);
}

std::optional<TimePoint> SdoTransferScheduler::next_deadline() const {
  auto due = clients_.next_deadline();
  if (!waiting_.empty() && static_cast<double>(boot_in_flight_) < std::floor(window_)) {
    due = earliest(due, paced_until_);
  }
  return due;
}

Duration SdoTransferScheduler::paced_time(double bits) const {
  const double seconds = bits / (static_cast<double>(settings_.bitrate_bps) *
                                 std::clamp(settings_.bus_load_limit, 0.05, 1.0));
  return Duration{static_cast<std::int64_t>(seconds * 1e6)};
}

void SdoTransferScheduler::pace_frame_of_others(const CanFrame& frame, TimePoint now) {
  // Only while the boot is paced (its next request waits); SDO responses on the default
  // channels (581h-5FFh) were counted with their requests.
  if (settings_.bitrate_bps == 0 || paced_until_ <= now || frame.error) return;
  if (!frame.extended && frame.id >= 0x581 && frame.id <= 0x5FF) return;
  paced_until_ += paced_time(frame_bits(frame).total());
}

void SdoTransferScheduler::take_frames(Output& out) {
  for (const auto& f : client_out_.frames) {
    // Each request and the answer it causes (taken to be as long), within the load limit.
    if (settings_.bitrate_bps != 0) unpaced_bits_ += 2.0 * frame_bits(f).total();
    ++unpaced_frames_;
    out.send(f);
  }
  client_out_.frames.clear();
}

// --- starting and ending ---

SdoTransferScheduler::Transfer SdoTransferScheduler::transfer(Owner owner, Request& request) const {
  Transfer t;
  t.owner = owner;
  t.object = request.object;
  t.upload = request.upload;
  t.data = std::move(request.data);
  t.options.timeout = request.timeout;
  t.retries_left = request.retries;
  return t;
}

void SdoTransferScheduler::start_boot(std::uint64_t try_id, Request request, TimePoint now,
                                      Output& out) {
  auto t = transfer(BootTry{try_id}, request);
  // Large values by block transfer; SdoClient falls back to segmented when refused.
  if (t.data.size() > settings_.block_threshold) t.options.mode = SdoMode::Block;
  schedule(request.node, std::move(t), now, out);
}

cfg::Result<SdoClient::TransferId> SdoTransferScheduler::start_application(
    cfg::NodeId node, cfg::ObjectAddress object, bool upload, std::vector<std::uint8_t> data,
    TimePoint now, Output& out) {
  Request request{.node = node, .object = object, .upload = upload, .data = std::move(data)};
  request.timeout = settings_.sdo_timeout;
  auto t = transfer(Application{0}, request);
  if (t.data.size() > settings_.block_threshold) t.options.mode = SdoMode::Block;
  // Checked now, not when the client gets it: it may wait behind the boot's transfers.
  if (auto ok = SdoClient::check_start(
          t.options, upload ? std::nullopt : std::optional<std::size_t>(t.data.size()));
      !ok) {
    return cfg::Error{node_text(node) + ": " + ok.error().message};
  }
  const auto id = next_application_id_++;  // only a transfer that starts uses up an id
  t.owner = Application{id};
  schedule(node, std::move(t), now, out);
  return id;
}

void SdoTransferScheduler::start_manager(std::uint64_t tag, Request request, TimePoint now,
                                         Output& out) {
  schedule(request.node, transfer(Manager{tag}, request), now, out);
}

void SdoTransferScheduler::schedule(cfg::NodeId node, Transfer transfer, TimePoint now,
                                    Output& out) {
  // DSP 302 §7.1: the manager "manages all SDO connections"; a default SDO it gave to an SRD is
  // the SRD's until released, and a second client on it would collide with the SRD's.
  if (!std::holds_alternative<Manager>(transfer.owner) && port_->default_sdo_given_out(node)) {
    held_.emplace_back(node, std::move(transfer));
    return;
  }
  // Boot transfers beyond the window, before the pacing allows, or behind others that wait,
  // wait too (pump), in order.
  if (is_boot(transfer) && (static_cast<double>(boot_in_flight_) >= std::floor(window_) ||
                            now < paced_until_ || !waiting_.empty())) {
    waiting_.emplace_back(node, std::move(transfer));
    return;
  }
  launch(node, std::move(transfer), now, out);
}

void SdoTransferScheduler::launch(cfg::NodeId node, Transfer transfer, TimePoint now, Output& out) {
  if (is_boot(transfer)) {
    ++boot_in_flight_;
    if (answer_times_[node.value()].count > 0) {
      transfer.options.repeat_after = repeat_after(node, transfer.options.timeout);
    } else if (transfer.upload && port_->heard_from(node)) {
      transfer.options.repeat_after = unanswered_read_repeat_after(transfer.options.timeout);
    }
  }
  transfer.launched = now;
  auto& client = clients_.client(node);
  const auto [index, sub] = transfer.object;
  const auto id = transfer.upload ? client.upload(index, sub, now, client_out_, transfer.options)
                                  : client.download(index, sub, transfer.data, now, client_out_,
                                                    transfer.options);
  take_frames(out);
  if (!id) {
    // A boot or manager transfer the client refuses (SdoClient::check_start: after
    // MasterOptions::validate only a download longer than 4 GiB; application transfers were
    // checked before they were queued). It ends at once with the client's words, and its owner
    // sees the failure when it is dispatched; no abort code, as none was on the bus.
    SdoResult r;
    r.id = next_refused_id_--;
    r.node_id = node;
    r.address = transfer.object;
    r.upload = transfer.upload;
    r.started = now;
    r.finished = now;
    r.refusal = id.error().message;
    transfers_[{node, r.id}] = std::move(transfer);
    results_.push_back(std::move(r));
    return;
  }
  transfers_[{node, *id}] = std::move(transfer);
}

void SdoTransferScheduler::forget(std::map<Key, Transfer>::iterator it) {
  if (is_boot(it->second)) --boot_in_flight_;
  transfers_.erase(it);
}

template <class O>
void SdoTransferScheduler::cancel_of(cfg::NodeId node, TimePoint now, Output& out) {
  // By client id, the order they started in: the one a cancel ends on the bus lets its client
  // start the next queued, which may be of the same owner and end next.
  for (auto it = transfers_.lower_bound({node, 0});
       it != transfers_.end() && it->first.first == node;) {
    if (std::holds_alternative<O>(it->second.owner)) {
      const auto id = it->first.second;
      forget(it++);
      clients_.client(node).cancel(id, now, client_out_);
    } else {
      ++it;
    }
  }
  take_frames(out);
}

void SdoTransferScheduler::cancel_boot(cfg::NodeId node, TimePoint now, Output& out) {
  done_[node.value()] = 0;  // a new try (or none) follows
  // CiA 302-2 §3.3: the boot of a slave "shall run asynchronously to other processes", and DSP
  // 302 §7.1: the SDO manager "manages all SDO connections" with accesses of its own. A boot
  // try's end is not theirs: the manager waits for each of its results (one access at a time),
  // and one never delivered would stop its jobs for good.
  cancel_of<BootTry>(node, now, out);
}

void SdoTransferScheduler::cancel_manager(cfg::NodeId node, TimePoint now, Output& out) {
  cancel_of<Manager>(node, now, out);
}

// --- settling ---

bool SdoTransferScheduler::collect(TimePoint now) {
  if (unpaced_frames_ > 0 && settings_.bitrate_bps != 0) {
    // The segments of a block download sub-block but its last cause no answer (booking an
    // answer for each booked a program image twice its air time).
    double bits = unpaced_bits_;
    const std::uint64_t unanswered = clients_.unanswered_bits();
    bits -= static_cast<double>(unanswered - unanswered_bits_paced_);
    unanswered_bits_paced_ = unanswered;
    paced_until_ = std::max(paced_until_, now) + paced_time(std::max(bits, 0.0));
  }
  unpaced_frames_ = 0;
  unpaced_bits_ = 0;
  for (auto& r : client_out_.events) results_.push_back(std::move(r));
  client_out_.events.clear();
  return !results_.empty();
}

bool SdoTransferScheduler::dispatch_next(TimePoint now, Output& out) {
  if (results_.empty()) return false;
  const SdoResult r = std::move(results_.front());
  results_.pop_front();
  dispatch(r, now, out);
  return true;
}

void SdoTransferScheduler::dispatch(const SdoResult& result, TimePoint now, Output& out) {
  if (!result.node_id) return;  // the scheduler's clients are all for_node
  const cfg::NodeId node = *result.node_id;
  if (result.longest_answer) {
    // Any owner's answer tells the slave's answer time.
    for (AnswerTimes* times : {&answer_times_[node.value()], &any_slave_answer_times_}) {
      times->recent[times->next] = *result.longest_answer;
      times->next = (times->next + 1) % kAnswerWindow;
      times->count = std::min(times->count + 1, kAnswerWindow);
    }
  }
  const auto it = transfers_.find({node, result.id});
  if (it == transfers_.end()) return;  // cancelled
  Transfer transfer = std::move(it->second);
  forget(it);
  const bool boot = is_boot(transfer);
  // Every boot transfer started is of its node's current try: the try's end cancels them.
  if (boot) ++done_[node.value()];
  const bool timed_out = result.abort == SdoAbort::Timeout && !result.aborted_by_server;
  if (boot) {
    // The window of boot transfers in flight, grown by one per window's worth of answers. Paced
    // (bit rate known), the pacing keeps the bus below its load limit, so a response that does
    // not come was lost or is slow: its transfer pays one timeout and is repeated, the others
    // keep their places. Unpaced, the window is the only brake on a bus so full that the
    // highest identifiers (heartbeats, and answers a device queues behind them) starve: it
    // halves once per loss event, not again for the transfers launched before the last cut.
    if (timed_out) {
      if (settings_.bitrate_bps == 0 && (!window_cut_ || transfer.launched >= *window_cut_)) {
        window_ = std::max(1.0, window_ / 2);
        window_cut_ = now;
      }
    } else {
      window_ = std::min(kMaxWindow, window_ + 1.0 / window_);
    }
  }
  // A timeout the client detected is most likely a lost frame: repeat the transfer.
  if (timed_out && transfer.retries_left > 0) {
    --transfer.retries_left;
    schedule(node, std::move(transfer), now, out);
    return;
  }
  if (const auto* b = std::get_if<BootTry>(&transfer.owner)) {
    if (!port_->boot_try_runs(node, b->try_id)) return;  // of an ended try
    if (result.ok() && !transfer.upload && transfer.object.index == cfg::object::kProgramData &&
        transfer.reported < transfer.data.size()) {
      // The last segment's confirmation ends a segmented download at once (a block download's
      // last sub-block is acknowledged before its end): 100% is reported here, once.
      out.report(ProgramProgress{node, transfer.data.size(), transfer.data.size()});
    }
  }
  out.report(Finished{node, transfer.owner, result});
}

void SdoTransferScheduler::release_held(TimePoint now, Output& out) {
  for (std::size_t i = 0; i < held_.size();) {
    if (port_->default_sdo_given_out(held_[i].first)) {
      ++i;
      continue;
    }
    auto [node, transfer] = std::move(held_[i]);
    held_.erase(held_.begin() + static_cast<std::ptrdiff_t>(i));
    const auto* b = std::get_if<BootTry>(&transfer.owner);
    if (b != nullptr && !port_->boot_try_runs(node, b->try_id)) continue;
    schedule(node, std::move(transfer), now, out);
  }
}

void SdoTransferScheduler::pump(TimePoint now, Output& out) {
  while (!waiting_.empty() && static_cast<double>(boot_in_flight_) < std::floor(window_) &&
         now >= paced_until_) {
    // The slave whose try is furthest behind goes first (each slave's own transfers in order):
    // a slave that lost a frame waited one timeout and catches up while the bus is full,
    // instead of ending its boot alone after the others.
    auto pick = waiting_.begin();
    std::bitset<128> seen;
    for (auto it = waiting_.begin(); it != waiting_.end(); ++it) {
      if (seen[it->first.value()]) continue;
      seen[it->first.value()] = true;
      if (done_[it->first.value()] < done_[pick->first.value()]) pick = it;
    }
    auto [node, transfer] = std::move(*pick);
    waiting_.erase(pick);
    if (!port_->boot_try_runs(node, std::get<BootTry>(transfer.owner).try_id)) continue;
    launch(node, std::move(transfer), now, out);
    if (settings_.bitrate_bps != 0) return;  // the next round paces the next after counting
  }
}

void SdoTransferScheduler::report_progress(Output& out) {
  // The 1F50h download (DSP 302 §9) as the client has it confirmed.
  for (auto& [key, t] : transfers_) {
    if (!is_boot(t) || t.upload || t.object.index != cfg::object::kProgramData) continue;
    const auto p = clients_.client(key.first).download_progress();
    if (!p || p->id != key.second || p->done <= t.reported) continue;
    if (p->done < p->total && p->done - t.reported < std::max<std::size_t>(p->total / 32, 1)) {
      continue;
    }
    t.reported = p->done;
    out.report(ProgramProgress{key.first, p->done, p->total});
  }
}

}  // namespace nmt
