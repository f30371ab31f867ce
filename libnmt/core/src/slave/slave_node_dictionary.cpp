// SlaveNode, its dictionary side: the write rules its hooks apply (CiA 301 communication
// objects through libcfg, program control DSP 302 §9), what a stored write does to the node's
// parts, and parameter storage (1010h/1011h, the restore at a reset). The node's behaviour where
// CiA 301 leaves room is listed at the top of nmt/slave/slave_node.hpp.
#include <array>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/cob_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/write_acceptance.hpp"
#include "nmt/slave/slave_node.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

bool is_program_object(std::uint16_t index) {
  return index >= obj::kProgramData && index <= obj::kFlashStatusIdentification;
}

bool in_range(std::uint16_t index, std::uint16_t first, std::uint16_t last) {
  return index >= first && index <= last;
}

// 1010h/1011h sub-index -> which indices it covers (CiA 301 §7.5.2.13).
bool in_area(std::uint8_t area, std::uint16_t index) {
  switch (area) {
    case 2:
      return in_range(index, obj::kCommunicationAreaFirst, obj::kCommunicationAreaLast);
    case 3:
      return in_range(index, obj::kProfileAreaFirst, obj::kProfileAreaLast);
    case 4:
      return in_range(index, obj::kManufacturerAreaFirst, obj::kManufacturerAreaLast);
    default:
      return true;  // 1: all parameters; 05h-7Fh manufacturer-specific: taken as all
  }
}

}  // namespace

void SlaveNode::restore(ResetScope scope) {
  std::vector<cfg::ObjectAddress> addresses;
  addresses.reserve(dict_.entries().size());
  for (const auto& [key, entry] : dict_.entries())
    addresses.push_back({entry.index, entry.sub_index});
  for (auto [index, sub] : addresses) {
    if (is_program_object(index)) continue;  // the program has its own memory
    if (scope == ResetScope::Communication &&
        !in_range(index, obj::kCommunicationAreaFirst, obj::kCommunicationAreaLast)) {
      continue;
    }
    auto stored = stored_.find(LocalDictionary::key(index, sub));
    if (stored != stored_.end()) {
      dict_.set_bytes(index, sub, stored->second);
    } else if (auto factory = factory_.get_bytes(index, sub)) {
      dict_.set_bytes(index, sub, *factory);
    }
  }
}

// --- dictionary hooks
// -----------------------------------------------------------------------------

bool SlaveNode::is_stored_parameter(std::uint16_t index, std::uint8_t sub) const {
  if (index == obj::kStoreParameters || index == obj::kRestoreDefaultParameters ||
      is_program_object(index)) {
    return false;
  }
  const DictionaryEntry* e = dict_.entry(index, sub);
  return e != nullptr && cfg::is_writable(e->access);
}

SdoAbort SlaveNode::check_write(std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data) const {
  // CiA 301's rules of the communication objects (signatures, COB-IDs, consumer heartbeat, PDO
  // parameters and mapping): libcfg's, which `cfgmgr check` applies to a file's download.
  const cfg::DeviceWriteRules rules{&description_.dummy_usage};
  if (auto verdict = cfg::check_object_rules(dict_.entries(), rules, index, sub, data);
      !verdict.accepted()) {
    return verdict.code;
  }
  return check_program_write(index, sub, data);
}

