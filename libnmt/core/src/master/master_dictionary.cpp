// The NMT master's own objects (CiA 302-2 §6): the ones a master DCF lacks get their defaults,
// and SDO writes get the §6 value checks; 1F82h/1F83h writes are requests (request NMT and
// request guarding, §6.4-6.5), their reads report.
#include <array>
#include <span>
#include <string>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

constexpr std::uint8_t kAllNodesSub = 0x80;  // 1F82h/1F83h sub 80h: all nodes (§6.4, §6.5)

}  // namespace

DictionaryEntry make_entry(std::uint16_t index, std::uint8_t sub, std::string name,
                           cfg::DataType type, cfg::AccessType access, std::uint64_t value) {
  DictionaryEntry e;
  e.index = index;
  e.sub_index = sub;
  e.name = std::move(name);
  e.data_type = static_cast<std::uint16_t>(type);
  e.basic_type = type;
  e.access = access;
  const std::size_t size = cfg::data_type_info(type).size_bytes;
  e.bytes.resize(size);
  cfg::store_le(value, e.bytes, size);
  return e;
}

namespace {

void add_var(LocalDictionary& dict, std::uint16_t index, const char* name, cfg::DataType type,
             std::uint64_t value) {
  if (dict.has_object(index)) return;
  dict.insert(make_entry(index, 0, name, type, cfg::AccessType::Rw, value));
}

/// An ARRAY with sub 0 = `last` (const) and subs 1..last of `type`; `all_nodes` adds the
/// write-only sub 80h of 1F82h/1F83h.
void add_array(LocalDictionary& dict, std::uint16_t index, const char* name, cfg::DataType type,
               std::uint8_t last, std::uint64_t value, bool all_nodes = false) {
  if (dict.has_object(index)) return;
  const std::uint8_t highest = all_nodes ? kAllNodesSub : last;
  dict.insert(make_entry(index, 0, "Highest sub-index supported", cfg::DataType::Unsigned8,
                         cfg::AccessType::Const, highest));
  for (unsigned sub = 1; sub <= last; ++sub) {
    dict.insert(make_entry(index, static_cast<std::uint8_t>(sub),
                           std::string(name) + " node " + std::to_string(sub), type,
                           cfg::AccessType::Rw, value));
  }
  if (all_nodes) {
    dict.insert(make_entry(index, kAllNodesSub, std::string(name) + " all nodes", type,
                           cfg::AccessType::Wo, 0));
  }
}

}  // namespace

