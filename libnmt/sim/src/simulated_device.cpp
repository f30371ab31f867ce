#include "nmt/simulated_device.hpp"
#include "cfg/hex.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <utility>

namespace nmt {

namespace {

// CiA 301 §7.5.2.13/14: 'save' and 'load' as little-endian UNSIGNED32.
constexpr std::uint32_t kSaveSignature = 0x65766173;
constexpr std::uint32_t kLoadSignature = 0x64616F6C;
constexpr std::uint32_t kCobIdInvalid = 0x80000000u;

constexpr std::uint16_t kDeviceType = 0x1000;
constexpr std::uint16_t kErrorRegister = 0x1001;
constexpr std::uint16_t kGuardTime = 0x100C;
constexpr std::uint16_t kLifeTimeFactor = 0x100D;
constexpr std::uint16_t kStoreParameters = 0x1010;
constexpr std::uint16_t kRestoreDefaults = 0x1011;
constexpr std::uint16_t kEmcyCobId = 0x1014;
constexpr std::uint16_t kEmcyInhibit = 0x1015;
constexpr std::uint16_t kConsumerHeartbeat = 0x1016;
constexpr std::uint16_t kProducerHeartbeat = 0x1017;
constexpr std::uint16_t kIdentity = 0x1018;
constexpr std::uint16_t kVerifyConfiguration = 0x1020;
constexpr std::uint16_t kErrorBehaviour = 0x1029;
constexpr std::uint16_t kProgramData = 0x1F50;
constexpr std::uint16_t kProgramControl = 0x1F51;
constexpr std::uint16_t kVerifyApplicationSoftware = 0x1F52;
constexpr std::uint16_t kProgramIdentification = 0x1F56;

bool is_program_object(std::uint16_t index) {
  return index >= 0x1F50 && index <= 0x1F57;
}
bool is_rpdo_comm(std::uint16_t index) {
  return index >= 0x1400 && index <= 0x15FF;
}
bool is_tpdo_comm(std::uint16_t index) {
  return index >= 0x1800 && index <= 0x19FF;
}
bool is_rpdo_mapping(std::uint16_t index) {
  return index >= 0x1600 && index <= 0x17FF;
}
bool is_tpdo_mapping(std::uint16_t index) {
  return index >= 0x1A00 && index <= 0x1BFF;
}

// 1010h/1011h sub-index -> which indices it covers (CiA 301 §7.5.2.13).
bool in_area(std::uint8_t area, std::uint16_t index) {
  switch (area) {
    case 2:
      return index >= 0x1000 && index <= 0x1FFF;
    case 3:
      return index >= 0x6000 && index <= 0x9FFF;
    case 4:
      return index >= 0x2000 && index <= 0x5FFF;
    default:
      return true;  // 1: all parameters; 05h-7Fh manufacturer-specific: taken as all
  }
}

std::uint32_t le32(std::span<const std::uint8_t> data) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < std::min<std::size_t>(4, data.size()); ++i) {
    v |= std::uint32_t{data[i]} << (8 * i);
  }
  return v;
}

// CRC-32 (IEEE 802.3), the checksum the simulated device reports in 1F56h after a download.
std::uint32_t crc32(std::span<const std::uint8_t> data) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (auto byte : data) {
    crc ^= byte;
    for (int i = 0; i < 8; ++i) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

std::string where(std::uint16_t index, std::uint8_t sub) {
  return cfg::hex_digits(index, 4) + "sub" + cfg::hex_digits(sub, 1);
}

}  // namespace

std::string_view to_string(DeviceEvent::Kind kind) {
  switch (kind) {
    case DeviceEvent::Kind::Boot:
      return "boot";
    case DeviceEvent::Kind::StateChange:
      return "nmt";
    case DeviceEvent::Kind::SdoWrite:
      return "sdo-write";
    case DeviceEvent::Kind::Stored:
      return "store";
    case DeviceEvent::Kind::Restored:
      return "restore";
    case DeviceEvent::Kind::LifeGuarding:
      return "life-guarding";
    case DeviceEvent::Kind::Heartbeat:
      return "heartbeat";
    case DeviceEvent::Kind::Emergency:
      return "emcy";
    case DeviceEvent::Kind::Program:
      return "program";
    case DeviceEvent::Kind::Fault:
      return "fault";
  }
  return "event";
}

