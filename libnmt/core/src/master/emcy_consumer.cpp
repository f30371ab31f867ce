#include "master/emcy_consumer.hpp"

namespace nmt {
namespace {
std::uint32_t key(cfg::NodeId node, std::uint16_t code) {
  return (std::uint32_t{node.value()} << 16) | code;
}
}  // namespace

void EmcyConsumer::consume(cfg::NodeId node, cfg::CobId cob_id) {
  if (cob_id.valid()) {
    cob_ids_[node.value()] = cob_id;
  } else {
    cob_ids_[node.value()].reset();
  }
}

void EmcyConsumer::clear() {
  cob_ids_.fill(std::nullopt);
}

std::optional<cfg::CobId> EmcyConsumer::cob_id(cfg::NodeId node) const {
  return cob_ids_[node.value()];
}

bool EmcyConsumer::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (frame.rtr || frame.error) return false;
  for (unsigned n = 1; n < cob_ids_.size(); ++n) {
    const auto& cob = cob_ids_[n];
    if (!cob) continue;
    const cfg::CanId id = cob->can_id();
    if (id.id != frame.id || id.extended != frame.extended) continue;
    const cfg::NodeId node = *cfg::NodeId::from(static_cast<std::uint8_t>(n));
    // CiA 301 §7.2.7.3.1: the EMCY has 8 bytes; a shorter frame on the identifier is not one.
    auto emcy = parse_emcy(frame);
    if (!emcy) return true;
    ++received_[n];
    Event e{.kind = Event::Kind::Emergency, .node = node, .emcy = *emcy, .at = now};
    if (emcy->error_code == emcy_code::kErrorReset) {
      // The error reset ends the node's errors: the floods counted so far are said first.
      for (auto it = windows_.lower_bound(key(node, 0));
           it != windows_.end() && (it->first >> 16) == n;) {
        end_window(node, static_cast<std::uint16_t>(it->first), it->second, now, out);
        it = windows_.erase(it);
      }
      e.ends_error = in_error_[n];
      in_error_[n] = false;
      out.report(e);
      return true;
    }
    in_error_[n] = true;
    auto [it, fresh] = windows_.try_emplace(key(node, emcy->error_code), Window{.began = now});
    Window& w = it->second;
    if (!fresh && now >= w.began + settings_.window) {
      end_window(node, emcy->error_code, w, now, out);
      w = Window{.began = now};
    }
    if (w.reported < settings_.max_per_window) {
      ++w.reported;
      out.report(e);
    } else {
      ++w.suppressed;
      w.last = *emcy;
    }
    return true;
  }
  return false;
}

void EmcyConsumer::end_window(cfg::NodeId node, std::uint16_t /*code*/, Window& w, TimePoint now,
                              Output& out) {
  if (w.suppressed == 0) return;
  out.report(Event{.kind = Event::Kind::Flood,
                   .node = node,
                   .emcy = w.last,
                   .at = now,
                   .suppressed = w.suppressed,
                   .window_began = w.began});
}

void EmcyConsumer::on_timer(TimePoint now, Output& out) {
  for (auto it = windows_.begin(); it != windows_.end();) {
    if (now >= it->second.began + settings_.window) {
      const cfg::NodeId node = *cfg::NodeId::from(static_cast<std::uint8_t>(it->first >> 16));
      end_window(node, static_cast<std::uint16_t>(it->first), it->second, now, out);
      it = windows_.erase(it);
    } else {
      ++it;
    }
  }
}

void EmcyConsumer::end_windows(TimePoint now, Output& out) {
  for (auto& [k, w] : windows_) {
    end_window(*cfg::NodeId::from(static_cast<std::uint8_t>(k >> 16)),
               static_cast<std::uint16_t>(k), w, now, out);
  }
  windows_.clear();
}

std::optional<TimePoint> EmcyConsumer::next_deadline() const {
  std::optional<TimePoint> due;
  for (const auto& [k, w] : windows_) {
    if (w.suppressed > 0) due = earliest(due, w.began + settings_.window);
  }
  return due;
}

}  // namespace nmt