void NmtMaster::Impl::add_missing_objects(LocalDictionary& dict) {
  using T = cfg::DataType;
  // Defaults of CiA 302-2 §6 (1F80h has none: 1 makes the device the master it was built as).
  add_var(dict, obj::kNmtInhibitTime, "NMT inhibit time", T::Unsigned16, 0);
  add_var(dict, obj::kNmtStartup, "NMT startup", T::Unsigned32, cfg::NmtStartup::kMaster);
  add_array(dict, obj::kSlaveAssignment, "NMT slave assignment", T::Unsigned32, 127, 0);
  add_array(dict, obj::kRequestNmt, "Request NMT", T::Unsigned8, 127, 0, true);
  add_array(dict, obj::kRequestGuarding, "Request node guarding", T::Unsigned8, 127, 0, true);
  add_array(dict, obj::kDeviceTypeIdentification, "Device type identification", T::Unsigned32, 127,
            0);
  add_array(dict, obj::kVendorIdentification, "Vendor identification", T::Unsigned32, 127, 0);
  add_array(dict, obj::kProductCode, "Product code", T::Unsigned32, 127, 0);
  add_array(dict, obj::kRevisionNumber, "Revision number", T::Unsigned32, 127, 0);
  add_array(dict, obj::kSerialNumber, "Serial number", T::Unsigned32, 127, 0);
  add_var(dict, obj::kBootTime, "Boot time", T::Unsigned32, 0);
  // §6.12: the default is manufacturer-specific; 1 restores everything (1011h sub 1).
  add_array(dict, obj::kRestoreConfiguration, "Restore configuration", T::Unsigned8, 127, 1);
  add_array(dict, obj::kConsumerHeartbeatTime, "Consumer heartbeat time", T::Unsigned32, 127, 0);
  add_array(dict, obj::kExpectedConfigurationDate, "Expected configuration date", T::Unsigned32,
            127, 0);
  add_array(dict, obj::kExpectedConfigurationTime, "Expected configuration time", T::Unsigned32,
            127, 0);
  add_array(dict, obj::kExpectedApplicationSwDate, "Expected application SW date", T::Unsigned32,
            127, 0);
  add_array(dict, obj::kExpectedApplicationSwTime, "Expected application SW time", T::Unsigned32,
            127, 0);
  add_array(dict, obj::kExpectedSoftwareIdentification, "Expected software identification",
            T::Unsigned32, 127, 0);
  // 1F82h/1F83h are requests whatever the file says: writable, and 80h for all nodes.
  for (std::uint16_t index : {obj::kRequestNmt, obj::kRequestGuarding}) {
    for (unsigned sub = 1; sub < kAllNodesSub; ++sub) {
      if (const auto* e = dict.entry(index, static_cast<std::uint8_t>(sub))) {
        auto copy = *e;
        copy.access = cfg::AccessType::Rw;
        dict.insert(std::move(copy));
      }
    }
    if (!dict.entry(index, kAllNodesSub)) {
      dict.insert(make_entry(index, kAllNodesSub, "all nodes", cfg::DataType::Unsigned8,
                             cfg::AccessType::Wo, 0));
    }
  }
}

void NmtMaster::Impl::add_flying_master_objects(LocalDictionary& dict, cfg::NodeId node) {
  struct Sub {
    const char* name;
    std::uint32_t value;
  };
  // An ARRAY of UNSIGNED16 with sub 0 = the number of entries (const).
  auto add = [&dict](std::uint16_t index, std::span<const Sub> subs) {
    if (dict.has_object(index)) return;
    dict.insert(make_entry(index, 0, "Highest sub-index supported", cfg::DataType::Unsigned8,
                           cfg::AccessType::Const, subs.size()));
    for (std::size_t i = 0; i < subs.size(); ++i) {
      dict.insert(make_entry(index, static_cast<std::uint8_t>(i + 1), subs[i].name,
                             cfg::DataType::Unsigned16, cfg::AccessType::Rw, subs[i].value));
    }
  };
  // CiA 302-2 §6.13, Table 50, in ms; the priority's default is manufacturer-specific: 1
  // (medium), so a device can be made more or less important than its peers.
  const std::array<Sub, 6> flying{{
      {"NMT master timeout", 100},
      {"NMT master negotiation time delay", 500},
      {"NMT master priority", 1},
      {"Priority time slot", 1500},
      {"CANopen device time slot", 10},
      {"Multiple NMT master detect cycle time", 4000 + 10 * std::uint32_t{node.value()}},
  }};
  add(obj::kFlyingMasterParameters, flying);
  // CiA 302-2 §6.14 / DSP 302 §5.5.6: the self-starting device's timing, in ms.
  const std::array<Sub, 3> self_starting{{
      {"Timeout for detection of an NMT master-capable device", 100},
      {"Delay time for an NMT master-capable device request", 500},
      {"Node time slot", 15},
  }};
  add(obj::kSelfStartingNodesTiming, self_starting);
}

