// The NMT master's side of its flying master (flying_master.hpp): the port the engine calls,
// 1F90h/1F91h in the engine's units, and the reset communication of all nodes of CiA 302-2
// §3.1 d, which NMT start-up and the flying master (§3.7 d, §5.4, §5.5.2) both request.
#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

Duration ms(std::uint32_t value) {
  return std::chrono::milliseconds(value);
}

}  // namespace

FlyingTiming NmtMaster::Impl::flying_timing(std::uint8_t written_sub, std::uint32_t written) const {
  auto sub = [&](std::uint8_t s) {
    return s == written_sub ? written : value_of(obj::kFlyingMasterParameters, s);
  };
  return {ms(sub(1)), ms(sub(2)), static_cast<std::uint16_t>(sub(3)),
          ms(sub(4)), ms(sub(5)), ms(sub(6))};
}

std::optional<DetectionTiming> NmtMaster::Impl::detection_timing(std::uint8_t written_sub,
                                                                 std::uint32_t written) const {
  if (!dict.has_object(obj::kSelfStartingNodesTiming)) return std::nullopt;
  auto sub = [&](std::uint8_t s) {
    return s == written_sub ? written : value_of(obj::kSelfStartingNodesTiming, s);
  };
  return DetectionTiming{ms(sub(1)), ms(sub(2)), ms(sub(3))};
}

void NmtMaster::Impl::queue_reset_all(TimePoint /*now*/) {
  // §3.1 d: node-ID 0 unless a slave is to be kept alive; then every other node-ID (also
  // those not in 1F81h) individually, never the master itself.
  bool keep_alive = false;
  for (const auto n : all_node_ids()) {
    if (is_slave(n) && assignment(n).keep_alive()) keep_alive = true;
  }
  if (!keep_alive) {
    queue_nmt(NmtCommand::ResetCommunication, NmtTarget::all_nodes());
    return;
  }
  for (const auto n : all_node_ids()) {
    if (n == node_id || (is_slave(n) && assignment(n).keep_alive())) continue;
    queue_nmt(NmtCommand::ResetCommunication, n);
  }
}

// --- the port ---

void NmtMaster::Impl::FlyingPort::became_active(TimePoint now, Output& out) {
  m.begin_startup(now, out);
}

void NmtMaster::Impl::FlyingPort::set_startup(StartupState state) {
  m.startup.state = state;
}

void NmtMaster::Impl::FlyingPort::restart(TimePoint now) {
  m.startup.due = now;
}

void NmtMaster::Impl::FlyingPort::reset_all_nodes() {
  m.queue_reset_all(TimePoint{});
}

void NmtMaster::Impl::FlyingPort::queue_nmt(NmtCommand command, NmtTarget target) {
  m.queue_nmt(command, target);
}

void NmtMaster::Impl::FlyingPort::obey(NmtCommand command, TimePoint now, Output& out) {
  m.apply_own_command(command, now, out);
}

bool NmtMaster::Impl::FlyingPort::master_capable() const {
  return m.startup_config().is_master();
}

std::optional<Duration> NmtMaster::Impl::FlyingPort::heartbeat_time(cfg::NodeId node) const {
  return m.heartbeat_time(node);
}

std::uint32_t NmtMaster::Impl::FlyingPort::own_heartbeat_ms() const {
  return m.value_of(obj::kProducerHeartbeatTime, 0);
}

}  // namespace nmt