// --- construction --------------------------------------------------------------------------------

cfg::Result<std::unique_ptr<SimulatedDevice>> SimulatedDevice::create(
    const cfg::DeviceDescription& description, std::optional<std::uint8_t> node_id,
    DeviceFaults faults, SimulatedDeviceOptions options) {
  if (!node_id) node_id = description.node_id();
  if (!node_id) {
    return cfg::Error{"no node-ID: give one (DEVICE.eds@ID) or set NodeID in [DeviceComissioning]"};
  }
  if (*node_id < 1 || *node_id > 127) {
    return cfg::Error{"node-ID " + std::to_string(*node_id) + " is out of range 1..127"};
  }
  auto factory = LocalDictionary::from_device(description, *node_id);
  if (!factory) return factory.error();
  return std::make_unique<SimulatedDevice>(Key{}, description, std::move(factory).value(), *node_id,
                                           std::move(faults), std::move(options));
}

SimulatedDevice::SimulatedDevice(Key, cfg::DeviceDescription description, LocalDictionary factory,
                                 std::uint8_t node_id, DeviceFaults faults,
                                 SimulatedDeviceOptions options)
    : description_(std::move(description)),
      factory_(std::move(factory)),
      dict_(factory_),
      faults_(std::move(faults)),
      options_(std::move(options)),
      nmt_(node_id),
      sdo_(faults_.sdo_latency, dict_, SdoServerConfig::for_node(node_id)),
      emcy_(kEmcyCobIdBase + node_id),
      rng_(faults_.loss_seed) {
  // Programs the device file declares (1F51h sub 1..); a shipped device runs its program
  // unless the file says otherwise.
  for (const auto& [key, entry] : dict_.entries()) {
    if (entry.index != kProgramControl || entry.sub_index == 0) continue;
    auto v = dict_.get_unsigned(kProgramControl, entry.sub_index).value_or(1);
    programs_[entry.sub_index] = v == 0 || v == 2 ? ProgramState::Stopped
                                 : v == 3         ? ProgramState::NoProgram
                                                  : ProgramState::Running;
  }
  install_hooks();
}

SimulatedDevice::~SimulatedDevice() = default;

void SimulatedDevice::install_hooks() {
  dict_.add_write_hook(
      [this](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data) {
        return check_write(index, sub, data);
      });
  dict_.add_write_observer(
      [this](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data) {
        after_write(index, sub, data);
      });
  dict_.add_read_hook(
      [this](std::uint16_t index, std::uint8_t sub) { return injected_abort(index, sub, false); });
}

void SimulatedDevice::set_faults(DeviceFaults faults) {
  faults_ = std::move(faults);
  rng_.seed(faults_.loss_seed);
  sdo_requests_ = 0;
  reboot_fired_ = false;
  sdo_.engine().set_config(sdo_.engine().config());
  sdo_.discard();
  sdo_.set_delay(faults_.sdo_latency);
}

std::optional<ProgramState> SimulatedDevice::program_state(std::uint8_t program) const {
  auto it = programs_.find(program);
  if (it == programs_.end()) return std::nullopt;
  return it->second;
}

void SimulatedDevice::emit(DeviceEvent::Kind kind, TimePoint at, std::string text) {
  if (on_event_) on_event_(DeviceEvent{kind, at, std::move(text)});
}

bool SimulatedDevice::lose() {
  if (faults_.frame_loss_rate <= 0.0) return false;
  return std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < faults_.frame_loss_rate;
}

void SimulatedDevice::flush(std::vector<CanFrame>& local, std::vector<CanFrame>& out) {
  for (const auto& f : local) {
    if (!lose()) out.push_back(f);
  }
  local.clear();
}

// --- resets
// ---------------------------------------------------------------------------------------

void SimulatedDevice::power_on(TimePoint now) {
  powered_ = true;
  now_ = now;
  nmt_.power_on();
  enter_initialisation(ResetScope::Application, now);
}

void SimulatedDevice::enter_initialisation(ResetScope scope, TimePoint now) {
  // CiA 301 §7.3.2.2.1: reset application restores 2000h-9FFFh (and then communication);
  // reset communication restores 1000h-1FFFh, from stored values where there are any.
  restore(scope);
  if (scope == ResetScope::Application) {
    // Like a power cycle, reset application boots the device's program when there is one.
    for (auto& [program, state] : programs_) {
      set_program_state(program, state == ProgramState::NoProgram ? ProgramState::NoProgram
                                                                  : ProgramState::Running);
    }
  }
  configure_services();
  heartbeat_.stop();
  boot_at_ = now + faults_.boot_delay;
  communication_errors_ = 0;
}

