// The master's side of its emergency consumer (master/emcy_consumer.hpp, CiA 301 §7.2.7): which
// COB-ID it consumes for each node, the consumer's reports as MasterEvents, and the EMCY a
// booting node sent for its boot's report.
#include <utility>

#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace {
// CiA 301 §7.5.2.30: 1028h, emergency consumer object; sub-index n holds the COB-ID of the EMCY
// the device consumes from node n ("the sub-index shall refer to the related node-ID", CiA 301
// v4.2.0, as Easy-CANopen's CANopen_Consumer_EMCY_Receive.c quotes it; bit 31 set: not valid).
constexpr std::uint16_t kEmergencyConsumer = 0x1028;
}  // namespace

void NmtMaster::Impl::consume_emergencies() {
  emcy.clear();
  for (unsigned n = 1; n <= cfg::kMaxNodeId; ++n) {
    const cfg::NodeId node = *cfg::NodeId::from(static_cast<std::uint8_t>(n));
    if (node == node_id) continue;
    const auto source = options.emcy.sources.find(node);
    const bool known = source != options.emcy.sources.end();
    if (!known && !is_slave(node)) continue;
    const auto configured = dict.get_unsigned(kEmergencyConsumer, static_cast<std::uint8_t>(n));
    if (configured) {
      emcy.consume(node, cfg::CobId::from_word(static_cast<std::uint32_t>(*configured)));
    } else if (known && source->second.cob_id) {
      emcy.consume(node, *source->second.cob_id);
    } else {
      emcy.consume(node, default_emcy_cob_id(node));
    }
  }
}

std::optional<std::uint32_t> NmtMaster::Impl::device_type_of(cfg::NodeId node) const {
  if (const auto it = options.emcy.sources.find(node);
      it != options.emcy.sources.end() && it->second.device_type) {
    return it->second.device_type;
  }
  const std::uint32_t expected = value_of(cfg::object::kDeviceTypeIdentification, node.value());
  return expected != 0 ? std::optional(expected) : std::nullopt;
}

void NmtMaster::Impl::dispatch_emergencies(Output& out) {
  for (const auto& e : outputs.emcy.events) {
    const bool flood = e.kind == EmcyConsumerEvent::Kind::Flood;
    auto event = master_event(
        flood ? MasterEvent::Kind::EmergencyFlood : MasterEvent::Kind::Emergency, e.at, e.node);
    event.emergency = MasterEvent::EmergencyReport{
        .emcy = e.emcy,
        .device_type = device_type_of(e.node),
        .ends_error = e.ends_error,
        .suppressed = e.suppressed,
        .window_began = e.window_began,
        .window = flood ? options.emcy.window : Duration{},
        .max_per_window = flood ? options.emcy.max_per_window : 0,
    };
    // "During its boot": while its boot NMT slave runs (a try or the wait for the next one).
    const auto step = boots[e.node].step();
    if (!flood && e.emcy.error_code != emcy_code::kErrorReset && step != BootStep::Idle &&
        step != BootStep::Booted && step != BootStep::Failed) {
      boot_emergencies[e.node.value()] = event.emergency;
    }
    report(out, std::move(event));
  }
  outputs.emcy.clear();
}

std::optional<MasterEvent::EmergencyReport> NmtMaster::Impl::BootPort::take_boot_emergency(
    cfg::NodeId node) {
  return std::exchange(m_.boot_emergencies[node.value()], std::nullopt);
}

}  // namespace nmt
