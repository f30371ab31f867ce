// The SDO transfers of NmtMaster: those of the boot (windowed and paced, repeated after a
// timeout) and those of the application, and settle(), which after every call dispatches their
// results, moves their frames out, sends due NMT commands and moves start-up on.
#include <algorithm>
#include <bitset>
#include <cmath>
#include <utility>

#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"
#include "nmt/frame_bits.hpp"

namespace nmt {

namespace {

// MasterEvent::ProgramProgress: `done` of the 1F50h image's `total` bytes confirmed.
MasterEvent program_progress(cfg::NodeId node, std::size_t done, std::size_t total, TimePoint now) {
  auto e = master_event(MasterEvent::Kind::ProgramProgress, now, node);
  e.step = BootStep::UpdateSoftware;
  e.bytes = done;
  e.total = total;
  return e;
}

}  // namespace

Duration NmtMaster::Impl::paced_time(double bits) const {
  const double seconds =
      bits / (static_cast<double>(options.bitrate) * std::clamp(options.bus_load_limit, 0.05, 1.0));
  return Duration{static_cast<std::int64_t>(seconds * 1e6)};
}

void NmtMaster::Impl::pace_frame_of_others(const CanFrame& frame, TimePoint now) {
  // Only while the boot is paced (its next request waits); SDO responses on the default
  // channels (581h-5FFh) were counted with their requests.
  if (options.bitrate == 0 || paced_until <= now || frame.error) return;
  if (!frame.extended && frame.id >= 0x581 && frame.id <= 0x5FF) return;
  paced_until += paced_time(frame_bits(frame).total());
}

SdoClient::TransferId NmtMaster::Impl::start_transfer(cfg::NodeId node, MasterTransfer transfer,
                                                      TimePoint now) {
  // DSP 302 §7.1: the manager "manages all SDO connections"; a default SDO it gave to an SRD is
  // the SRD's until released, and a second client on it would collide with the SRD's.
  if (!transfer.for_manager && sdo_manager.default_sdo_given_out(node)) {
    held.emplace_back(node, std::move(transfer));
    return 0;
  }
  // Boot transfers beyond the window, before the pacing allows, or behind others that wait,
  // wait too (pump_transfers), in order.
  if (!transfer.for_application && !transfer.for_manager &&
      (static_cast<double>(boot_transfers) >= std::floor(window) || now < paced_until ||
       !waiting.empty())) {
    waiting.emplace_back(node, std::move(transfer));
    return 0;
  }
  return launch_transfer(node, std::move(transfer), now);
}

SdoClient::TransferId NmtMaster::Impl::launch_transfer(cfg::NodeId node, MasterTransfer transfer,
                                                       TimePoint now) {
  if (!transfer.for_application && !transfer.for_manager) ++boot_transfers;
  transfer.launched = now;
  auto& client = clients.client(node);
  const auto [index, sub] = transfer.object;
  const auto id = transfer.upload
                      ? client.upload(index, sub, now, sdo_out, transfer.options)
                      : client.download(index, sub, transfer.data, now, sdo_out, transfer.options);
  if (!id) {
    // A boot or manager transfer the client refuses (SdoClient::check_start: after
    // MasterOptions::validate only a download longer than 4 GiB; application transfers were
    // checked before they were queued). It ends at once with the client's words, and its
    // process sees the failure when settle dispatches it; no abort code, as none was on the bus.
    SdoResult r;
    r.id = next_refused_id--;
    r.node_id = node;
    r.address = transfer.object;
    r.upload = transfer.upload;
    r.started = now;
    r.finished = now;
    r.refusal = id.error().message;
    transfers[{node, r.id}] = std::move(transfer);
    results.push_back(std::move(r));
    return 0;
  }
  transfers[{node, *id}] = std::move(transfer);
  return *id;
}

void NmtMaster::Impl::forget_transfer(
    std::map<std::pair<cfg::NodeId, SdoClient::TransferId>, MasterTransfer>::iterator it) {
  if (!it->second.for_application && !it->second.for_manager) --boot_transfers;
  transfers.erase(it);
}

void NmtMaster::Impl::pump_transfers(TimePoint now) {
  while (!waiting.empty() && static_cast<double>(boot_transfers) < std::floor(window) &&
         now >= paced_until) {
    // The slave whose try is furthest behind goes first (each slave's own transfers in order):
    // a slave that lost a frame waited one timeout and catches up while the bus is full,
    // instead of ending its boot alone after the others.
    auto pick = waiting.begin();
    std::bitset<128> seen;
    for (auto it = waiting.begin(); it != waiting.end(); ++it) {
      if (seen[it->first]) continue;
      seen[it->first] = true;
      if (slaves[it->first].transfers_done < slaves[pick->first].transfers_done) pick = it;
    }
    auto [node, transfer] = std::move(*pick);
    waiting.erase(pick);
    const auto& b = boot(node);
    if (!b.running() || transfer.try_id != b.try_id()) continue;  // its try ended meanwhile
    launch_transfer(node, std::move(transfer), now);
    if (options.bitrate != 0) return;  // settle() paces the next one after counting its frames
  }
}

void NmtMaster::Impl::release_held(TimePoint now) {
  for (std::size_t i = 0; i < held.size();) {
    if (sdo_manager.default_sdo_given_out(held[i].first)) {
      ++i;
      continue;
    }
    auto [node, transfer] = std::move(held[i]);
    held.erase(held.begin() + static_cast<std::ptrdiff_t>(i));
    const auto& b = boot(node);
    if (!transfer.for_application && (!b.running() || transfer.try_id != b.try_id())) continue;
    start_transfer(node, std::move(transfer), now);
  }
}

void NmtMaster::Impl::dispatch(const SdoResult& result, TimePoint now, Output& out) {
  if (!result.node_id) return;  // the master's clients are all for_node
  const cfg::NodeId node = *result.node_id;
  const auto it = transfers.find({node, result.id});
  if (it == transfers.end()) return;  // cancelled, or of an older boot try
  MasterTransfer transfer = std::move(it->second);
  forget_transfer(it);
  if (!transfer.for_application && !transfer.for_manager &&
      transfer.try_id == boot(node).try_id()) {
    ++slaves[node].transfers_done;
  }
  const bool timed_out = result.abort == SdoAbort::Timeout && !result.aborted_by_server;
  if (!transfer.for_application && !transfer.for_manager) {
    // The window of boot transfers in flight, grown by one per window's worth of answers. Paced
    // (bit rate known), the pacing keeps the bus below its load limit, so a response that does
    // not come was lost or is slow: its transfer pays one timeout and is repeated, the others
    // keep their places. Unpaced, the window is the only brake on a bus so full that the
    // highest identifiers (heartbeats, and answers a device queues behind them) starve: it
    // halves once per loss event, not again for the transfers launched before the last cut.
    if (timed_out) {
      if (options.bitrate == 0 && (!window_cut || transfer.launched >= *window_cut)) {
        window = std::max(1.0, window / 2);
        window_cut = now;
      }
    } else {
      window = std::min(kMaxWindow, window + 1.0 / window);
    }
  }
  // A timeout the client detected is most likely a lost frame: repeat the transfer.
  if (timed_out && transfer.retries_left > 0) {
    --transfer.retries_left;
    start_transfer(node, std::move(transfer), now);
    return;
  }
  if (transfer.for_manager) {
    sdo_manager.on_transfer_result(transfer.try_id, result, now, out);
    return;
  }
  if (transfer.for_application) {
    auto e = master_event(MasterEvent::Kind::SdoFinished, now, node);
    e.sdo = result;
    e.sdo->id = transfer.application_id;
    report(out, std::move(e));
    return;
  }
  auto& b = boot(node);
  if (!b.running() || transfer.try_id != b.try_id()) return;
  if (result.ok() && !transfer.upload && transfer.object.index == cfg::object::kProgramData &&
      transfer.reported < transfer.data.size()) {
    // The last segment's confirmation ends a segmented download at once (a block download's
    // last sub-block is acknowledged before its end): 100% is reported here, once.
    report(out, program_progress(node, transfer.data.size(), transfer.data.size(), now));
  }
  b.on_sdo_result(result, now, out);
  track_boot_deadline(node);
}

void NmtMaster::Impl::report_program_progress(TimePoint now, Output& out) {
  // The software update's 1F50h download (DSP 302 §9) as the client has it confirmed, for the
  // live view: about every 1/32 of the image, so a 256 KiB image gives some 32 events.
  for (auto& [key, t] : transfers) {
    if (t.for_application || t.for_manager || t.upload ||
        t.object.index != cfg::object::kProgramData) {
      continue;
    }
    const auto p = clients.client(key.first).download_progress();
    if (!p || p->id != key.second || p->done <= t.reported) continue;
    if (p->done < p->total && p->done - t.reported < std::max<std::size_t>(p->total / 32, 1)) {
      continue;
    }
    t.reported = p->done;
    report(out, program_progress(key.first, p->done, p->total, now));
  }
}

void NmtMaster::Impl::settle(TimePoint now, Output& out) {
  // The call's SDO requests stay in sdo_out until the end: the NMT commands of the call (each
  // round's flush_nmt) go out ahead of them, by output order (§6.1 queue, nmt_command_queue.hpp).
  std::size_t counted = 0;  // sdo_out frames the pacing has counted
  for (;;) {
    if (options.bitrate != 0 && sdo_out.frames.size() > counted) {
      // Each request and the answer it causes (taken to be as long), within the load limit;
      // the segments of a block download sub-block but its last cause none (booking an answer
      // for each booked a program image twice its air time).
      double bits = 0;
      for (std::size_t i = counted; i < sdo_out.frames.size(); ++i) {
        bits += 2.0 * frame_bits(sdo_out.frames[i]).total();
      }
      const std::uint64_t unanswered = clients.unanswered_bits();
      bits -= static_cast<double>(unanswered - unanswered_bits_paced);
      unanswered_bits_paced = unanswered;
      paced_until = std::max(paced_until, now) + paced_time(std::max(bits, 0.0));
    }
    counted = sdo_out.frames.size();
    for (auto& r : sdo_out.events) results.push_back(std::move(r));
    sdo_out.events.clear();
    if (!results.empty()) {
      while (!results.empty()) {
        const SdoResult r = std::move(results.front());
        results.pop_front();
        dispatch(r, now, out);
      }
      continue;
    }
    release_held(now);
    pump_transfers(now);
    sdo_manager.pump(now, out);
    if (startup == StartupState::BootingSlaves) check_startup(now, out);
    flush_nmt(now, out);
    if (sdo_out.events.empty() && sdo_out.frames.size() == counted) break;
  }
  report_program_progress(now, out);
  for (const auto& f : sdo_out.frames) out.send(f);
  sdo_out.frames.clear();
  // Node guarding started in this call (boot's start error control, the SDO manager's watch,
  // request node guarding) has its first request due at `now` (NodeGuardingMaster::guard): the
  // error control service sends it here, last, after the call's NMT commands and SDO requests,
  // where it has always gone: a slave that boot starts is started before its first guarding
  // request, so its first reply says operational (CiA 302-2 §3.4 part 3 e before g-l). (A request
  // that fell due before on_timer came goes with it: engine.hpp rule 3.)
  error_control_out.clear();
  error_control.send_due_requests(now, error_control_out);
  dispatch_error_control(now, out);
}

}  // namespace nmt