void SimulatedDevice::restore(ResetScope scope) {
  std::vector<std::pair<std::uint16_t, std::uint8_t>> keys;
  keys.reserve(dict_.entries().size());
  for (const auto& [key, entry] : dict_.entries()) keys.emplace_back(entry.index, entry.sub_index);
  for (auto [index, sub] : keys) {
    if (is_program_object(index)) continue;  // the program has its own memory
    if (scope == ResetScope::Communication && (index < 0x1000 || index > 0x1FFF)) continue;
    auto stored = stored_.find(LocalDictionary::key(index, sub));
    if (stored != stored_.end()) {
      dict_.set_bytes(index, sub, stored->second);
    } else if (auto factory = factory_.get_bytes(index, sub)) {
      dict_.set_bytes(index, sub, *factory);
    }
  }
  apply_identity();
}

void SimulatedDevice::apply_identity() {
  auto put = [this](std::uint16_t index, std::uint8_t sub, std::optional<std::uint32_t> value) {
    if (!value) return;
    if (!dict_.entry(index, sub)) {
      DictionaryEntry e;
      e.index = index;
      e.sub_index = sub;
      e.name = "identity (injected)";
      e.data_type = static_cast<std::uint16_t>(cfg::DataType::Unsigned32);
      e.basic_type = cfg::DataType::Unsigned32;
      e.access = cfg::AccessType::Ro;
      e.max_size = 4;
      e.bytes.assign(4, 0);
      dict_.insert(std::move(e));
    }
    dict_.set_unsigned(index, sub, *value);
  };
  put(kDeviceType, 0, faults_.device_type);
  put(kIdentity, 1, faults_.vendor_id);
  put(kIdentity, 2, faults_.product_code);
  put(kIdentity, 3, faults_.revision_number);
  put(kIdentity, 4, faults_.serial_number);
}

void SimulatedDevice::configure_services() {
  // Drops a transfer in progress, and responses not yet sent, without a frame.
  sdo_.engine().set_config(SdoServerConfig::from_dictionary(dict_));
  sdo_.discard();
  sdo_.set_delay(faults_.sdo_latency);

  heartbeat_.set_period(
      static_cast<std::uint16_t>(dict_.get_unsigned(kProducerHeartbeat, 0).value_or(0)), now_);
  guarding_.configure(
      static_cast<std::uint16_t>(dict_.get_unsigned(kGuardTime, 0).value_or(0)),
      static_cast<std::uint8_t>(dict_.get_unsigned(kLifeTimeFactor, 0).value_or(0)));
  guarding_.reset();

  emcy_.set_cob_id(static_cast<std::uint32_t>(
      dict_.get_unsigned(kEmcyCobId, 0).value_or(kEmcyCobIdBase + nmt_.node_id())));
  emcy_.set_inhibit_time(
      static_cast<std::uint16_t>(dict_.get_unsigned(kEmcyInhibit, 0).value_or(0)));
  emcy_.reset();
  restart_consumer();
}

void SimulatedDevice::restart_consumer() {
  consumer_.stop_all();
  for (std::uint8_t sub = 1; sub != 0 && dict_.entry(kConsumerHeartbeat, sub); ++sub) {
    auto value = dict_.get_unsigned(kConsumerHeartbeat, sub).value_or(0);
    consumer_.monitor(HeartbeatConsumerEntry::decode(static_cast<std::uint32_t>(value)), now_);
  }
}

// --- engine
// ---------------------------------------------------------------------------------------

