#include "nmt/protocol/error_control.hpp"

#include <algorithm>
#include <array>

namespace nmt {

namespace {
Duration ms(std::int64_t value) {
  return std::chrono::milliseconds(value);
}
}  // namespace

CanFrame make_heartbeat(cfg::NodeId node_id, NmtState state) {
  const std::array<std::uint8_t, 1> bytes{static_cast<std::uint8_t>(state)};
  return CanFrame::make(kErrorControlCobIdBase + node_id, bytes);
}

CanFrame make_guarding_request(cfg::NodeId node_id) {
  CanFrame f;
  f.id = kErrorControlCobIdBase + node_id;
  f.rtr = true;
  f.dlc = 1;  // CiA 301 §7.2.8.3.2.1: the request asks for the one-byte reply
  return f;
}

std::optional<ErrorControlMessage> parse_error_control(const CanFrame& frame) {
  if (frame.extended || frame.rtr || frame.error || frame.dlc != 1) return std::nullopt;
  if (frame.id < kErrorControlCobIdBase) return std::nullopt;
  // 700h (node-ID 0) and 780h-7FFh carry no node's error control.
  const auto node = cfg::NodeId::from(frame.id - kErrorControlCobIdBase);
  if (!node) return std::nullopt;
  return ErrorControlMessage{*node, frame.data[0]};
}

// --- heartbeat producer -------------------------------------------------------------------------

void HeartbeatProducer::set_period(std::uint16_t period_ms, TimePoint now) {
  if (period_ms == period_ms_) return;
  period_ms_ = period_ms;
  // CiA 301 §7.2.8.3.2.2: a non-zero producer time starts the protocol immediately.
  if (period_ms_ == 0) {
    next_.reset();
  } else {
    next_ = now;
  }
}

void HeartbeatProducer::on_boot_up(TimePoint now) {
  // The boot-up message is the first heartbeat.
  if (period_ms_ == 0) {
    next_.reset();
  } else {
    next_ = now + ms(period_ms_);
  }
}

void HeartbeatProducer::on_timer(TimePoint now, Output& out) {
  if (!next_ || now < *next_ || period_ms_ == 0) return;
  // Keep the cycle free of drift, but do not burst to catch up after a long stall.
  *next_ += ms(period_ms_);
  if (*next_ <= now) *next_ = now + ms(period_ms_);
  out.send(make_heartbeat(node_id_, state_));
}

// --- heartbeat consumer -------------------------------------------------------------------------

std::string_view to_string(HeartbeatEventKind kind) {
  switch (kind) {
    case HeartbeatEventKind::Timeout:
      return "heartbeat timeout";
    case HeartbeatEventKind::Resolved:
      return "heartbeat resolved";
    case HeartbeatEventKind::StateChanged:
      return "state changed";
    case HeartbeatEventKind::BootUp:
      return "boot-up";
  }
  return "unknown";
}

void HeartbeatConsumer::monitor(HeartbeatConsumerEntry entry, TimePoint now) {
  const auto id = entry.node();
  if (!id) return;  // names no node: nothing to start or stop
  stop(*id);        // a restart begins afresh
  if (!entry.active()) return;
  Node& node = nodes_[*id];
  node.time = ms(entry.time_ms);
  if (options_.timeout_from_start) set_expires(*id, node, now + node.time);
}

void HeartbeatConsumer::stop(cfg::NodeId node_id) {
  auto it = nodes_.find(node_id);
  if (it == nodes_.end()) return;
  due_.move(node_id, it->second.expires, std::nullopt);
  nodes_.erase(it);
}

void HeartbeatConsumer::set_expires(cfg::NodeId id, Node& node, std::optional<TimePoint> expires) {
  due_.move(id, node.expires, expires);
  node.expires = expires;
}

std::optional<NmtState> HeartbeatConsumer::last_state(cfg::NodeId node_id) const {
  auto it = nodes_.find(node_id);
  return it == nodes_.end() ? std::nullopt : it->second.state;
}

bool HeartbeatConsumer::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto msg = parse_error_control(frame);
  if (!msg) return false;
  auto it = nodes_.find(msg->node_id);
  if (it == nodes_.end()) return false;
  Node& node = it->second;
  auto state = msg->state();
  if (!state) return true;  // not a state byte: ignore rather than guess

