#include "nmt/sim/fault_injection.hpp"

#include <algorithm>

#include <string>

#include "cfg/object_index.hpp"
#include "nmt/protocol/error_control.hpp"

namespace nmt {

namespace {

// The identifier a COB-ID word stands for is the frame's (SDO server COB-IDs of 1200h).
bool on_cob_id(const CanFrame& frame, const cfg::CobId& cob_id) {
  const auto can_id = cfg::usable_can_id(cob_id);
  return can_id && frame.id == can_id->id && frame.extended == can_id->extended;
}

}  // namespace

struct FaultInjectedSlave::State {
  DeviceFaults faults;
  /// The options as the node's owner gave them (set_options adds the latency's share).
  SlaveNodeOptions options;
  std::mt19937_64 rng;
  std::uint64_t sdo_requests = 0;
  bool reboot_fired = false;
  /// End of the initialisation the boot delay lengthens; nullopt outside initialising.
  std::optional<TimePoint> boot_at;
  HeldFrames sdo_responses;        ///< waiting out the latency
  std::size_t next_emergency = 0;  ///< faults.emergencies raised before this one

  bool lose() {
    if (faults.frame_loss_rate <= 0.0) return false;
    return std::uniform_real_distribution<double>(0.0, 1.0)(rng) < faults.frame_loss_rate;
  }
  SdoAbort injected_abort(std::uint16_t index, std::uint8_t sub, bool write) const {
    for (const auto& a : faults.sdo_aborts) {
      if (a.index == index && (!a.sub_index || *a.sub_index == sub) &&
          (write ? a.on_write : a.on_read)) {
        return a.code;
      }
    }
    return SdoAbort::None;
  }
};

FaultInjectedSlave::FaultInjectedSlave(std::unique_ptr<SlaveNode> node, DeviceFaults faults)
    : node_(std::move(node)), state_(std::make_unique<State>()) {
  state_->options = node_->options();
  // Injected aborts answer before the node's own checks, as a device that fails to access the
  // object at all would.
  State* state = state_.get();
  auto& dict = node_->dictionary();
  dict.add_write_hook([state](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t>,
                              TimePoint) { return state->injected_abort(index, sub, true); },
                      LocalDictionary::HookPosition::First);
  dict.add_read_hook([state](std::uint16_t index, std::uint8_t sub,
                             TimePoint) { return state->injected_abort(index, sub, false); },
                     LocalDictionary::HookPosition::First);
  set_faults(std::move(faults));
}

FaultInjectedSlave::FaultInjectedSlave(FaultInjectedSlave&&) noexcept = default;
FaultInjectedSlave& FaultInjectedSlave::operator=(FaultInjectedSlave&&) noexcept = default;
FaultInjectedSlave::~FaultInjectedSlave() = default;

const SlaveNodeOptions& FaultInjectedSlave::options() const {
  return state_->options;
}

void FaultInjectedSlave::set_options(SlaveNodeOptions options) {
  state_->options = options;
  apply_sdo_timeout();
}

const DeviceFaults& FaultInjectedSlave::faults() const {
  return state_->faults;
}

std::uint64_t FaultInjectedSlave::sdo_requests() const {
  return state_->sdo_requests;
}

void FaultInjectedSlave::set_faults(DeviceFaults faults) {
  state_->faults = std::move(faults);
  state_->rng.seed(state_->faults.loss_seed);
  state_->sdo_requests = 0;
  state_->reboot_fired = false;
  state_->sdo_responses.clear();
  std::stable_sort(state_->faults.emergencies.begin(), state_->faults.emergencies.end(),
                   [](const auto& a, const auto& b) { return a.at < b.at; });
  state_->next_emergency = 0;
  apply_sdo_timeout();
}

void FaultInjectedSlave::apply_sdo_timeout() {
  // The server sees requests undelayed: its timeout must also cover the response's latency.
  SlaveNodeOptions options = state_->options;
  options.sdo_server_timeout += state_->faults.sdo_latency;
  node_->set_options(options);
}

// --- resets --------------------------------------------------------------------------------------

void FaultInjectedSlave::start(TimePoint now, Output& out) {
  node_->start(now, out);
  after_reset(now);
}

void FaultInjectedSlave::after_reset(TimePoint now) {
  state_->boot_at = now + state_->faults.boot_delay;
  state_->sdo_responses.clear();  // the server's transfer is gone with the reset
  apply_identity();
}

void FaultInjectedSlave::apply_identity() {
  auto& dict = node_->dictionary();
  auto put = [&dict](std::uint16_t index, std::uint8_t sub, std::optional<std::uint32_t> value) {
    if (!value) return;
    if (!dict.entry(index, sub)) {
      DictionaryEntry e;
      e.index = index;
      e.sub_index = sub;
      e.name = "identity (injected)";
      e.data_type = static_cast<std::uint16_t>(cfg::DataType::Unsigned32);
      e.basic_type = cfg::DataType::Unsigned32;
      e.access = cfg::AccessType::Ro;
      e.max_size = 4;
      e.bytes.assign(4, 0);
      dict.insert(std::move(e));
    }
    dict.set_unsigned(index, sub, *value);
  };
  const auto& f = state_->faults;
  put(cfg::object::kDeviceType, 0, f.device_type);
  put(cfg::object::kIdentity, 1, f.vendor_id);
  put(cfg::object::kIdentity, 2, f.product_code);
  put(cfg::object::kIdentity, 3, f.revision_number);
  put(cfg::object::kIdentity, 4, f.serial_number);
}

// --- engine --------------------------------------------------------------------------------------

bool FaultInjectedSlave::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  const DeviceFaults& f = state_->faults;
  if (!node_->powered() || f.absent) return false;
  if (state_->lose()) return false;
  // Not on the bus yet; but a node without node-ID stays initialising and serves LSS only
  // (nmt/slave/slave_node.hpp), so its frames go to it.
  if (node_->state() == NmtState::Initialising && node_->has_node_id()) return false;

