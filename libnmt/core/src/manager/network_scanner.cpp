#include "nmt/manager/network_scanner.hpp"

#include <algorithm>
#include <string>
#include <utility>

#include "cfg/bytes.hpp"
#include "nmt/protocol/error_control.hpp"
#include "nmt/protocol/frame_bits.hpp"

namespace nmt {
namespace {

// CiA 301 §7.3.5 pre-defined connection set.
constexpr std::uint32_t kSdoResponseBase = 0x580;  // default SDO server -> client
constexpr std::uint32_t kSdoRequestBase = 0x600;   // default SDO client -> server

constexpr cfg::ObjectAddress kDeviceType{0x1000, 0};
constexpr std::uint16_t kIdentity = 0x1018;
constexpr cfg::ObjectAddress kStoredEds{0x1021, 0};
constexpr cfg::ObjectAddress kStorageFormat{0x1022, 0};
// CiA 301 §7.5.2.21: storage format 0 is ISO 10646, not compressed: the EDS text itself.
constexpr std::uint16_t kStorageUncompressed = 0;

bool in_range(const CanFrame& frame, std::uint32_t base) {
  return !frame.extended && !frame.rtr && frame.id > base && frame.id <= base + 0x7F;
}

}  // namespace

NetworkScanner::NetworkScanner(ScanOptions options) : options_(options) {}

NetworkScanner::Node& NetworkScanner::node(cfg::NodeId id) {
  return nodes_.try_emplace(id.value(), Node{.id = id}).first->second;
}

void NetworkScanner::probe(Node& n) {
  n.phase = Phase::Probe;
  n.absent = false;
  n.todo.clear();
  n.todo.push_back({kDeviceType, Purpose::Probe});
  ++pending_;
  make_ready(n);
}

void NetworkScanner::make_ready(Node& n) {
  if (n.queued || n.running || n.todo.empty()) return;
  n.queued = true;
  ready_.push_back(n.id.value());
}

void NetworkScanner::start(std::span<const cfg::NodeId> nodes, TimePoint now, Output& out) {
  sdo_.clear();
  for (const cfg::NodeId id : nodes) {
    if (nodes_.contains(id.value())) continue;
    probe(node(id));
  }
  take(now, out);
}

cfg::Status NetworkScanner::read(cfg::NodeId id, std::vector<cfg::ObjectAddress> entries,
                                 TimePoint now, Output& out) {
  const auto it = nodes_.find(id.value());
  if (it == nodes_.end() || it->second.phase != Phase::AwaitingEntries) {
    return cfg::Error{"node " + std::to_string(id.value()) +
                      " is not a device the scan found and waits for its entries"};
  }
  Node& n = it->second;
  n.phase = Phase::Entries;
  for (const auto& address : entries) n.todo.push_back({address, Purpose::Entry});
  sdo_.clear();
  advance(n, now, out);
  take(now, out);
  return {};
}

bool NetworkScanner::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (options_.bitrate_bps != 0 && paced_until_ > now && !frame.error &&
      !in_range(frame, kSdoResponseBase) && !in_range(frame, kSdoRequestBase)) {
    // A frame of another node while a request waits: it took bus time the pacing must leave.
    // The answers to the requests (and the requests as the driver echoes them) were counted
    // when the requests went out.
    paced_until_ += paced_time(frame_bits(frame).total());
  }
  if (const auto message = parse_error_control(frame)) {
    // CiA 301 §7.2.8.3.2: a heartbeat or boot-up: a device is at this node-ID.
    if (const auto it = nodes_.find(message->node_id.value()); it != nodes_.end()) {
      Node& n = it->second;
      const bool first = !n.heard;
      n.heard = true;
      // Once: a device whose SDO server never answers must not keep the scan going.
      if (n.absent && first) {
        probe(n);
        sdo_.clear();
        take(now, out);
      }
    }
    return false;
  }
  sdo_.clear();
  const bool mine = mux_.on_frame(frame, now, sdo_);
  if (mine) take(now, out);
  return mine;
}

void NetworkScanner::on_timer(TimePoint now, Output& out) {
  sdo_.clear();
  mux_.on_timer(now, sdo_);
  take(now, out);
}

std::optional<TimePoint> NetworkScanner::next_deadline() const {
  auto due = mux_.next_deadline();
  if (!ready_.empty()) due = earliest(due, paced_until_);
  return due;
}

Duration NetworkScanner::paced_time(double bits) const {
  const double seconds = bits / (static_cast<double>(options_.bitrate_bps) *
                                 std::clamp(options_.bus_load_limit, 0.05, 1.0));
  return Duration{static_cast<std::int64_t>(seconds * 1e6)};
}

SdoTransferOptions NetworkScanner::options_for(Purpose purpose) const {
  SdoTransferOptions o = options_.sdo;
  // An EDS is kilobytes: a block upload takes about half the frames of a segmented one
  // (CiA 301 §7.2.4.3.14); the client falls back when the server has no block transfer.
  if (purpose == Purpose::StoredEds) o.mode = SdoMode::Block;
  return o;
}