std::optional<std::string> NmtMaster::Impl::flying_value_problem(const LocalDictionary& dict,
                                                                 std::uint8_t sub,
                                                                 std::uint32_t value) {
  // §6.13, Table 48: 0 high, 1 medium, 2 low; 3..FFFFh reserved.
  if (sub == 3 && value > 2) return "priority " + std::to_string(value) + " is reserved (0..2)";
  if (sub == 4 || sub == 5) {
    // §6.13: "Priority time slot > 127 x CANopen device time slot", so the priority orders
    // the masters before the node-ID does.
    auto current = [&](std::uint8_t s) {
      return dict.get_unsigned(obj::kFlyingMasterParameters, s).value_or(0);
    };
    const std::uint64_t priority_slot = sub == 4 ? value : current(4);
    const std::uint64_t node_slot = sub == 5 ? value : current(5);
    if (priority_slot <= 127 * node_slot) {
      return "priority time slot " + std::to_string(priority_slot) +
             " ms must exceed 127 x the CANopen device time slot " + std::to_string(node_slot) +
             " ms";
    }
  }
  return std::nullopt;
}

namespace {

/// §6.2: reserved bits of 1F80h.
std::optional<std::string> startup_problem(std::uint32_t value) {
  if ((value & ~cfg::NmtStartup::kDefinedBits) != 0) return "reserved bits 7-31 are set";
  return std::nullopt;
}

/// §6.3 / DSP 302 §5.2: bit 1 of 1F81h is reserved.
bool assignment_reserved(std::uint32_t value) {
  return (value & cfg::SlaveAssignment::kReservedBit1) != 0;
}

/// §6.4/§6.5 (Tables 28 and 31): sub-index 1..127 of 1F82h/1F83h addresses that node, 80h all
/// nodes; nullopt for any other sub-index.
std::optional<NmtTarget> request_target(std::uint8_t sub) {
  constexpr std::uint8_t kAllNodes = 0x80;
  if (sub == kAllNodes) return NmtTarget::all_nodes();
  if (const auto node = cfg::NodeId::from(sub)) return NmtTarget(*node);
  return std::nullopt;
}

}  // namespace

cfg::Status NmtMaster::Impl::check_configuration_values(const LocalDictionary& dict) {
  // Reserved bits are an error of the file.
  const auto startup = dict.get_unsigned(obj::kNmtStartup, 0).value_or(0);
  if ((startup & ~std::uint64_t{cfg::NmtStartup::kDefinedBits}) != 0) {
    return cfg::Error{cfg::to_string(cfg::ObjectAddress{obj::kNmtStartup, 0}) +
                      ": reserved bits 7-31 are set (" +
                      cfg::hex(static_cast<std::uint32_t>(startup), 8) + ")"};
  }
  for (std::uint8_t sub = 3; sub <= 5; ++sub) {
    const auto value = static_cast<std::uint32_t>(
        dict.get_unsigned(obj::kFlyingMasterParameters, sub).value_or(0));
    if (auto problem = flying_value_problem(dict, sub, value)) {
      return cfg::Error{cfg::to_string(cfg::ObjectAddress{obj::kFlyingMasterParameters, sub}) +
                        ": " + *problem};
    }
  }
  for (unsigned sub = 1; sub <= cfg::kMaxNodeId; ++sub) {
    const auto value =
        dict.get_unsigned(obj::kSlaveAssignment, static_cast<std::uint8_t>(sub)).value_or(0);
    if (assignment_reserved(static_cast<std::uint32_t>(value))) {
      return cfg::Error{cfg::to_string(cfg::ObjectAddress{obj::kSlaveAssignment,
                                                          static_cast<std::uint8_t>(sub)}) +
                        ": reserved bit 1 is set (" + cfg::hex(static_cast<std::uint32_t>(value)) +
                        ")"};
    }
  }
  return {};
}