bool SimulatedDevice::on_frame(const CanFrame& frame, TimePoint now, Output& output) {
  auto& out = output.frames;
  if (!powered_ || faults_.absent) return false;
  now_ = now;
  if (lose()) return false;
  if (nmt_.state() == NmtState::Initialising) return false;  // not on the bus yet

  std::vector<CanFrame> local;
  if (auto t = nmt_.on_frame(frame)) {
    apply_nmt(*t, now);
    flush(local, out);
    return true;
  }
  const NmtServices services = nmt_.services();

  const auto sdo_request = cfg::usable_can_id(sdo_.engine().config().request_cob_id);
  if (sdo_request && frame.id == sdo_request->id && frame.extended == sdo_request->extended &&
      !frame.rtr && !frame.error && services.sdo) {
    ++sdo_requests_;
    if (faults_.reboot_at_sdo_request && !reboot_fired_ &&
        sdo_requests_ >= *faults_.reboot_at_sdo_request) {
      reboot_fired_ = true;
      emit(DeviceEvent::Kind::Fault, now,
           "power cycle at SDO request " + std::to_string(sdo_requests_) + " (injected)");
      power_on(now);
      return true;
    }
    Delayed<SdoServer>::Output sdo_out;
    sdo_.on_frame(frame, now, sdo_out);
    local.insert(local.end(), sdo_out.frames.begin(), sdo_out.frames.end());
  }

  if (services.error_control) {
    // CiA 301 §7.2.8.1: a device uses heartbeat when 1017h is not 0, node guarding otherwise.
    if (heartbeat_.period_ms() == 0 && !faults_.ignore_guarding) {
      auto r = guarding_.on_frame(frame, now, nmt_.node_id(), nmt_.state());
      if (r.reply) local.push_back(*r.reply);
      if (r.event == LifeGuardingEvent::Resolved) {
        emit(DeviceEvent::Kind::LifeGuarding, now, "life guarding resolved");
        communication_recovered("life guarding", now, local);
      }
    }
    for (const auto& ev : consumer_.on_frame(frame, now)) {
      if (ev.kind == HeartbeatEventKind::Resolved) {
        emit(DeviceEvent::Kind::Heartbeat, now,
             "heartbeat of node " + std::to_string(ev.node_id) + " resolved");
        communication_recovered("heartbeat", now, local);
      }
    }
  }
  flush(local, out);
  return true;
}

void SimulatedDevice::apply_nmt(const NmtSlave::Transition& t, TimePoint now) {
  emit(DeviceEvent::Kind::StateChange, now,
       std::string(to_string(t.command)) + ": " + std::string(to_string(t.from)) + " -> " +
           std::string(t.reset ? to_string(*t.reset) : to_string(t.to)));
  if (t.reset) enter_initialisation(*t.reset, now);
}

bool SimulatedDevice::heartbeat_stopped_by_fault(TimePoint at) const {
  return faults_.heartbeat_stops_at && at >= *faults_.heartbeat_stops_at;
}

void SimulatedDevice::on_timer(TimePoint now, Output& output) {
  auto& out = output.frames;
  if (!powered_ || faults_.absent) return;
  now_ = now;
  std::vector<CanFrame> local;
  if (boot_at_ && now >= *boot_at_) {
    boot_at_.reset();
    local.push_back(nmt_.finish_initialisation());
    heartbeat_.on_boot_up(now);
    emit(DeviceEvent::Kind::Boot, now, "boot-up");
  }
  if (nmt_.state() != NmtState::Initialising) {
    if (auto due = heartbeat_.deadline(); due && now >= *due) {
      auto hb = heartbeat_.on_timer(now, nmt_.node_id(), nmt_.state());
      if (hb && !heartbeat_stopped_by_fault(*due)) local.push_back(*hb);
    }
    if (guarding_.on_timer(now) == LifeGuardingEvent::Occurred) {
      emit(DeviceEvent::Kind::LifeGuarding, now, "life guarding event");
      communication_error("life guarding", now, local);
    }
    for (const auto& ev : consumer_.on_timer(now)) {
      emit(DeviceEvent::Kind::Heartbeat, now,
           "heartbeat of node " + std::to_string(ev.node_id) + " timed out");
      communication_error("heartbeat", now, local);
    }
    // Read the state again: the error behaviour above may have changed it.
    for (auto& f : emcy_.on_timer(now, nmt_.services().emcy)) local.push_back(f);
    Delayed<SdoServer>::Output sdo_out;
    sdo_.on_timer(now, sdo_out);
    // Stopped: responses still waiting out the latency are not sent.
    if (nmt_.services().sdo)
      local.insert(local.end(), sdo_out.frames.begin(), sdo_out.frames.end());
  }
  flush(local, out);
}

