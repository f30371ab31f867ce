// ErrorControlService (error_control_service.hpp): the master's heartbeat consumer and node
// guarding master, and who wants each node watched.
#include "master/error_control_service.hpp"

#include <algorithm>
#include <chrono>

namespace nmt {

void ErrorControlService::monitor(cfg::NodeId node, Watcher watcher, Duration time, TimePoint now) {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(time).count();
  // 1016h holds the consumer time in 16 bits; 0 is an unused entry (no consumer).
  const auto time_ms = static_cast<std::uint16_t>(std::clamp<std::int64_t>(ms, 0, 0xFFFF));
  if (time_ms == 0) return;
  heartbeats_.monitor({node.value(), time_ms}, now);
  heartbeat_watchers_[node].set(watcher, true);
}

cfg::Status ErrorControlService::guard(cfg::NodeId node, Watcher watcher,
                                       std::uint16_t guard_time_ms, std::uint8_t life_time_factor,
                                       TimePoint now) {
  auto started = guarding_.guard(node, guard_time_ms, life_time_factor, now);
  if (started) guarding_watchers_[node].set(watcher, true);
  return started;
}

bool ErrorControlService::join(cfg::NodeId node, Watcher watcher) {
  bool joined = false;
  if (heartbeats_.monitors(node)) {
    heartbeat_watchers_[node].set(watcher, true);
    joined = true;
  }
  if (guarding_.guards(node)) {
    guarding_watchers_[node].set(watcher, true);
    joined = true;
  }
  return joined;
}

void ErrorControlService::stop(cfg::NodeId node, Watcher watcher) {
  auto& heartbeat = heartbeat_watchers_[node];
  heartbeat.set(watcher, false);
  if (!heartbeat.any()) heartbeats_.stop(node);
  stop_guarding(node, watcher);
}

void ErrorControlService::stop_guarding(cfg::NodeId node, Watcher watcher) {
  auto& guarding = guarding_watchers_[node];
  guarding.set(watcher, false);
  if (!guarding.any()) guarding_.stop(node);
}

Watchers ErrorControlService::watchers(cfg::NodeId node) const {
  const auto& h = heartbeat_watchers_[node];
  const auto& g = guarding_watchers_[node];
  return {.master = h.master || g.master, .manager = h.manager || g.manager};
}

void ErrorControlService::report(cfg::NodeId node, ErrorControlEvent::Kind kind,
                                 ErrorControlProtocol protocol, TimePoint at, Output& out) const {
  const auto& watchers = protocol == ErrorControlProtocol::Heartbeat ? heartbeat_watchers_[node]
                                                                     : guarding_watchers_[node];
  out.report({.node = node, .kind = kind, .protocol = protocol, .watchers = watchers, .at = at});
}

bool ErrorControlService::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  guarding_out_.clear();
  const bool guarding_took = guarding_.on_frame(frame, now, guarding_out_);
  for (const auto& e : guarding_out_.events) {
    if (e.kind == NodeGuardingEventKind::Resolved) {
      report(e.node_id, ErrorControlEvent::Kind::Resolved, ErrorControlProtocol::Guarding, now,
             out);
    }
  }
  heartbeat_out_.clear();
  const bool heartbeat_took = heartbeats_.on_frame(frame, now, heartbeat_out_);
  for (const auto& e : heartbeat_out_.events) {
    if (e.kind == HeartbeatEventKind::Resolved) {
      report(e.node_id, ErrorControlEvent::Kind::Resolved, ErrorControlProtocol::Heartbeat, now,
             out);
    }
  }
  return guarding_took || heartbeat_took;
}

void ErrorControlService::on_timer(TimePoint now, Output& out) {
  heartbeat_out_.clear();
  heartbeats_.on_timer(now, heartbeat_out_);
  for (const auto& e : heartbeat_out_.events) {
    if (e.kind == HeartbeatEventKind::Timeout) {
      report(e.node_id, ErrorControlEvent::Kind::Lost, ErrorControlProtocol::Heartbeat, now, out);
    }
  }
  guarding_timer(now, out);
}

void ErrorControlService::send_due_requests(TimePoint now, Output& out) {
  if (const auto due = guarding_.next_deadline(); due && *due <= now) guarding_timer(now, out);
}

void ErrorControlService::guarding_timer(TimePoint now, Output& out) {
  guarding_out_.clear();
  guarding_.on_timer(now, guarding_out_);
  for (const auto& f : guarding_out_.frames) out.send(f);
  for (const auto& e : guarding_out_.events) {
    if (e.kind == NodeGuardingEventKind::Timeout) {
      report(e.node_id, ErrorControlEvent::Kind::Lost, ErrorControlProtocol::Guarding, now, out);
    }
  }
}

std::optional<TimePoint> ErrorControlService::next_deadline() const {
  return earliest(heartbeats_.next_deadline(), guarding_.next_deadline());
}

}  // namespace nmt