void NetworkScanner::pump(TimePoint now) {
  std::size_t counted = sdo_.frames.size();
  auto count_new_frames = [&] {
    if (options_.bitrate_bps == 0) return;
    for (; counted < sdo_.frames.size(); ++counted) {
      // The request and the answer it asks for, both at the request's length (SDO frames
      // have 8 data bytes both ways).
      const double bits = 2.0 * frame_bits(sdo_.frames[counted]).total();
      paced_until_ = std::max(paced_until_, now) + paced_time(bits);
    }
  };
  count_new_frames();  // segment requests and aborts the clients sent in this call
  while (!ready_.empty() && paced(now)) {
    Node& n = nodes_.at(ready_.front());
    ready_.pop_front();
    n.queued = false;
    if (n.running || n.todo.empty()) continue;
    Upload upload = n.todo.front();
    n.todo.pop_front();
    const auto id = mux_.client(n.id).upload(upload.address.index, upload.address.sub_index, now,
                                             sdo_, options_for(upload.purpose));
    if (!n.began) n.began = now;
    if (!id) {
      // SdoClient::check_start refuses only a timeout that is not positive: the entry is one
      // whose answer did not come, without a retry.
      SdoResult refused;
      refused.abort = SdoAbort::Timeout;
      refused.node_id = n.id;
      refused.address = upload.address;
      upload.attempts = options_.retries + 1;
      sdo_.events.push_back(std::move(refused));
      n.running = upload;
      n.transfer = 0;
      continue;
    }
    n.running = upload;
    n.transfer = *id;
    count_new_frames();
  }
}

void NetworkScanner::take(TimePoint now, Output& out) {
  // Results first (they may queue the next upload of their node), then what may start; until a
  // round brings no result.
  for (;;) {
    pump(now);
    if (sdo_.events.empty()) break;
    std::vector<SdoResult> results = std::move(sdo_.events);
    sdo_.events.clear();
    for (auto& result : results) {
      if (!result.node_id) continue;  // the mux's clients are all for_node
      const auto it = nodes_.find(result.node_id->value());
      if (it == nodes_.end() || !it->second.running || it->second.transfer != result.id) continue;
      Node& n = it->second;
      Upload upload = *n.running;
      n.running.reset();
      finished_upload(n, upload, std::move(result), now, out);
    }
  }
  for (const auto& f : sdo_.frames) out.send(f);
  sdo_.frames.clear();
}

void NetworkScanner::finished_upload(Node& n, Upload upload, SdoResult result, TimePoint now,
                                     Output& out) {
  const bool timed_out = result.abort == SdoAbort::Timeout && !result.aborted_by_server;
  if (timed_out) {
    // Repetitions: of a probe, probe_retries for any node-ID and retries for one the bus
    // showed alive; of the other uploads, retries (the device answered the probe).
    const unsigned allowed = upload.purpose == Purpose::Probe
                                 ? (n.heard ? std::max(options_.retries, options_.probe_retries)
                                            : options_.probe_retries)
                                 : (n.answered ? options_.retries : 0);
    if (upload.attempts <= allowed) {
      ++upload.attempts;
      n.todo.push_front(upload);
      make_ready(n);
      return;
    }
  } else {
    n.answered = true;
  }
  const bool ok = result.ok();
  switch (upload.purpose) {
    case Purpose::Probe:
      if (timed_out) {
        n.absent = true;
        n.phase = Phase::Done;
        --pending_;
        out.report(NodeAbsent{n.id});
        return;
      }
      n.found = NodeFound{.node = n.id};
      if (ok) {
        n.found.identity.device_type = cfg::low_le32(result.data);
      } else {
        ++n.found.skipped;
      }
      n.phase = Phase::Identity;
      for (std::uint8_t sub = 1; sub <= 4; ++sub) {
        n.todo.push_back({{kIdentity, sub}, Purpose::Identity});
      }
      break;
    case Purpose::Identity: {
      if (!ok) {
        ++n.found.skipped;
        break;
      }
      const std::uint32_t value = cfg::low_le32(result.data);
      auto& id = n.found.identity;
      std::optional<std::uint32_t>* field[] = {&id.vendor_id, &id.product_code, &id.revision_number,
                                               &id.serial_number};
      *field[upload.address.sub_index - 1] = value;
      break;
    }
    case Purpose::StoredEdsFormat:
      if (ok) {
        n.found.stored_eds_format = static_cast<std::uint16_t>(cfg::low_le32(result.data));
        if (*n.found.stored_eds_format == kStorageUncompressed) {
          n.todo.push_back({kStoredEds, Purpose::StoredEds});
        }
      }
      break;
    case Purpose::StoredEds:
      if (ok) n.found.stored_eds = std::move(result.data);
      break;
    case Purpose::Entry:
      ok ? ++n.read : ++n.skipped;
      out.report(EntryRead{.node = n.id,
                           .address = upload.address,
                           .data = ok ? std::move(result.data) : std::vector<std::uint8_t>{},
                           .abort = ok ? SdoAbort::None : result.abort,
                           .attempts = upload.attempts});
      break;
  }
  advance(n, now, out);
}

void NetworkScanner::advance(Node& n, TimePoint now, Output& out) {
  if (!n.todo.empty()) {
    make_ready(n);
    return;
  }
  switch (n.phase) {
    case Phase::Identity:
      if (options_.read_stored_eds) {
        n.phase = Phase::StoredEds;
        n.todo.push_back({kStorageFormat, Purpose::StoredEdsFormat});
        make_ready(n);
        return;
      }
      [[fallthrough]];
    case Phase::StoredEds:
      n.phase = Phase::AwaitingEntries;
      out.report(n.found);
      return;
    case Phase::Entries:
      n.phase = Phase::Done;
      --pending_;
      out.report(NodeScanned{.node = n.id,
                             .read = n.read,
                             .skipped = n.skipped,
                             .took = n.began ? now - *n.began : Duration{0}});
      return;
    case Phase::Probe:
    case Phase::AwaitingEntries:
    case Phase::Done:
      return;
  }
}

}  // namespace nmt