std::optional<TimePoint> SimulatedDevice::next_deadline() const {
  if (!powered_ || faults_.absent) return std::nullopt;
  std::optional<TimePoint> earliest = boot_at_;
  auto consider = [&earliest](std::optional<TimePoint> t) {
    if (t && (!earliest || *t < *earliest)) earliest = t;
  };
  if (nmt_.state() != NmtState::Initialising) {
    auto hb = heartbeat_.deadline();
    if (hb && !heartbeat_stopped_by_fault(*hb)) consider(hb);
    consider(guarding_.deadline());
    consider(consumer_.deadline());
    consider(emcy_.deadline());
    consider(sdo_.next_deadline());
  }
  return earliest;
}

// --- errors and emergencies
// -----------------------------------------------------------------------

std::uint8_t SimulatedDevice::error_register() const {
  return static_cast<std::uint8_t>(dict_.get_unsigned(kErrorRegister, 0).value_or(0));
}

void SimulatedDevice::set_error_register(std::uint8_t value) {
  dict_.set_unsigned(kErrorRegister, 0, value);
}

void SimulatedDevice::raise_emergency(std::uint16_t error_code, std::uint8_t error_register_bits,
                                      TimePoint now, std::vector<CanFrame>& out) {
  if (!powered_ || faults_.absent || nmt_.state() == NmtState::Initialising) return;
  now_ = now;
  // CiA 301 §7.5.2.2: the generic bit is set whenever any error is present.
  const auto reg = static_cast<std::uint8_t>(
      error_register() | error_register_bits |
      (error_code != emcy_code::kErrorReset ? error_register::kGeneric : 0));
  set_error_register(reg);
  emit(DeviceEvent::Kind::Emergency, now,
       "EMCY " + cfg::hex_digits(error_code, 4) + " register " + cfg::hex_digits(reg, 2));
  std::vector<CanFrame> local;
  if (auto f = emcy_.raise({error_code, reg, {}}, now, nmt_.services().emcy)) local.push_back(*f);
  flush(local, out);
}

void SimulatedDevice::communication_error(const std::string& what, TimePoint now,
                                          std::vector<CanFrame>& out) {
  ++communication_errors_;
  const auto reg = static_cast<std::uint8_t>(error_register() | error_register::kGeneric |
                                             error_register::kCommunication);
  set_error_register(reg);
  // spec/002: "Node 1 send an EMCY indicating the lifeguard error" (8130h).
  emit(DeviceEvent::Kind::Emergency, now, "EMCY 8130 (" + what + ")");
  if (auto f =
          emcy_.raise({emcy_code::kLifeGuardOrHeartbeat, reg, {}}, now, nmt_.services().emcy)) {
    out.push_back(*f);
  }
  // CiA 301 §7.5.2.32 (1029h sub 1): 0 pre-operational (only from operational), 1 no change,
  // 2 stopped. Devices without 1029h stay where they are.
  if (auto behaviour = dict_.get_unsigned(kErrorBehaviour, 1)) {
    if (*behaviour == 0 && nmt_.state() == NmtState::Operational) {
      nmt_.set_state(NmtState::PreOperational);
      emit(DeviceEvent::Kind::StateChange, now, "error behaviour: operational -> pre-operational");
    } else if (*behaviour == 2 && nmt_.state() != NmtState::Stopped) {
      emit(DeviceEvent::Kind::StateChange, now,
           "error behaviour: " + std::string(to_string(nmt_.state())) + " -> stopped");
      nmt_.set_state(NmtState::Stopped);
    }
  }
}

void SimulatedDevice::communication_recovered(const std::string& what, TimePoint now,
                                              std::vector<CanFrame>& out) {
  if (communication_errors_ == 0) return;
  if (--communication_errors_ > 0) return;
  const auto reg = static_cast<std::uint8_t>(
      error_register() & ~(error_register::kCommunication | error_register::kGeneric));
  set_error_register(reg);
  // CiA 301 §7.2.7.1: error code 0000h tells that an error condition has gone.
  emit(DeviceEvent::Kind::Emergency, now, "EMCY 0000 (" + what + " recovered)");
  if (auto f = emcy_.raise({emcy_code::kErrorReset, reg, {}}, now, nmt_.services().emcy)) {
    out.push_back(*f);
  }
}

// --- dictionary hooks
// -----------------------------------------------------------------------------