  if (*state == NmtState::Initialising) {
    // The node rebooted. CiA 301: the consumer waits for its first heartbeat again; the NMT
    // master runs boot slave and restarts error control (CiA 302-2 §4.3 boot-up handler).
    out.report({msg->node_id, HeartbeatEventKind::BootUp, state, now});
    set_expires(msg->node_id, node, std::nullopt);
    node.timed_out = false;
    node.state = state;
    return true;
  }
  if (node.timed_out) {
    out.report({msg->node_id, HeartbeatEventKind::Resolved, state, now});
    node.timed_out = false;
  }
  if (node.state && *node.state != *state) {
    out.report({msg->node_id, HeartbeatEventKind::StateChanged, state, now});
  }
  node.state = state;
  set_expires(msg->node_id, node, now + node.time);
  return true;
}

void HeartbeatConsumer::on_timer(TimePoint now, Output& out) {
  // Only the due nodes, earliest first; a timed-out node waits for a heartbeat (no deadline).
  while (auto id = due_.first_due(now)) {
    Node& node = nodes_.at(*id);
    out.report({*id, HeartbeatEventKind::Timeout, std::nullopt, *node.expires});
    set_expires(*id, node, std::nullopt);
    node.timed_out = true;
  }
}

std::optional<TimePoint> HeartbeatConsumer::next_deadline() const {
  return due_.earliest();
}

// --- node guarding / life guarding (slave side) -------------------------------------------------

void NodeGuardingSlave::configure(std::uint16_t guard_time_ms, std::uint8_t life_time_factor) {
  guard_time_ms_ = guard_time_ms;
  life_time_factor_ = life_time_factor;
  expired_ = false;
}

void NodeGuardingSlave::reset() {
  toggle_ = false;
  last_request_.reset();
  expired_ = false;
}

Duration NodeGuardingSlave::life_time() const {
  return ms(std::int64_t{guard_time_ms_} * life_time_factor_);
}

bool NodeGuardingSlave::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!frame.rtr || frame.extended || frame.error ||
      frame.id != kErrorControlCobIdBase + node_id_) {
    return false;
  }
  // CiA 301 §7.2.8.3.2.1: bit 7 toggles, starting with 0 for the first reply.
  const auto byte = static_cast<std::uint8_t>((toggle_ ? 0x80 : 0x00) |
                                              (static_cast<std::uint8_t>(state_) & 0x7F));
  toggle_ = !toggle_;
  const std::array<std::uint8_t, 1> bytes{byte};
  out.send(CanFrame::make(kErrorControlCobIdBase + node_id_, bytes));
  if (expired_) out.report(LifeGuardingEvent::Resolved);
  expired_ = false;
  last_request_ = now;
  return true;
}

std::optional<TimePoint> NodeGuardingSlave::next_deadline() const {
  if (!last_request_ || expired_ || life_time() == Duration::zero()) return std::nullopt;
  return *last_request_ + life_time();
}

void NodeGuardingSlave::on_timer(TimePoint now, Output& out) {
  auto due = next_deadline();
  if (!due || now < *due) return;
  expired_ = true;
  out.report(LifeGuardingEvent::Occurred);
}

// --- node guarding (master side) ----------------------------------------------------------------

std::string_view to_string(NodeGuardingEventKind kind) {
  switch (kind) {
    case NodeGuardingEventKind::Timeout:
      return "node guarding timeout";
    case NodeGuardingEventKind::Resolved:
      return "node guarding resolved";
    case NodeGuardingEventKind::StateChanged:
      return "state changed";
  }
  return "unknown";
}

