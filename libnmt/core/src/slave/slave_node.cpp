#include "nmt/slave/slave_node.hpp"

#include <cstdlib>
#include <utility>

#include "cfg/cob_id.hpp"
#include "cfg/hex.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/network.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "slave/process_picture.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

// The frames a part sent, in order, into the node's output (its events the node handles).
template <class Part>
void forward_frames(const Outbox<Part>& part, SlaveNode::Output& out) {
  out.frames.insert(out.frames.end(), part.frames.begin(), part.frames.end());
}

// The device's dictionary for `node_id`. CiA 305: the LSS address is 1018h sub 1-4, and a DCF's
// [DeviceComissioning] LSS_SerialNumber is the serial number of that address (cfg::identity_of,
// which the master's expected 1F88h comes from): the device answers an SDO read of 1018h sub 4
// with the number it answers LSS with, one value, not the file's 1018h sub 4 beside it. A file
// whose 1018h has no sub 4 gets one (UNSIGNED32, ro, CiA 301 §7.5.2.18).
cfg::Result<LocalDictionary> device_dictionary(const cfg::DeviceDescription& description,
                                               cfg::NodeId node_id) {
  auto dict = LocalDictionary::from_device(description, node_id);
  if (!dict || !description.commissioning || !description.commissioning->lss_serial_number) {
    return dict;
  }
  const std::uint32_t serial = *description.commissioning->lss_serial_number;
  LocalDictionary& d = dict.value();
  if (d.entry(obj::kIdentity, 4) == nullptr && d.has_object(obj::kIdentity)) {
    DictionaryEntry entry;
    entry.index = obj::kIdentity;
    entry.sub_index = 4;
    entry.name = "Serial number";
    entry.data_type = static_cast<std::uint16_t>(cfg::DataType::Unsigned32);
    entry.basic_type = cfg::DataType::Unsigned32;
    entry.access = cfg::AccessType::Ro;
    entry.max_size = 4;
    d.insert(std::move(entry));
    if (d.get_unsigned(obj::kIdentity, 0).value_or(4) < 4) d.set_unsigned(obj::kIdentity, 0, 4);
  }
  d.set_unsigned(obj::kIdentity, 4, serial);
  return dict;
}

}  // namespace

std::string_view to_string(SlaveEvent::Kind kind) {
  switch (kind) {
    case SlaveEvent::Kind::Boot:
      return "boot";
    case SlaveEvent::Kind::StateChange:
      return "nmt";
    case SlaveEvent::Kind::SdoWrite:
      return "sdo-write";
    case SlaveEvent::Kind::Stored:
      return "store";
    case SlaveEvent::Kind::Restored:
      return "restore";
    case SlaveEvent::Kind::LifeGuarding:
      return "life-guarding";
    case SlaveEvent::Kind::Heartbeat:
      return "heartbeat";
    case SlaveEvent::Kind::Emergency:
      return "emcy";
    case SlaveEvent::Kind::Program:
      return "program";
    case SlaveEvent::Kind::Fault:
      return "fault";
    case SlaveEvent::Kind::Lss:
      return "lss";
  }
  return "event";
}

// --- construction --------------------------------------------------------------------------------

cfg::Result<std::unique_ptr<SlaveNode>> SlaveNode::create(const cfg::DeviceDescription& description,
                                                          cfg::NodeId node_id,
                                                          SlaveNodeOptions options) {
  auto factory = device_dictionary(description, node_id);
  if (!factory) return factory.error();
  return std::make_unique<SlaveNode>(Key{}, description, std::move(factory).value(), node_id,
                                     options);
}

cfg::Result<std::unique_ptr<SlaveNode>> SlaveNode::create_unconfigured(
    const cfg::DeviceDescription& description, SlaveNodeOptions options) {
  // The dictionary is built for node-ID 1 until LSS gives the real one (take_node_id).
  auto node = create(description, *cfg::NodeId::from(1), options);
  if (!node) return node.error();
  if (!node.value()->lss_) {
    return cfg::Error{
        "the device file does not say [DeviceInfo] LSS_Supported=1: a device "
        "without node-ID needs LSS to get one"};
  }
  node.value()->power_on_node_id_ = lss::kUnconfigured;
  return node;
}