SdoAbort SimulatedDevice::injected_abort(std::uint16_t index, std::uint8_t sub, bool write) const {
  for (const auto& a : faults_.sdo_aborts) {
    if (a.index == index && (!a.sub_index || *a.sub_index == sub) &&
        (write ? a.on_write : a.on_read)) {
      return a.code;
    }
  }
  return SdoAbort::None;
}

bool SimulatedDevice::is_stored_parameter(std::uint16_t index, std::uint8_t sub) const {
  if (index == kStoreParameters || index == kRestoreDefaults || is_program_object(index)) {
    return false;
  }
  const DictionaryEntry* e = dict_.entry(index, sub);
  return e != nullptr && cfg::is_writable(e->access);
}

SdoAbort SimulatedDevice::check_write(std::uint16_t index, std::uint8_t sub,
                                      std::span<const std::uint8_t> data) {
  if (auto code = injected_abort(index, sub, true); code != SdoAbort::None) return code;
  if (index == kStoreParameters && sub != 0 && le32(data) != kSaveSignature) {
    return SdoAbort::CannotStoreOrTransfer;  // CiA 301 §7.5.2.13: wrong signature
  }
  if (index == kRestoreDefaults && sub != 0 && le32(data) != kLoadSignature) {
    return SdoAbort::CannotStoreOrTransfer;  // CiA 301 §7.5.2.14
  }
  if (auto code = check_pdo_write(index, sub, data); code != SdoAbort::None) return code;
  return check_program_write(index, sub, data);
}

SdoAbort SimulatedDevice::check_pdo_write(std::uint16_t index, std::uint8_t sub,
                                          std::span<const std::uint8_t> data) const {
  if (is_rpdo_comm(index) || is_tpdo_comm(index)) {
    const auto cob_id = dict_.get_unsigned(index, 1);
    const bool valid = cob_id && (*cob_id & kCobIdInvalid) == 0;
    if (!valid) return SdoAbort::None;
    if (sub == 1) {
      // CiA 301 §7.5.2.35/37: bits 0-30 may only change while the PDO does not exist;
      // setting bit 31 (destroying the PDO) is always allowed.
      const std::uint32_t value = le32(data);
      if ((value & kCobIdInvalid) == 0 && value != *cob_id) return SdoAbort::ValueRangeExceeded;
    }
    // CiA 301 §7.5.2.37: inhibit time (3) and SYNC start value (6) of a TPDO shall not change
    // while the PDO exists.
    if (is_tpdo_comm(index) && (sub == 3 || sub == 6)) {
      const DictionaryEntry* e = dict_.entry(index, sub);
      if (e && !std::equal(e->bytes.begin(), e->bytes.end(), data.begin(), data.end())) {
        return SdoAbort::ValueRangeExceeded;
      }
    }
    return SdoAbort::None;
  }
  if (is_rpdo_mapping(index) || is_tpdo_mapping(index)) {
    // CiA 301 §7.5.2.36/38: mapping changes only while the PDO is invalid, entries only while
    // sub 0 is 0; writing sub 0 = n validates the n entries.
    const auto comm = static_cast<std::uint16_t>(index - 0x200);
    const auto cob_id = dict_.get_unsigned(comm, 1);
    if (cob_id && (*cob_id & kCobIdInvalid) == 0) return SdoAbort::DeviceState;
    if (sub != 0) {
      return dict_.get_unsigned(index, 0).value_or(0) != 0 ? SdoAbort::DeviceState : SdoAbort::None;
    }
    return data.empty() ? SdoAbort::None : check_pdo_mapping(index, data[0]);
  }
  return SdoAbort::None;
}

