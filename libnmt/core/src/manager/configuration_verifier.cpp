#include "nmt/manager/configuration_verifier.hpp"

#include <map>

#include "cfg/object_address.hpp"
#include "nmt/protocol/error_control.hpp"

namespace nmt {
namespace {

std::uint64_t key(cfg::NodeId node, SdoClient::TransferId id) {
  return std::uint64_t{node.value()} << 32 | id;
}

}  // namespace

void ConfigurationVerifier::upload(VerifyResult result, TimePoint now, Outbox<SdoResult>& sdo,
                                   Output& out) {
  const auto node = result.node_id;
  const auto id = mux_.client(node).upload(result.address.index, result.address.sub_index, now, sdo,
                                           options_.sdo);
  if (!id) {
    // SdoClient::check_start refuses an upload only for a timeout that is not positive: the
    // entry is reported as one whose answer did not come.
    result.abort = SdoAbort::Timeout;
    out.report(std::move(result));
    return;
  }
  running_.insert_or_assign(key(node, *id), Running{std::move(result)});
}

void ConfigurationVerifier::verify(cfg::NodeId node, std::span<const cfg::ObjectWrite> writes,
                                   TimePoint now, Output& out) {
  // The value each entry is left with: its last write, at the place of its first.
  std::vector<cfg::ObjectWrite> entries;
  std::map<std::uint32_t, std::size_t> where;
  for (const auto& w : writes) {
    const std::uint32_t k = cfg::ObjectAddress{w.index, w.sub_index}.key();
    if (const auto it = where.find(k); it != where.end()) {
      entries[it->second].data = w.data;
      continue;
    }
    where.emplace(k, entries.size());
    entries.push_back(w);
  }
  sdo_.clear();
  for (auto& e : entries) {
    upload(
        VerifyResult{
            .node_id = node, .address = {e.index, e.sub_index}, .expected = std::move(e.data)},
        now, sdo_, out);
  }
  take(sdo_, now, out);
}

bool ConfigurationVerifier::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (const auto message = parse_error_control(frame)) {
    // A heartbeat or boot-up (CiA 301 §7.2.8.3.2): the node is there, a lost answer of it is
    // asked again.
    answered_.insert(message->node_id.value());
    return false;
  }
  sdo_.clear();
  const bool mine = mux_.on_frame(frame, now, sdo_);
  take(sdo_, now, out);
  return mine;
}

void ConfigurationVerifier::on_timer(TimePoint now, Output& out) {
  sdo_.clear();
  mux_.on_timer(now, sdo_);
  take(sdo_, now, out);
}

void ConfigurationVerifier::take(Outbox<SdoResult>& sdo, TimePoint now, Output& out) {
  // Loop until no result is left (a retry is started here; one the client refuses is reported
  // by upload() itself).
  while (!sdo.events.empty()) {
    std::vector<SdoResult> results = std::move(sdo.events);
    sdo.events.clear();
    for (auto& result : results) {
      if (!result.node_id) continue;  // the mux's clients are all for_node
      const auto it = running_.find(key(*result.node_id, result.id));
      if (it == running_.end()) continue;
      VerifyResult r = std::move(it->second.result);
      running_.erase(it);
      const cfg::NodeId node_id = r.node_id;
      const std::uint8_t node = node_id.value();
      const bool timed_out = result.abort == SdoAbort::Timeout && !result.aborted_by_server;
      if (unreachable_.contains(node)) {
        // One of the node's other entries, cancelled below: never asked.
        r.abort = SdoAbort::Timeout;
        r.attempts = 0;
        r.unreachable = true;
        out.report(std::move(r));
        continue;
      }
      if (!timed_out) answered_.insert(node);
      if (timed_out && !answered_.contains(node)) {
        // The node's first upload went unanswered: absent. Its other entries are cancelled
        // (each result comes back through `sdo` and is reported above).
        unreachable_.insert(node);
        r.abort = SdoAbort::Timeout;
        r.unreachable = true;
        out.report(std::move(r));
        std::vector<SdoClient::TransferId> others;
        for (const auto& [k, running] : running_) {
          if (k >> 32 == node) others.push_back(static_cast<SdoClient::TransferId>(k));
        }
        for (const auto id : others) mux_.client(node_id).cancel(id, now, sdo, SdoAbort::Timeout);
        continue;
      }
      if (timed_out && r.attempts <= options_.retries) {
        ++r.attempts;
        upload(std::move(r), now, sdo, out);
        continue;
      }
      r.abort = result.abort;
      if (result.ok()) r.actual = std::move(result.data);
      out.report(std::move(r));
    }
  }
  for (const auto& f : sdo.frames) out.send(f);
}

}  // namespace nmt