void NmtMaster::Impl::install_hooks() {
  dict.add_write_hook([this](std::uint16_t index, std::uint8_t sub,
                             std::span<const std::uint8_t> data, TimePoint now, HookOutput out) {
    return check_write(index, sub, data, now, out.as<MasterEvent>());
  });
  dict.add_read_hook([this](std::uint16_t index, std::uint8_t sub, TimePoint /*now*/) {
    if (index == obj::kRequestNmt && cfg::is_node_id(sub)) {
      // Table 28 on upload: the one place the known state becomes 1F82h's byte.
      const std::uint8_t state = sub == node_id.value() ? static_cast<std::uint8_t>(own_state)
                                                        : slaves[sub].known_state.to_byte();
      dict.set_unsigned(index, sub, state);
    } else if (const auto node = cfg::NodeId::from(sub); index == obj::kRequestGuarding && node) {
      dict.set_unsigned(index, sub, error_control.guards(*node) ? 1 : 0);
    }
    return SdoAbort::None;
  });
  store_objects.install();
}

SdoAbort NmtMaster::Impl::check_write(std::uint16_t index, std::uint8_t sub,
                                      std::span<const std::uint8_t> data, TimePoint now,
                                      Output* out) {
  // Every write comes here, DOMAINs of any length too; the numeric objects below have had their
  // size checked by the dictionary (0607 0010).
  const auto value = cfg::low_le32(data);
  switch (index) {
    case obj::kNmtStartup:
      return startup_problem(value) ? SdoAbort::ValueRangeExceeded : SdoAbort::None;
    case obj::kSlaveAssignment:
      return sub != 0 && assignment_reserved(value) ? SdoAbort::ValueRangeExceeded : SdoAbort::None;
    case obj::kFlyingMasterParameters:
      if (flying_value_problem(dict, sub, value)) return SdoAbort::ValueRangeExceeded;
      flying.set_timing(flying_timing(sub, value));  // the engine's next steps use it
      return SdoAbort::None;
    case obj::kSelfStartingNodesTiming:
      if (auto timing = detection_timing(sub, value)) flying.set_detection_timing(*timing);
      return SdoAbort::None;
    case obj::kRequestNmt: {
      const auto target = request_target(sub);
      if (!target) return SdoAbort::SubIndexDoesNotExist;
      // §6.4: a reserved value is refused with 0609 0030.
      const auto request = nmt_request_from_byte(static_cast<std::uint8_t>(value));
      if (!request) return SdoAbort::ValueRangeExceeded;
      return request_nmt(*target, *request, std::nullopt, now, out);
    }
    case obj::kRequestGuarding: {
      const auto target = request_target(sub);
      if (!target) return SdoAbort::SubIndexDoesNotExist;
      return request_guarding(*target, static_cast<std::uint8_t>(value), now);
    }
    default:
      return SdoAbort::None;
  }
}

std::uint32_t NmtMaster::Impl::value_of(std::uint16_t index, std::uint8_t sub) const {
  return static_cast<std::uint32_t>(dict.get_unsigned(index, sub).value_or(0));
}

cfg::SlaveAssignment NmtMaster::Impl::assignment(cfg::NodeId node) const {
  // §6.3: "The sub-index corresponding to its own node-ID shall be ignored."
  if (node == node_id) return {};
  return {value_of(obj::kSlaveAssignment, node)};
}

std::optional<Duration> NmtMaster::Impl::heartbeat_time(cfg::NodeId node) const {
  const auto count = dict.get_unsigned(obj::kConsumerHeartbeatTime, 0).value_or(0);
  for (std::uint64_t sub = 1; sub <= count && sub <= 0xFF; ++sub) {
    const auto entry = HeartbeatConsumerEntry::decode(
        value_of(obj::kConsumerHeartbeatTime, static_cast<std::uint8_t>(sub)));
    if (entry.active() && entry.node_id == node) {
      return std::chrono::milliseconds(entry.time_ms);
    }
  }
  return std::nullopt;
}

Duration NmtMaster::Impl::nmt_inhibit_time() const {
  // §6.1: multiples of 100 µs.
  return Duration{std::int64_t{100} * value_of(obj::kNmtInhibitTime, 0)};
}

// --- request NMT (1F82h) and request guarding (1F83h) ---