SdoAbort SimulatedDevice::check_pdo_mapping(std::uint16_t mapping_index, std::uint8_t count) const {
  const bool receive = is_rpdo_mapping(mapping_index);
  unsigned total_bits = 0;
  for (std::uint8_t i = 1; i <= count && i != 0; ++i) {
    auto value = dict_.get_unsigned(mapping_index, i);
    if (!value) return SdoAbort::CannotBeMapped;
    const auto index = static_cast<std::uint16_t>(*value >> 16);
    const auto sub = static_cast<std::uint8_t>((*value >> 8) & 0xFF);
    const auto bits = static_cast<unsigned>(*value & 0xFF);
    if (bits == 0) return SdoAbort::CannotBeMapped;

    if (index >= 0x0001 && index <= 0x0007 && sub == 0) {
      // Dummy mapping (CiA 301 §7.4.7.1): a data type index, allowed when [DummyUsage] says so.
      const auto* type = cfg::find_data_type(index);
      const std::string key = "Dummy" + cfg::hex_digits(index, 4);
      const std::string* usage = description_.dummy_usage.find(key);
      if (!type || !usage || *usage == "0" || !receive) return SdoAbort::CannotBeMapped;
      const unsigned type_bits = index == 0x0001 ? 1u : type->size_bytes * 8u;
      if (bits != type_bits) return SdoAbort::CannotBeMapped;
    } else {
      const DictionaryEntry* e = dict_.entry(index, sub);
      if (e == nullptr || !e->pdo_mapping) return SdoAbort::CannotBeMapped;
      // CiA 306 §4.6.3: rww entries go into RPDOs, rwr entries into TPDOs.
      using cfg::AccessType;
      const bool fits = receive ? (e->access == AccessType::Rw || e->access == AccessType::Wo ||
                                   e->access == AccessType::Rww)
                                : (e->access == AccessType::Rw || e->access == AccessType::Ro ||
                                   e->access == AccessType::Rwr || e->access == AccessType::Const);
      if (!fits) return SdoAbort::CannotBeMapped;
      if (auto size = e->fixed_size()) {
        // BOOLEAN maps as 1 bit (CiA 301) or as its byte.
        const bool boolean = e->basic_type == cfg::DataType::Boolean;
        if (bits != *size * 8 && !(boolean && bits == 1)) return SdoAbort::CannotBeMapped;
      } else if (bits % 8 != 0) {
        return SdoAbort::CannotBeMapped;
      }
    }
    total_bits += bits;
  }
  // CiA 301 §7.5.2.36: a classic CAN PDO carries at most 64 bits.
  if (total_bits > 64) return SdoAbort::PdoLengthExceeded;
  return SdoAbort::None;
}

SdoAbort SimulatedDevice::check_program_write(std::uint16_t index, std::uint8_t sub,
                                              std::span<const std::uint8_t> data) const {
  if (index == kProgramData && sub != 0) {
    // Program data may only replace a program that is not running.
    auto it = programs_.find(sub);
    if (it != programs_.end() && it->second == ProgramState::Running) return SdoAbort::DeviceState;
    return SdoAbort::None;
  }
  if (index == kProgramControl && sub != 0 && !data.empty()) {
    auto it = programs_.find(sub);
    const ProgramState state = it == programs_.end() ? ProgramState::NoProgram : it->second;
    // DSP 302 §9: "If the action is not possible, the Device responds with ... 0800 0024h".
    switch (data[0]) {
      case 0:  // stop
        return SdoAbort::None;
      case 1:  // start
      case 2:  // reset
        return state == ProgramState::NoProgram ? SdoAbort::NoDataAvailable : SdoAbort::None;
      case 3:  // clear (CiA 302-3): not while running
        return state == ProgramState::Running ? SdoAbort::NoDataAvailable : SdoAbort::None;
      default:
        return SdoAbort::ValueRangeExceeded;
    }
  }
  return SdoAbort::None;
}

void SimulatedDevice::set_program_state(std::uint8_t program, ProgramState state) {
  programs_[program] = state;
  dict_.set_unsigned(kProgramControl, program, static_cast<std::uint8_t>(state));
}