  const bool sdo_request = on_cob_id(frame, node_->sdo_config().request_cob_id) && !frame.rtr &&
                           !frame.error && node_->services().sdo;
  if (sdo_request) {
    ++state_->sdo_requests;
    if (f.reboot_at_sdo_request && !state_->reboot_fired &&
        state_->sdo_requests >= *f.reboot_at_sdo_request) {
      state_->reboot_fired = true;
      out.report(
          {SlaveEvent::Kind::Fault, now,
           "power cycle at SDO request " + std::to_string(state_->sdo_requests) + " (injected)"});
      start(now, out);
      return true;
    }
  }
  // The guarding request is the node's only RTR frame on 700h + node-ID.
  if (f.ignore_guarding && frame.rtr &&
      frame.id == kErrorControlCobIdBase + node_->node_id().value()) {
    return false;
  }

  Output inner;
  const bool taken = node_->on_frame(frame, now, inner);
  if (node_->state() == NmtState::Initialising) after_reset(now);  // an NMT reset
  pass(inner, /*drop_heartbeat=*/false, now, out);
  // A response whose latency ends now leaves with the server's answer to this request.
  if (sdo_request) release_sdo_responses(now, out);
  return taken;
}

void FaultInjectedSlave::on_timer(TimePoint now, Output& out) {
  const DeviceFaults& f = state_->faults;
  if (!node_->powered() || f.absent) return;
  if (node_->state() == NmtState::Initialising) {
    if (state_->boot_at && now < *state_->boot_at) return;  // still booting (late boot)
    state_->boot_at.reset();
  }
  // A heartbeat whose time came at or after the stop is never sent.
  const auto heartbeat_due = node_->heartbeat_producer().next_deadline();
  const bool drop_heartbeat = f.heartbeat_stops_at && heartbeat_due && now >= *heartbeat_due &&
                              *heartbeat_due >= *f.heartbeat_stops_at;
  Output inner;
  node_->on_timer(now, inner);
  pass(inner, drop_heartbeat, now, out);
  if (node_->state() != NmtState::Initialising) release_sdo_responses(now, out);
  auto& due = state_->faults.emergencies;
  while (state_->next_emergency < due.size() && due[state_->next_emergency].at <= now) {
    const auto& e = due[state_->next_emergency++];
    raise_emergency(e.error_code, e.error_register_bits, now, out);
  }
}

std::optional<TimePoint> FaultInjectedSlave::next_deadline() const {
  if (!node_->powered() || state_->faults.absent) return std::nullopt;
  auto next = node_->next_deadline();
  if (node_->state() == NmtState::Initialising) {
    // The node would boot at once; the boot delay holds it back.
    if (next && state_->boot_at && *state_->boot_at > *next) next = state_->boot_at;
    return next;
  }
  next = earliest(next, state_->sdo_responses.next_due());
  const auto& due = state_->faults.emergencies;
  if (state_->next_emergency < due.size()) next = earliest(next, due[state_->next_emergency].at);
  return next;
}

void FaultInjectedSlave::raise_emergency(std::uint16_t error_code, std::uint8_t error_register_bits,
                                         TimePoint now, Output& out) {
  if (!node_->powered() || state_->faults.absent) return;
  Output inner;
  node_->raise_emergency(error_code, error_register_bits, now, inner);
  pass(inner, /*drop_heartbeat=*/false, now, out);
}

void FaultInjectedSlave::pass(Output& inner, bool drop_heartbeat, TimePoint now, Output& out) {
  const DeviceFaults& f = state_->faults;
  for (const auto& frame : inner.frames) {
    if (drop_heartbeat) {
      // The heartbeat, not the boot-up (00) that may come in the same call.
      auto msg = parse_error_control(frame);
      if (msg && msg->node_id == node_->node_id() && msg->byte != 0) continue;
    }
    if (f.sdo_latency > Duration::zero() && on_cob_id(frame, node_->sdo_config().response_cob_id)) {
      state_->sdo_responses.hold(frame, now + f.sdo_latency);
      continue;
    }
    if (!state_->lose()) out.send(frame);
  }
  for (auto& event : inner.events) out.report(std::move(event));
  inner.clear();
}

void FaultInjectedSlave::release_sdo_responses(TimePoint now, Output& out) {
  // Stopped: responses still waiting out the latency are not sent.
  const bool sdo = node_->services().sdo;
  state_->sdo_responses.release(now, [&](const CanFrame& frame) {
    if (sdo && !state_->lose()) out.send(frame);
  });
}

}  // namespace nmt