SlaveNode::SlaveNode(Key, cfg::DeviceDescription description, LocalDictionary factory,
                     cfg::NodeId node_id, SlaveNodeOptions options)
    : description_(std::move(description)),
      factory_(std::move(factory)),
      dict_(factory_),
      options_(options),
      nmt_(node_id),
      heartbeat_(node_id),
      guarding_(node_id),
      emcy_(default_emcy_cob_id(node_id)) {
  // Programs the device file declares (1F51h sub 1..); a shipped device runs its program
  // unless the file says otherwise.
  for (const auto& [key, entry] : dict_.entries()) {
    if (entry.index != obj::kProgramControl || entry.sub_index == 0) continue;
    auto v = dict_.get_unsigned(obj::kProgramControl, entry.sub_index).value_or(1);
    programs_[entry.sub_index] = v == 0 || v == 2 ? ProgramState::Stopped
                                 : v == 3         ? ProgramState::NoProgram
                                                  : ProgramState::Running;
  }
  // CiA 301 §7.5.2.33: the default channel always, the additional ones the file declares.
  sdo_.open(obj::kSdoServerFirst, SdoServerConfig::for_node(node_id));
  add_sdo_channels();
  install_hooks();
  power_on_node_id_ = node_id;
  const std::string* lss_supported = description_.device_info.find("LSS_Supported");
  if (lss_supported != nullptr && std::strtoul(lss_supported->c_str(), nullptr, 0) != 0) {
    // CiA 305: the LSS address is the identity object (cfg::identity_of: where 1018h has no
    // value [DeviceInfo] gives it, and a DCF's LSS_SerialNumber is sub 4, which the dictionary
    // answers too, device_dictionary), as the identity a simulated device answers and a master
    // derived from the same file expects.
    const cfg::DeviceIdentity identity = cfg::identity_of(description_, node_id);
    const LssAddress address{identity.vendor_id.value_or(0), identity.product_code.value_or(0),
                             identity.revision_number.value_or(0),
                             identity.serial_number.value_or(0)};
    lss_.emplace(address, node_id);
  }
}

SlaveNode::~SlaveNode() = default;

std::vector<std::uint16_t> SlaveNode::sdo_server_channels() const {
  return sdo_.indices();
}

const SdoServerConfig* SlaveNode::sdo_config(std::uint16_t index) const {
  const SdoServer* server = sdo_.find(index);
  return server != nullptr ? &server->config() : nullptr;
}

bool SlaveNode::sdo_busy(std::uint16_t index) const {
  const SdoServer* server = sdo_.find(index);
  return server != nullptr && server->busy();
}

void SlaveNode::add_sdo_channels() {
  // Entries a device model inserted after creation (LocalDictionary::insert) count too.
  for (std::uint16_t index = obj::kSdoServerFirst + 1; index <= obj::kSdoServerLast; ++index) {
    if (dict_.has_object(index)) sdo_.open_from_dictionary(index, options_.sdo_server_timeout);
  }
}

void SlaveNode::reconfigure_sdo_channels() {
  sdo_changed_ = false;
  add_sdo_channels();
  // Only a changed channel restarts (set_config drops its transfer in progress).
  sdo_.reconfigure(options_.sdo_server_timeout, false);
}

void SlaveNode::install_hooks() {
  dict_.add_write_hook([this](std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data,
                              TimePoint) { return check_write(index, sub, data); });
  dict_.add_write_observer([this](std::uint16_t index, std::uint8_t sub,
                                  std::span<const std::uint8_t> data, TimePoint now,
                                  HookOutput hooks) { after_write(index, sub, data, now, hooks); });
  // CiA DSP 302 §8.3: 1F70h of a programmable device (process_picture.hpp).
  detail::install_process_picture(dict_, description_);
}