cfg::Status NodeGuardingMaster::start(cfg::NodeId node_id, std::uint16_t guard_time_ms,
                                      std::uint8_t life_time_factor, TimePoint now, Output& out) {
  auto guarded = guard(node_id, guard_time_ms, life_time_factor, now);
  if (!guarded) return guarded;
  // The first request goes out now (engine.hpp rule 5), as on_timer sends every later one.
  send_due(node_id, nodes_[node_id], now, out);
  return {};
}

cfg::Status NodeGuardingMaster::guard(cfg::NodeId node_id, std::uint16_t guard_time_ms,
                                      std::uint8_t life_time_factor, TimePoint now) {
  // CiA 302-2 §6.3: a guard time or retry factor of 0 disables guarding of the device.
  if (guard_time_ms == 0) return cfg::Error{"node guarding needs a guard time above 0 ms"};
  if (life_time_factor == 0) return cfg::Error{"node guarding needs a life time factor above 0"};
  stop(node_id);  // a restart begins afresh
  Node& node = nodes_[node_id];
  node.guard_time = ms(guard_time_ms);
  node.life_time_factor = life_time_factor;
  node.next_request = now;
  due_.move(node_id, std::nullopt, node.next_request);
  return {};
}

bool NodeGuardingMaster::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto msg = parse_error_control(frame);
  if (!msg) return false;
  auto it = nodes_.find(msg->node_id);
  if (it == nodes_.end() || !it->second.awaiting_reply) return false;
  Node& node = it->second;
  auto state = msg->state();
  // A boot-up (00) is no guarding reply; the master's boot-up handler deals with it.
  if (!state || *state == NmtState::Initialising) return false;
  if (msg->toggle() != node.expected_toggle) {
    // CiA 301 §7.2.8.3.2.1: the toggle bit alternates; a repeated one means a lost reply.
    // Still awaiting a valid reply: counted as missed when the next request goes out.
    node.expected_toggle = !msg->toggle();
    return true;
  }
  node.awaiting_reply = false;
  node.expected_toggle = !node.expected_toggle;
  node.missed = 0;
  if (node.timed_out) {
    node.timed_out = false;
    out.report({msg->node_id, NodeGuardingEventKind::Resolved, state, now});
  }
  if (node.state && *node.state != *state) {
    out.report({msg->node_id, NodeGuardingEventKind::StateChanged, state, now});
  }
  node.state = state;
  return true;
}

void NodeGuardingMaster::send_due(cfg::NodeId id, Node& node, TimePoint now, Output& out) {
  if (now < node.next_request) return;
  // The previous request's answer window ends with this request.
  if (node.awaiting_reply) {
    if (node.missed < 255) ++node.missed;
    if (node.missed >= node.life_time_factor && !node.timed_out) {
      node.timed_out = true;
      out.report({id, NodeGuardingEventKind::Timeout, std::nullopt, node.next_request});
    }
  }
  out.send(make_guarding_request(id));
  node.awaiting_reply = true;
  const auto due = node.next_request;
  node.next_request += node.guard_time;
  if (node.next_request <= now) node.next_request = now + node.guard_time;
  due_.move(id, due, node.next_request);
}

void NodeGuardingMaster::stop(cfg::NodeId node_id) {
  auto it = nodes_.find(node_id);
  if (it == nodes_.end()) return;
  due_.move(node_id, it->second.next_request, std::nullopt);
  nodes_.erase(it);
}

void NodeGuardingMaster::on_timer(TimePoint now, Output& out) {
  // Only the due nodes, earliest first; each moves to a request after `now` (guard time > 0).
  while (auto id = due_.first_due(now)) send_due(*id, nodes_.at(*id), now, out);
}

std::optional<TimePoint> NodeGuardingMaster::next_deadline() const {
  return due_.earliest();
}

}  // namespace nmt