void SimulatedDevice::after_write(std::uint16_t index, std::uint8_t sub,
                                  std::span<const std::uint8_t> data) {
  emit(DeviceEvent::Kind::SdoWrite, now_,
       where(index, sub) + " = " + std::to_string(data.size()) + " byte(s)");

  if (index == kStoreParameters || index == kRestoreDefaults) {
    if (sub != 0) {
      if (index == kStoreParameters) {
        save(sub);
      } else {
        restore_defaults(sub);
      }
      // Reads keep telling what the device supports, not the signature.
      if (auto factory = factory_.get_bytes(index, sub)) dict_.set_bytes(index, sub, *factory);
    }
    return;
  }
  // DSP 302 §6.3: changing a boot-up configuration value invalidates 1020h.
  if (index != kVerifyConfiguration && is_stored_parameter(index, sub)) {
    dict_.set_unsigned(kVerifyConfiguration, 1, 0);
    dict_.set_unsigned(kVerifyConfiguration, 2, 0);
  }

  switch (index) {
    case kProducerHeartbeat:
      heartbeat_.set_period(static_cast<std::uint16_t>(le32(data)), now_);
      break;
    case kGuardTime:
    case kLifeTimeFactor:
      guarding_.configure(
          static_cast<std::uint16_t>(dict_.get_unsigned(kGuardTime, 0).value_or(0)),
          static_cast<std::uint8_t>(dict_.get_unsigned(kLifeTimeFactor, 0).value_or(0)));
      break;
    case kEmcyCobId:
      emcy_.set_cob_id(le32(data));
      break;
    case kEmcyInhibit:
      emcy_.set_inhibit_time(static_cast<std::uint16_t>(le32(data)));
      break;
    case kConsumerHeartbeat:
      if (sub != 0) restart_consumer();
      break;
    case kProgramControl:
      if (sub != 0 && !data.empty()) {
        static constexpr std::array<ProgramState, 4> kAfter{
            ProgramState::Stopped, ProgramState::Running, ProgramState::Stopped,
            ProgramState::NoProgram};
        set_program_state(sub, kAfter[data[0] & 3]);
        emit(DeviceEvent::Kind::Program, now_,
             "program " + std::to_string(sub) + " control " + std::to_string(data[0]));
      }
      break;
    case kProgramData:
      if (sub != 0) {
        set_program_state(sub, ProgramState::Stopped);
        if (dict_.entry(kProgramIdentification, sub)) {
          dict_.set_unsigned(kProgramIdentification, sub, crc32(data));
        }
        // DSP 302 §9: 1F52h verifies "the stored program number 1"; the new image's date and
        // time come from the options (unset: the simulator does not know them, 1F52h stays).
        if (sub == 1 && options_.downloaded_program_version) {
          const auto& v = *options_.downloaded_program_version;
          if (dict_.entry(kVerifyApplicationSoftware, 1)) {
            dict_.set_unsigned(kVerifyApplicationSoftware, 1, v.date_days);
          }
          if (dict_.entry(kVerifyApplicationSoftware, 2)) {
            dict_.set_unsigned(kVerifyApplicationSoftware, 2, v.time_ms);
          }
        }
        emit(DeviceEvent::Kind::Program, now_,
             "program " + std::to_string(sub) + " downloaded, " + std::to_string(data.size()) +
                 " bytes");
      }
      break;
    default:
      break;
  }
}

void SimulatedDevice::save(std::uint8_t area) {
  std::size_t count = 0;
  for (const auto& [key, entry] : dict_.entries()) {
    if (!in_area(area, entry.index) || !is_stored_parameter(entry.index, entry.sub_index)) continue;
    stored_[key] = entry.bytes;
    ++count;
  }
  emit(DeviceEvent::Kind::Stored, now_,
       "saved " + std::to_string(count) + " parameters (1010sub" + cfg::hex_digits(area, 1) + ")");
}

void SimulatedDevice::restore_defaults(std::uint8_t area) {
  // CiA 301 §7.5.2.14: defaults become effective at the next reset; until then nothing changes.
  std::erase_if(stored_, [area](const auto& kv) { return in_area(area, kv.first >> 8 & 0xFFFF); });
  emit(DeviceEvent::Kind::Restored, now_,
       "defaults requested (1011sub" + cfg::hex_digits(area, 1) + "), effective at next reset");
}

// --- simulated bus node
// ---------------------------------------------------------------------------

void SimulatedDeviceNode::power_on() {
  device_->power_on(now());
  set_timer(device_->next_deadline());
}

void SimulatedDeviceNode::apply(
    const std::function<void(SimulatedDevice&, TimePoint, std::vector<CanFrame>&)>& fn) {
  out_.clear();
  fn(*device_, now(), out_.frames);
  flush();
}

void SimulatedDeviceNode::on_frame(const CanFrame& frame, TimePoint now) {
  out_.clear();
  device_->on_frame(frame, now, out_);
  flush();
}

void SimulatedDeviceNode::on_timer(TimePoint now) {
  out_.clear();
  device_->on_timer(now, out_);
  flush();
}

void SimulatedDeviceNode::flush() {
  for (const auto& f : out_.frames) send(f);
  out_.clear();
  set_timer(device_->next_deadline());
}

}  // namespace nmt