void SlaveNode::set_options(SlaveNodeOptions options) {
  const bool timeout_changed = options.sdo_server_timeout != options_.sdo_server_timeout;
  options_ = options;
  if (timeout_changed) sdo_.reconfigure(options_.sdo_server_timeout, false);
}

std::optional<ProgramState> SlaveNode::program_state(std::uint8_t program) const {
  auto it = programs_.find(program);
  if (it == programs_.end()) return std::nullopt;
  return it->second;
}

void SlaveNode::emit(Output& out, SlaveEvent::Kind kind, TimePoint at, std::string text,
                     std::optional<cfg::ObjectAddress> object) {
  out.report(SlaveEvent{kind, at, std::move(text), object});
}

void SlaveNode::sync_parts() {
  // The parts send what the NMT slave's state allows and announce that state.
  heartbeat_.set_state(nmt_.state());
  guarding_.set_state(nmt_.state());
  emcy_.set_allowed(nmt_.services().emcy);
}

// --- resets
// ---------------------------------------------------------------------------------------

void SlaveNode::start(TimePoint now, Output& out) {
  powered_ = true;
  // The NMT slave's power-on sends nothing (finish_initialisation() does); forwarded all the same.
  auto& nmt_out = scratch_.nmt;
  nmt_out.clear();
  if (lss_) {
    const std::uint8_t id = lss_stored_ ? lss_stored_->node_id : power_on_node_id_;
    lss_->start(id, lss_stored_ ? std::optional(lss_stored_->bit_timing_index) : std::nullopt);
    if (id == lss::kUnconfigured) {
      nmt_.start(now, nmt_out);
      forward_frames(nmt_out, out);
      become_unconfigured(now);
      return;
    }
    unconfigured_ = false;
    if (id != nmt_.node_id()) {
      // LssSlave holds 1..127 or FFh (handled above); another byte is not taken.
      if (const auto node = cfg::NodeId::from(id)) {
        take_node_id(*node, ResetScope::Application, now, out);
      }
      return;
    }
  }
  nmt_.start(now, nmt_out);
  forward_frames(nmt_out, out);
  enter_initialisation(ResetScope::Application, now);
}

void SlaveNode::become_unconfigured(TimePoint now) {
  // Parameters load as at any reset; then the node waits for LSS without boot-up.
  unconfigured_ = true;
  enter_initialisation(ResetScope::Application, now);
  boot_at_.reset();
}

void SlaveNode::take_node_id(cfg::NodeId id, ResetScope scope, TimePoint now, Output& out) {
  auto factory = device_dictionary(description_, id);
  if (!factory) return;  // the file built a dictionary before: not for another node-ID only
  // $NODEID values (COB-IDs) of the new node-ID; stored values keep what was stored.
  factory_ = std::move(factory).value();
  dict_.set_node_id(id);  // the default SDO channel (600h/580h + node-ID) follows
  nmt_ = NmtSlave(id);
  unconfigured_ = false;
  lss_->activate_pending_node_id();
  emit(out, SlaveEvent::Kind::Lss, now, "LSS: node-ID " + std::to_string(id.value()));
  enter_initialisation(scope, now);
}

bool SlaveNode::on_lss_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto& lss_out = scratch_.lss;
  lss_out.clear();
  const bool taken = lss_->on_frame(frame, now, lss_out);
  forward_frames(lss_out, out);
  for (const auto& e : lss_out.events) {
    emit(out, SlaveEvent::Kind::Lss, now, e.text);
    if (e.kind == LssSlaveEvent::Kind::StoreRequested) {
      lss_stored_ =
          LssStoredConfig{e.node_id, e.bit_timing_index.value_or(lss_->bit_timing_index())};
    }
    // CiA 305 (CANopenNode): a device without node-ID starts with the one it got.
    if (e.kind == LssSlaveEvent::Kind::NodeIdActivate && unconfigured_) {
      if (const auto node = cfg::NodeId::from(e.node_id)) {
        take_node_id(*node, ResetScope::Application, now, out);
      }
    }
  }
  return taken;
}