SdoAbort SlaveNode::check_program_write(std::uint16_t index, std::uint8_t sub,
                                        std::span<const std::uint8_t> data) const {
  if (index == obj::kProgramData && sub != 0) {
    // Program data may only replace a program that is not running.
    auto it = programs_.find(sub);
    if (it != programs_.end() && it->second == ProgramState::Running) return SdoAbort::DeviceState;
    return SdoAbort::None;
  }
  if (index == obj::kProgramControl && sub != 0 && !data.empty()) {
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

void SlaveNode::set_program_state(std::uint8_t program, ProgramState state) {
  programs_[program] = state;
  dict_.set_unsigned(obj::kProgramControl, program, static_cast<std::uint8_t>(state));
  program_state_changed(program, state);  // program_memory.cpp
}

void SlaveNode::after_write(std::uint16_t index, std::uint8_t sub,
                            std::span<const std::uint8_t> data, TimePoint now, HookOutput hooks) {
  // The events go into the output of the call the write runs in; a write outside any call of
  // the node (its owner setting a value up) has no one to tell.
  if (hooks.as<SlaveEvent>() == nullptr) scratch_.outside.clear();
  Output& out = hooks.as<SlaveEvent>() != nullptr ? *hooks.as<SlaveEvent>() : scratch_.outside;
  emit(out, SlaveEvent::Kind::SdoWrite, now,
       cfg::to_string(cfg::ObjectAddress{index, sub}) + " = " + std::to_string(data.size()) +
           " byte(s)",
       cfg::ObjectAddress{index, sub});

  if (index == obj::kStoreParameters || index == obj::kRestoreDefaultParameters) {
    if (sub != 0) {
      if (index == obj::kStoreParameters) {
        save(sub, now, out);
      } else {
        restore_defaults(sub, now, out);
      }
      // Reads keep telling what the device supports, not the signature.
      if (auto factory = factory_.get_bytes(index, sub)) dict_.set_bytes(index, sub, *factory);
    }
    return;
  }
  // DSP 302 §6.3: changing a boot-up configuration value invalidates 1020h.
  if (index != obj::kVerifyConfiguration && is_stored_parameter(index, sub)) {
    dict_.set_unsigned(obj::kVerifyConfiguration, 1, 0);
    dict_.set_unsigned(obj::kVerifyConfiguration, 2, 0);
  }

  if (obj::is_sdo_server_parameter(index) && (sub == 1 || sub == 2)) {
    // Takes effect without a reset (CiA 301 §7.5.2.33); inside an SDO call after its answer.
    sdo_changed_ = true;
    if (!in_sdo_) reconfigure_sdo_channels();
  }

  switch (index) {
    case obj::kProducerHeartbeatTime:
      heartbeat_.set_period(static_cast<std::uint16_t>(cfg::low_le32(data)), now);
      break;
    case obj::kGuardTime:
    case obj::kLifeTimeFactor:
      guarding_.configure(
          static_cast<std::uint16_t>(dict_.get_unsigned(obj::kGuardTime, 0).value_or(0)),
          static_cast<std::uint8_t>(dict_.get_unsigned(obj::kLifeTimeFactor, 0).value_or(0)));
      break;
    case obj::kCobIdEmcy:
      emcy_.set_cob_id(cfg::CobId::from_word(cfg::low_le32(data)));
      break;
    case obj::kInhibitTimeEmcy:
      emcy_.set_inhibit_time(static_cast<std::uint16_t>(cfg::low_le32(data)));
      break;
    case obj::kConsumerHeartbeatTime:
      if (sub != 0) restart_consumer(now);
      break;
    case obj::kProgramControl:
      if (sub != 0 && !data.empty()) {
        static constexpr std::array<ProgramState, 4> kAfter{
            ProgramState::Stopped, ProgramState::Running, ProgramState::Stopped,
            ProgramState::NoProgram};
        set_program_state(sub, kAfter[data[0] & 3]);
        emit(out, SlaveEvent::Kind::Program, now,
             "program " + std::to_string(sub) + " control " + std::to_string(data[0]));
      }
      break;
    case obj::kProgramData:
      if (sub != 0) program_downloaded(sub, data, now, out);  // program_memory.cpp
      break;
    default:
      break;
  }
}

void SlaveNode::save(std::uint8_t area, TimePoint now, Output& out) {
  std::size_t count = 0;
  for (const auto& [key, entry] : dict_.entries()) {
    if (!in_area(area, entry.index) || !is_stored_parameter(entry.index, entry.sub_index)) continue;
    stored_[key] = entry.bytes;
    ++count;
  }
  emit(out, SlaveEvent::Kind::Stored, now,
       "saved " + std::to_string(count) + " parameters (" +
           cfg::to_string(cfg::ObjectAddress{obj::kStoreParameters, area}) + ")");
}

void SlaveNode::set_stored(std::map<std::uint32_t, std::vector<std::uint8_t>> values) {
  std::erase_if(values, [this](const auto& kv) {
    return !is_stored_parameter(static_cast<std::uint16_t>(kv.first >> 8),
                                static_cast<std::uint8_t>(kv.first & 0xFF));
  });
  stored_ = std::move(values);
}

void SlaveNode::set_lss_stored(std::optional<LssStoredConfig> stored) {
  if (lss_) lss_stored_ = stored;
}

void SlaveNode::restore_defaults(std::uint8_t area, TimePoint now, Output& out) {
  // CiA 301 §7.5.2.14: defaults become effective at the next reset; until then nothing changes.
  std::erase_if(stored_, [area](const auto& kv) { return in_area(area, kv.first >> 8 & 0xFFFF); });
  emit(out, SlaveEvent::Kind::Restored, now,
       "defaults requested (" +
           cfg::to_string(cfg::ObjectAddress{obj::kRestoreDefaultParameters, area}) +
           "), effective at next reset");
}

}  // namespace nmt