SdoAbort NmtMaster::Impl::request_nmt(NmtTarget target, NmtRequest request,
                                      std::optional<cfg::NodeId> requester, TimePoint now,
                                      Output* out) {
  const auto command = nmt_command_of(request);
  if (!startup_config().is_master() || !acts_as_master()) return SdoAbort::DeviceState;
  const bool excluding = excludes_master_and_requester(request);
  // §6.4: 84h-8Fh need the requester's node-ID; unknown: 0800 0000.
  if (excluding && !requester) return SdoAbort::General;
  auto hold = [&](cfg::NodeId node) {
    // DSP 302 §5.4: no automatic re-boot after a state change by request NMT (start ends it).
    if (is_slave(node)) slaves[node].held = command != NmtCommand::Start;
  };
  // Each queued command waits for the inhibit time (102Ah, which a peer may set to 6.5 s):
  // bounded by MasterOptions::nmt.max_queued_requests, 0504 0005 beyond (docs/master.md).
  auto no_room_for = [&](std::size_t commands) {
    return nmt_commands.size() + commands > options.nmt.max_queued_requests;
  };
  // A command for the master itself changes its state in this call: that needs the call's output.
  const bool applies_to_master = target.all() ? !excluding : target.node() == node_id;
  if (applies_to_master && out == nullptr) return SdoAbort::DeviceState;
  if (target.all()) {
    if (excluding) {
      const bool self = requester->value() == node_id.value();
      if (no_room_for(cfg::kMaxNodeId - (self ? 1 : 2))) return SdoAbort::OutOfMemory;
      for (const auto n : all_node_ids()) {
        if (n == node_id || n == *requester) continue;
        queue_nmt(command, n);
        hold(n);
      }
      return SdoAbort::None;
    }
    if (no_room_for(1)) return SdoAbort::OutOfMemory;
    queue_nmt(command, NmtTarget::all_nodes());
    for (const auto n : all_node_ids()) hold(n);
    // DSP 302 §5.4: "A RequestNMT to all nodes will also apply for the Master itself."
    apply_own_command(command, now, *out);
    return SdoAbort::None;
  }
  const auto node = target.node();
  if (*node == node_id) {
    apply_own_command(command, now, *out);
    return SdoAbort::None;
  }
  if (excluding && *node == *requester) return SdoAbort::General;
  // A request for a node that is not a slave of this master: 0800 0000 (docs/master.md, choices).
  if (!is_slave(*node)) return SdoAbort::General;
  if (no_room_for(1)) return SdoAbort::OutOfMemory;
  queue_nmt(command, *node);
  hold(*node);
  return SdoAbort::None;
}

SdoAbort NmtMaster::Impl::request_guarding(NmtTarget target, std::uint8_t value, TimePoint now) {
  // §6.5, Table 31: 0 stop, 1 start; the rest is reserved.
  if (value > 1) return SdoAbort::ValueRangeExceeded;
  if (!startup_config().is_master() || !acts_as_master()) return SdoAbort::DeviceState;
  auto apply = [&](cfg::NodeId node) {
    if (!is_slave(node)) return SdoAbort::General;
    if (value == 0) {
      error_control.stop_guarding(node, Watcher::Master);
      return SdoAbort::None;
    }
    const auto a = assignment(node);
    // §6.3: guard time or retry factor 0 disable guarding for the device (guard refuses them).
    // The first request leaves at the end of the call (settle()), or at the next call of the
    // master for a write through dictionary() (next_deadline: due at `now`).
    const auto started =
        error_control.guard(node, Watcher::Master, a.guard_time_ms(), a.retry_factor(), now);
    return started ? SdoAbort::None : SdoAbort::General;
  };
  if (target.all()) {
    for (const auto n : all_node_ids()) {
      if (is_slave(n)) (void)apply(n);
    }
    return SdoAbort::None;
  }
  const auto node = target.node();
  // §6.5: "The sub-index corresponding to its own node-ID shall be ignored."
  if (*node == node_id) return SdoAbort::None;
  return apply(*node);
}

}  // namespace nmt