void SlaveNode::enter_initialisation(ResetScope scope, TimePoint now) {
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
  configure_services(now);
  heartbeat_.stop();
  boot_at_ = now;
  communication_errors_ = 0;
}

void SlaveNode::configure_services(TimePoint now) {
  add_sdo_channels();
  sdo_.reconfigure(options_.sdo_server_timeout, true);  // drops transfers without a frame
  sdo_changed_ = false;

  heartbeat_.set_node_id(nmt_.node_id());
  heartbeat_.set_period(
      static_cast<std::uint16_t>(dict_.get_unsigned(obj::kProducerHeartbeatTime, 0).value_or(0)),
      now);
  guarding_.set_node_id(nmt_.node_id());
  guarding_.configure(
      static_cast<std::uint16_t>(dict_.get_unsigned(obj::kGuardTime, 0).value_or(0)),
      static_cast<std::uint8_t>(dict_.get_unsigned(obj::kLifeTimeFactor, 0).value_or(0)));
  guarding_.reset();

  const auto emcy_cob_id = dict_.get_unsigned(obj::kCobIdEmcy, 0);
  emcy_.set_cob_id(emcy_cob_id ? cfg::CobId::from_word(static_cast<std::uint32_t>(*emcy_cob_id))
                               : default_emcy_cob_id(nmt_.node_id()));
  emcy_.set_inhibit_time(
      static_cast<std::uint16_t>(dict_.get_unsigned(obj::kInhibitTimeEmcy, 0).value_or(0)));
  emcy_.reset();
  restart_consumer(now);
}

void SlaveNode::restart_consumer(TimePoint now) {
  consumer_.stop_all();
  for (std::uint8_t sub = 1; sub != 0 && dict_.entry(obj::kConsumerHeartbeatTime, sub); ++sub) {
    auto value = dict_.get_unsigned(obj::kConsumerHeartbeatTime, sub).value_or(0);
    consumer_.monitor(HeartbeatConsumerEntry::decode(static_cast<std::uint32_t>(value)), now);
  }
}

// --- engine
// ---------------------------------------------------------------------------------------

bool SlaveNode::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!powered_) return false;
  if (lss_ && lss::is_lss_frame(frame, lss::kMasterCobId)) return on_lss_frame(frame, now, out);
  if (unconfigured_ || nmt_.state() == NmtState::Initialising) return false;  // not on the bus

  auto& nmt_out = scratch_.nmt;
  nmt_out.clear();
  if (nmt_.on_frame(frame, now, nmt_out)) {
    for (const auto& t : nmt_out.events) apply_nmt(t, now, out);
    return true;
  }
  const NmtServices services = nmt_.services();
  sync_parts();
  bool taken = false;

  if (services.sdo && !frame.rtr && !frame.error) {
    auto& sdo_out = scratch_.sdo;
    sdo_out.clear();
    in_sdo_ = true;
    taken = sdo_.on_frame(frame, now, sdo_out, HookOutput(out)).has_value();
    in_sdo_ = false;
    forward_frames(sdo_out, out);
    if (sdo_changed_) reconfigure_sdo_channels();
  }

  if (services.error_control) {
    // CiA 301 §7.2.8.1: a device uses heartbeat when 1017h is not 0, node guarding otherwise.
    if (heartbeat_.period_ms() == 0) {
      auto& guarding_out = scratch_.guarding;
      guarding_out.clear();
      taken = guarding_.on_frame(frame, now, guarding_out) || taken;
      forward_frames(guarding_out, out);
      for (auto event : guarding_out.events) {
        if (event != LifeGuardingEvent::Resolved) continue;
        emit(out, SlaveEvent::Kind::LifeGuarding, now, "life guarding resolved");
        communication_recovered("life guarding", now, out);
      }
    }
    auto& consumer_out = scratch_.consumer;
    consumer_out.clear();
    taken = consumer_.on_frame(frame, now, consumer_out) || taken;
    for (const auto& ev : consumer_out.events) {
      if (ev.kind != HeartbeatEventKind::Resolved) continue;
      emit(out, SlaveEvent::Kind::Heartbeat, now,
           "heartbeat of node " + std::to_string(ev.node_id) + " resolved");
      communication_recovered("heartbeat", now, out);
    }
  }
  return taken;
}

