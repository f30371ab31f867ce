#include "nmt/manager/configuration_verifier.hpp"

#include <map>

#include "cfg/object_address.hpp"

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
      if (result.abort == SdoAbort::Timeout && r.attempts <= options_.retries) {
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