void SlaveNode::apply_nmt(const NmtTransition& t, TimePoint now, Output& out) {
  emit(out, SlaveEvent::Kind::StateChange, now,
       std::string(to_string(t.command)) + ": " + std::string(to_string(t.from)) + " -> " +
           std::string(t.reset ? to_string(*t.reset) : to_string(t.to)));
  if (!t.reset) return;
  // CiA 305: a node-ID configured by LSS takes effect at the reset.
  if (lss_ && lss_->pending_node_id() != lss_->active_node_id()) {
    if (lss_->pending_node_id() == lss::kUnconfigured) {
      lss_->activate_pending_node_id();
      emit(out, SlaveEvent::Kind::Lss, now, "LSS: no node-ID");
      become_unconfigured(now);
      return;
    }
    if (const auto node = cfg::NodeId::from(lss_->pending_node_id())) {
      take_node_id(*node, *t.reset, now, out);
    }
    return;
  }
  enter_initialisation(*t.reset, now);
}

void SlaveNode::on_timer(TimePoint now, Output& out) {
  if (!powered_ || unconfigured_) return;
  if (boot_at_ && now >= *boot_at_) {
    boot_at_.reset();
    auto& nmt_out = scratch_.nmt;
    nmt_out.clear();
    nmt_.finish_initialisation(now, nmt_out);
    forward_frames(nmt_out, out);
    heartbeat_.on_boot_up(now);
    emit(out, SlaveEvent::Kind::Boot, now, "boot-up");
  }
  if (nmt_.state() != NmtState::Initialising) {
    sync_parts();
    auto& heartbeat_out = scratch_.heartbeat;
    heartbeat_out.clear();
    heartbeat_.on_timer(now, heartbeat_out);
    forward_frames(heartbeat_out, out);

    auto& guarding_out = scratch_.guarding;
    guarding_out.clear();
    guarding_.on_timer(now, guarding_out);
    for (auto event : guarding_out.events) {
      if (event != LifeGuardingEvent::Occurred) continue;
      emit(out, SlaveEvent::Kind::LifeGuarding, now, "life guarding event");
      communication_error("life guarding", now, out);
    }
    auto& consumer_out = scratch_.consumer;
    consumer_out.clear();
    consumer_.on_timer(now, consumer_out);
    for (const auto& ev : consumer_out.events) {
      emit(out, SlaveEvent::Kind::Heartbeat, now,
           "heartbeat of node " + std::to_string(ev.node_id) + " timed out");
      communication_error("heartbeat", now, out);
    }
    // The error behaviour above may have changed the state.
    sync_parts();
    auto& emcy_out = scratch_.emcy;
    emcy_out.clear();
    emcy_.on_timer(now, emcy_out);
    forward_frames(emcy_out, out);
    auto& sdo_out = scratch_.sdo;
    sdo_out.clear();
    sdo_.on_timer(now, sdo_out);
    // Stopped: a transfer that times out now is not answered.
    if (nmt_.services().sdo) forward_frames(sdo_out, out);
  }
}

std::optional<TimePoint> SlaveNode::next_deadline() const {
  if (!powered_ || unconfigured_) return std::nullopt;
  std::optional<TimePoint> next = boot_at_;
  if (nmt_.state() != NmtState::Initialising) {
    next = earliest(next, heartbeat_.next_deadline());
    next = earliest(next, guarding_.next_deadline());
    next = earliest(next, consumer_.next_deadline());
    next = earliest(next, emcy_.next_deadline());
    next = earliest(next, sdo_.next_deadline());
  }
  return next;
}

// --- errors and emergencies
// -----------------------------------------------------------------------

std::uint8_t SlaveNode::error_register() const {
  return static_cast<std::uint8_t>(dict_.get_unsigned(obj::kErrorRegister, 0).value_or(0));
}

void SlaveNode::set_error_register(std::uint8_t value) {
  dict_.set_unsigned(obj::kErrorRegister, 0, value);
}

void SlaveNode::send_emcy(const Emergency& emcy, TimePoint now, Output& out) {
  sync_parts();
  auto& emcy_out = scratch_.emcy;
  emcy_out.clear();
  // Not sent is what CiA 301 asks of a node whose state forbids EMCY (or whose 1014h is
  // invalid, or whose queue is full): the producer counts it (EmcyProducer::dropped()); the
  // node's error register and 1003h keep the error either way.
  (void)emcy_.raise(emcy, now, emcy_out);
  forward_frames(emcy_out, out);
}

void SlaveNode::raise_emergency(std::uint16_t error_code, std::uint8_t error_register_bits,
                                TimePoint now, Output& out) {
  if (!powered_ || nmt_.state() == NmtState::Initialising) return;
  // CiA 301 §7.5.2.2: the generic bit is set whenever any error is present.
  const auto reg = static_cast<std::uint8_t>(
      error_register() | error_register_bits |
      (error_code != emcy_code::kErrorReset ? error_register::kGeneric : 0));
  set_error_register(reg);
  emit(out, SlaveEvent::Kind::Emergency, now,
       "EMCY " + cfg::hex_digits(error_code, 4) + " register " + cfg::hex_digits(reg, 2));
  send_emcy({error_code, reg, {}}, now, out);
}

void SlaveNode::communication_error(const std::string& what, TimePoint now, Output& out) {
  ++communication_errors_;
  const auto reg = static_cast<std::uint8_t>(error_register() | error_register::kGeneric |
                                             error_register::kCommunication);
  set_error_register(reg);
  // spec/002: "Node 1 send an EMCY indicating the lifeguard error" (8130h).
  emit(out, SlaveEvent::Kind::Emergency, now,
       "EMCY " + cfg::hex_digits(emcy_code::kLifeGuardOrHeartbeat, 4) + " (" + what + ")");
  send_emcy({emcy_code::kLifeGuardOrHeartbeat, reg, {}}, now, out);
  // CiA 301 §7.5.2.32 (1029h sub 1): 0 pre-operational (only from operational), 1 no change,
  // 2 stopped. Devices without 1029h stay where they are.
  if (auto behaviour = dict_.get_unsigned(obj::kErrorBehaviour, 1)) {
    if (*behaviour == 0 && nmt_.state() == NmtState::Operational) {
      nmt_.set_state(NmtState::PreOperational);
      emit(out, SlaveEvent::Kind::StateChange, now,
           "error behaviour: operational -> pre-operational");
    } else if (*behaviour == 2 && nmt_.state() != NmtState::Stopped) {
      emit(out, SlaveEvent::Kind::StateChange, now,
           "error behaviour: " + std::string(to_string(nmt_.state())) + " -> stopped");
      nmt_.set_state(NmtState::Stopped);
    }
  }
}

void SlaveNode::communication_recovered(const std::string& what, TimePoint now, Output& out) {
  if (communication_errors_ == 0) return;
  if (--communication_errors_ > 0) return;
  const auto reg = static_cast<std::uint8_t>(
      error_register() & ~(error_register::kCommunication | error_register::kGeneric));
  set_error_register(reg);
  // CiA 301 §7.2.7.1: error code 0000h tells that an error condition has gone.
  emit(out, SlaveEvent::Kind::Emergency, now,
       "EMCY " + cfg::hex_digits(emcy_code::kErrorReset, 4) + " (" + what + " recovered)");
  send_emcy({emcy_code::kErrorReset, reg, {}}, now, out);
}

}  // namespace nmt
