#include "cfg/write_acceptance.hpp"

#include <algorithm>
#include <set>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/cob_id.hpp"
#include "cfg/download_order.hpp"
#include "cfg/hex.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"

namespace cfg {

namespace obj = object;

namespace {

bool is_numeric(DataType type) {
  auto c = data_type_info(type).type_class;
  return c == TypeClass::Signed || c == TypeClass::Unsigned || c == TypeClass::Real;
}

WriteVerdict refuse(SdoAbort code, std::string reason) {
  return {code, std::move(reason)};
}

std::string type_name(const DeviceEntry& e) {
  return e.basic_type ? std::string(to_string(*e.basic_type)) : "DataType " + hex(e.data_type, 4);
}

}  // namespace

// --- the device's entries ------------------------------------------------------------------------

std::optional<std::size_t> DeviceEntry::fixed_size() const {
  if (!basic_type) return std::nullopt;
  auto size = data_type_info(*basic_type).size_bytes;
  if (size == 0) return std::nullopt;
  return size;
}

std::optional<std::uint64_t> DeviceEntry::unsigned_value() const {
  if (!basic_type) return std::nullopt;
  auto c = data_type_info(*basic_type).type_class;
  if (c != TypeClass::Boolean && c != TypeClass::Signed && c != TypeClass::Unsigned) {
    return std::nullopt;
  }
  const std::size_t size = std::min<std::size_t>(bytes.size(), 8);
  return size == 0 ? 0 : load_le(bytes, size);
}

Result<DeviceEntries> device_entries(const DeviceDescription& device, std::uint8_t node_id) {
  if (!is_node_id(node_id)) {
    return Error{"node-ID " + std::to_string(node_id) + " is outside 1..127"};
  }
  DeviceEntries entries;
  const std::optional<std::uint8_t> recorded_at = recorded_node_id(device);
  for (const auto& [index, object] : device.objects) {
    for (const auto& [sub_index, sub] : object.subs) {
      DeviceEntry e;
      e.index = index;
      e.sub_index = sub_index;
      e.name = sub.name;
      e.data_type = sub.data_type;
      e.basic_type = sub.basic_type();
      e.access = sub.access;
      e.pdo_mapping = sub.pdo_mapping;
      const auto where = [&](std::string_view key, const std::string& text) {
        return "object " + to_string({e.index, e.sub_index}) + ": " + std::string(key) + " '" +
               text + "': ";
      };
      if (!e.basic_type) {
        // Unknown or complex type: kept as DOMAIN-like bytes; its value text cannot be read.
        e.max_size = kDefaultMaxVariableSize;
        entries.emplace(ObjectAddress{index, sub_index}.key(), std::move(e));
        continue;
      }
      const auto type = *e.basic_type;
      const auto fixed = e.fixed_size();
      e.max_size = fixed ? *fixed : kDefaultMaxVariableSize;
      const OptionalText& configured = sub.configured_value();
      std::optional<std::string_view> text;
      if (configured) text = std::string_view(*configured);
      if (sub.parameter_value && sub.default_value && recorded_at &&
          is_default_at(type, *sub.default_value, *sub.parameter_value, *recorded_at)) {
        // A value of the pre-defined connection set recorded at the file's node-ID (a DCF saved
        // at node 1 says 1200h sub 1 = 0x601): the device derives it from its own node-ID
        // (CiA 301 §7.3.5), as a device that moves to another node-ID does.
        text = std::string_view(*sub.default_value);
      }
      if (text) {
        auto value = parse_value(type, *text, node_id);
        if (!value) {
          return Error{
              where(sub.parameter_value ? "ParameterValue" : "DefaultValue", std::string(*text)) +
              value.error().message};
        }
        e.bytes = encode(*value);
      } else if (fixed) {
        e.bytes.assign(*fixed, 0);
      }
      if (is_numeric(type)) {
        if (sub.low_limit) {
          auto v = parse_value(type, *sub.low_limit, node_id);
          if (!v) return Error{where("LowLimit", *sub.low_limit) + v.error().message};
          e.low_limit = *v;
        }
        if (sub.high_limit) {
          auto v = parse_value(type, *sub.high_limit, node_id);
          if (!v) return Error{where("HighLimit", *sub.high_limit) + v.error().message};
          e.high_limit = *v;
        }
      }
      entries.emplace(ObjectAddress{index, sub_index}.key(), std::move(e));
    }
  }
  return entries;
}

const DeviceEntry* find_entry(const DeviceEntries& entries, std::uint16_t index, std::uint8_t sub) {
  auto it = entries.find(ObjectAddress{index, sub}.key());
  return it == entries.end() ? nullptr : &it->second;
}

bool has_object(const DeviceEntries& entries, std::uint16_t index) {
  auto it = entries.lower_bound(ObjectAddress{index, 0}.key());
  return it != entries.end() && it->second.index == index;
}

// --- access and value ----------------------------------------------------------------------------

WriteVerdict check_entry_access(const DeviceEntries& entries, std::uint16_t index, std::uint8_t sub,
                                std::optional<std::size_t> size) {
  const DeviceEntry* e = find_entry(entries, index, sub);
  if (e == nullptr) {
    return has_object(entries, index)
               ? refuse(SdoAbort::SubIndexDoesNotExist,
                        object_name(index) + " has no sub-index " + hex_digits(sub, 2) + "h")
               : refuse(SdoAbort::ObjectDoesNotExist,
                        "the device has no object " + object_name(index));
  }
  // the CiA 301 abort code table: "attempt to write a read only object" covers ro and const.
  if (!is_writable(e->access)) {
    return refuse(SdoAbort::WriteOfReadOnly,
                  "its access type is " + std::string(to_string(e->access)));
  }
  if (!size) return {};
  const auto written = std::to_string(*size) + " byte(s) written";
  if (auto fixed = e->fixed_size()) {
    const auto has = ", its type " + type_name(*e) + " has " + std::to_string(*fixed);
    if (*size > *fixed) return refuse(SdoAbort::LengthTooHigh, written + has);
    if (*size < *fixed) return refuse(SdoAbort::LengthTooLow, written + has);
  } else if (*size > e->max_size) {
    return refuse(SdoAbort::LengthTooHigh,
                  written + ", the device holds at most " + std::to_string(e->max_size));
  }
  return {};
}

WriteVerdict check_entry_value(const DeviceEntry& e, std::span<const std::uint8_t> data) {
  if (!e.basic_type) return {};
  const auto type = *e.basic_type;
  const auto type_class = data_type_info(type).type_class;
  if (type_class == TypeClass::UnicodeString && data.size() % 2 != 0) {
    return refuse(SdoAbort::LengthMismatch, "UTF-16 code units are two bytes");
  }
  if (type_class == TypeClass::Boolean && !data.empty() && data[0] > 1) {
    return refuse(SdoAbort::ValueRangeExceeded, "a BOOLEAN is 0 or 1");
  }
  if (!e.low_limit && !e.high_limit) return {};
  auto value = decode(type, data);
  if (!value) return refuse(SdoAbort::ValueRangeExceeded, value.error().message);
  if (e.low_limit && e.high_limit) {
    const auto order = compare_values(*e.high_limit, *e.low_limit);
    if (order && *order < 0) {
      return refuse(SdoAbort::MaxLessThanMin, "its HighLimit " + describe_value(*e.high_limit) +
                                                  " is below its LowLimit " +
                                                  describe_value(*e.low_limit));
    }
  }
  const auto above = e.high_limit ? compare_values(*value, *e.high_limit) : -1;
  const auto below = e.low_limit ? compare_values(*value, *e.low_limit) : 1;
  if (!above || !below) return refuse(SdoAbort::ValueRangeExceeded, "NaN is in no range");
  if (*above > 0) {
    return refuse(SdoAbort::ValueTooHigh, describe_value(*value) + " is above its HighLimit " +
                                              describe_value(*e.high_limit));
  }
  if (*below < 0) {
    return refuse(SdoAbort::ValueTooLow, describe_value(*value) + " is below its LowLimit " +
                                             describe_value(*e.low_limit));
  }
  return {};
}

// --- the communication objects -------------------------------------------------------------------

namespace {

// CiA 301 §7.5.2.5/35/37: bits 0-29 of a COB-ID may only change while the object does not exist
// (bit 31 = 1); setting bit 31 (destroying it) is always allowed.
bool cob_id_change_allowed(std::uint64_t current, std::uint32_t written) {
  const auto value = CobId::from_word(written);
  return !CobId::from_word(static_cast<std::uint32_t>(current)).valid() || !value.valid() ||
         value.word() == current;
}

WriteVerdict refuse_cob_id_change(std::uint64_t current) {
  return refuse(SdoAbort::ValueRangeExceeded,
                "the COB-ID is valid (" + hex(current, 8) +
                    "): it may change only while bit 31 is set (CiA 301)");
}

// CiA 301 §7.4.7.1: mapping entries with a data type index (0001h-0007h) are dummies.
bool is_dummy_index(std::uint16_t index) {
  return index >= 0x0001 && index <= 0x0007;
}

std::optional<std::uint64_t> unsigned_at(const DeviceEntries& entries, std::uint16_t index,
                                         std::uint8_t sub) {
  const DeviceEntry* e = find_entry(entries, index, sub);
  return e != nullptr ? e->unsigned_value() : std::nullopt;
}

// "RPDO 2", numbered from 1 as in CiA 301.
std::string pdo_name(const obj::PdoIndices& pdo) {
  const std::uint16_t first =
      pdo.receive ? obj::kRpdoCommunicationFirst : obj::kTpdoCommunicationFirst;
  return std::string(pdo.receive ? "RPDO " : "TPDO ") + std::to_string(pdo.comm_index - first + 1);
}

class ObjectRules {
 public:
  ObjectRules(const DeviceEntries& entries, const DeviceWriteRules& rules)
      : entries_(entries), rules_(rules) {}

  WriteVerdict check(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data) {
    if (index == obj::kStoreParameters && sub != 0 && low_le32(data) != kSaveSignature) {
      // CiA 301 §7.5.2.13: wrong signature
      return refuse(SdoAbort::CannotStoreOrTransfer, "the signature is not 'save'");
    }
    if (index == obj::kRestoreDefaultParameters && sub != 0 && low_le32(data) != kLoadSignature) {
      return refuse(SdoAbort::CannotStoreOrTransfer, "the signature is not 'load'");
    }
    if (index == obj::kCobIdEmcy) {
      // CiA 301 §7.5.2.5: 0609 0030 (invalid value), as for the PDO COB-IDs.
      const auto current = unsigned_at(entries_, obj::kCobIdEmcy, 0);
      if (current && !cob_id_change_allowed(*current, low_le32(data))) {
        return refuse_cob_id_change(*current);
      }
      return {};
    }
    if (index == obj::kConsumerHeartbeatTime && sub != 0) return consumer_heartbeat(sub, data);
    if (auto verdict = pdo(index, sub, data); !verdict.accepted()) return verdict;
    return sdo_parameter(index, sub, data);
  }

 private:
  WriteVerdict consumer_heartbeat(std::uint8_t sub, std::span<const std::uint8_t> data) const {
    // CiA 301 §7.5.2.33: at most one non-zero consumer heartbeat time per node-ID; a second one
    // aborts with 0604 0043. An entry: node-ID in bits 16-23, time in ms in bits 0-15.
    const auto node_of = [](std::uint64_t v) { return static_cast<std::uint8_t>(v >> 16); };
    const auto active = [&](std::uint64_t v) { return is_node_id(node_of(v)) && (v & 0xFFFF); };
    const std::uint32_t written = low_le32(data);
    if (!active(written)) return {};
    for (std::uint8_t other = 1;
         other != 0 && find_entry(entries_, obj::kConsumerHeartbeatTime, other) != nullptr;
         ++other) {
      if (other == sub) continue;
      const auto entry = unsigned_at(entries_, obj::kConsumerHeartbeatTime, other).value_or(0);
      if (active(entry) && node_of(entry) == node_of(written)) {
        return refuse(SdoAbort::ParameterIncompatibility,
                      to_string(ObjectAddress{obj::kConsumerHeartbeatTime, other}) +
                          " already consumes the heartbeat of node " +
                          std::to_string(node_of(written)));
      }
    }
    return {};
  }

  WriteVerdict sdo_parameter(std::uint16_t index, std::uint8_t sub,
                             std::span<const std::uint8_t> data) const {
    if (!obj::is_sdo_server_parameter(index) && !obj::is_sdo_client_parameter(index)) return {};
    if (sub != 1 && sub != 2) return {};
    const auto current = unsigned_at(entries_, index, sub);
    // CiA 301 §7.5.2.33: 1200h holds the pre-defined connection set; its COB-IDs are fixed.
    // The value it has is accepted, so a tool downloading a whole DCF that declares them rw
    // succeeds.
    if (index == obj::kSdoServerFirst) {
      if (current && *current == low_le32(data) && data.size() == 4) return {};
      return refuse(SdoAbort::WriteOfReadOnly,
                    "the default SDO channel's COB-IDs are the predefined connection set (" +
                        (current ? hex(*current, 8) : std::string("unknown")) + ")");
    }
    if (current && !cob_id_change_allowed(*current, low_le32(data))) {
      return refuse_cob_id_change(*current);
    }
    return {};
  }

  WriteVerdict pdo(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data) {
    const auto pdo = obj::pdo_indices_of(index);
    if (!pdo) return {};
    const auto comm_cob_id = unsigned_at(entries_, pdo->comm_index, 1);
    const bool pdo_valid =
        comm_cob_id && CobId::from_word(static_cast<std::uint32_t>(*comm_cob_id)).valid();
    if (index == pdo->comm_index) {
      if (!pdo_valid) return {};
      if (sub == 1 && !cob_id_change_allowed(*comm_cob_id, low_le32(data))) {
        return refuse_cob_id_change(*comm_cob_id);
      }
      // CiA 301 §7.5.2.37: inhibit time (3) and SYNC start value (6) of a TPDO shall not
      // change while the PDO exists.
      if (!pdo->receive && (sub == 3 || sub == 6)) {
        const DeviceEntry* e = find_entry(entries_, index, sub);
        if (e && !std::equal(e->bytes.begin(), e->bytes.end(), data.begin(), data.end())) {
          return refuse(SdoAbort::ValueRangeExceeded,
                        std::string(sub == 3 ? "the inhibit time" : "the SYNC start value") +
                            " of " + pdo_name(*pdo) +
                            " may change only while the PDO is "
                            "invalid (COB-ID bit 31 set), and its COB-ID is " +
                            hex(*comm_cob_id, 8));
        }
      }
      return {};
    }
    // CiA 301 §7.5.2.36/38: mapping changes only while the PDO is invalid, entries only while
    // sub 0 is 0; writing sub 0 = n validates the n entries.
    if (pdo_valid) {
      return refuse(SdoAbort::DeviceState,
                    "the mapping of " + pdo_name(*pdo) +
                        " may change only while the PDO is invalid (COB-ID bit 31 set), and its "
                        "COB-ID " +
                        to_string(ObjectAddress{pdo->comm_index, 1}) + " is " +
                        hex(*comm_cob_id, 8));
    }
    if (sub != 0) {
      const auto count = unsigned_at(entries_, index, 0).value_or(0);
      if (count != 0) {
        return refuse(SdoAbort::DeviceState,
                      "a mapping entry may be written only while sub-index 0 is 0, and it is " +
                          std::to_string(count));
      }
      // CiA 301 §7.5.2.36/38 step 3: the device checks each entry as it is written (0602 0000
      // or 0604 0041). 0 clears the entry (sub 0 never counts it), so it stays accepted.
      const auto value = low_le32(data);
      if (value == 0) return {};
      const auto mapped = static_cast<std::uint16_t>(value >> 16);
      if (!is_dummy_index(mapped) && !has_object(entries_, mapped)) {
        return refuse(
            SdoAbort::ObjectDoesNotExist,
            pdo_name(*pdo) + " maps " + object_name(mapped) + ", which the device does not have");
      }
      return mapping_entry(*pdo, value).verdict;
    }
    return data.empty() ? WriteVerdict{} : mapping(*pdo, data[0]);
  }

  struct MappingCheck {
    WriteVerdict verdict;
    unsigned bits = 0;  ///< length of the mapped entry when accepted
  };

  MappingCheck mapping_entry(const obj::PdoIndices& pdo, std::uint32_t value) const {
    const auto index = static_cast<std::uint16_t>(value >> 16);
    const auto sub = static_cast<std::uint8_t>((value >> 8) & 0xFF);
    const auto bits = static_cast<unsigned>(value & 0xFF);
    const std::string what = pdo_name(pdo) + " maps " + to_string(ObjectAddress{index, sub});
    const auto cannot = [](std::string reason) {
      return MappingCheck{refuse(SdoAbort::CannotBeMapped, std::move(reason))};
    };
    if (bits == 0) return cannot(what + " with 0 bits");

    if (is_dummy_index(index) && sub == 0) {
      // Dummy mapping (CiA 301 §7.4.7.1): a data type index, allowed when [DummyUsage] says so.
      const auto* type = find_data_type(index);
      const std::string key = "Dummy" + hex_digits(index, 4);
      const std::string* usage =
          rules_.dummy_usage != nullptr ? rules_.dummy_usage->find(key) : nullptr;
      if (!pdo.receive) return cannot(what + ", a dummy entry, which only RPDOs may map");
      if (!type || !usage || *usage == "0") {
        return cannot(what + ", a dummy entry the device does not support ([DummyUsage] " + key +
                      ")");
      }
      const unsigned type_bits = index == 0x0001 ? 1U : type->size_bytes * 8U;
      if (bits != type_bits) {
        return cannot(what + " with " + std::to_string(bits) + " bits, but the dummy's type " +
                      std::string(type->name) + " has " + std::to_string(type_bits));
      }
      return {{}, bits};
    }
    const DeviceEntry* e = find_entry(entries_, index, sub);
    if (e == nullptr) return cannot(what + ", which the device does not have");
    if (!e->pdo_mapping) return cannot(what + ", which is not mappable (PDOMapping=0)");
    // CiA 306 §4.6.3: rww entries go into RPDOs, rwr entries into TPDOs.
    const bool fits = pdo.receive
                          ? (e->access == AccessType::Rw || e->access == AccessType::Wo ||
                             e->access == AccessType::Rww)
                          : (e->access == AccessType::Rw || e->access == AccessType::Ro ||
                             e->access == AccessType::Rwr || e->access == AccessType::Const);
    if (!fits) {
      return cannot(what + ", whose access type " + std::string(to_string(e->access)) +
                    (pdo.receive ? " an RPDO cannot write" : " a TPDO cannot read"));
    }
    if (auto size = e->fixed_size()) {
      // BOOLEAN maps as 1 bit (CiA 301) or as its byte.
      const bool boolean = e->basic_type == DataType::Boolean;
      if (bits != *size * 8 && !(boolean && bits == 1)) {
        return cannot(what + " with " + std::to_string(bits) + " bits, but its type " +
                      type_name(*e) + " has " + std::to_string(*size * 8));
      }
    } else if (bits % 8 != 0) {
      return cannot(what + " with " + std::to_string(bits) + " bits, not whole bytes of its " +
                    type_name(*e));
    }
    return {{}, bits};
  }

  WriteVerdict mapping(const obj::PdoIndices& pdo, std::uint8_t count) const {
    unsigned total_bits = 0;
    for (std::uint8_t i = 1; i <= count && i != 0; ++i) {
      auto value = unsigned_at(entries_, pdo.mapping_index, i);
      if (!value) {
        return refuse(SdoAbort::CannotBeMapped, pdo_name(pdo) + " has no mapping entry " +
                                                    to_string(ObjectAddress{pdo.mapping_index, i}) +
                                                    " to count");
      }
      auto check = mapping_entry(pdo, static_cast<std::uint32_t>(*value));
      if (!check.verdict.accepted()) {
        check.verdict.reason =
            to_string(ObjectAddress{pdo.mapping_index, i}) + ": " + check.verdict.reason;
        return check.verdict;
      }
      total_bits += check.bits;
    }
    // CiA 301 §7.5.2.36: a classic CAN PDO carries at most 64 bits.
    if (total_bits > 64) {
      return refuse(SdoAbort::PdoLengthExceeded,
                    "the " + std::to_string(count) + " entries of " + pdo_name(pdo) + " map " +
                        std::to_string(total_bits) + " bits, a CAN frame carries 64");
    }
    return {};
  }

  const DeviceEntries& entries_;
  const DeviceWriteRules& rules_;
};

}  // namespace

WriteVerdict check_object_rules(const DeviceEntries& entries, const DeviceWriteRules& rules,
                                std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data) {
  return ObjectRules(entries, rules).check(index, sub, data);
}

WriteVerdict check_device_write(const DeviceEntries& entries, const DeviceWriteRules& rules,
                                std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data) {
  if (auto v = check_entry_access(entries, index, sub, data.size()); !v.accepted()) return v;
  if (auto v = check_entry_value(*find_entry(entries, index, sub), data); !v.accepted()) return v;
  return check_object_rules(entries, rules, index, sub, data);
}

// --- a node's download ---------------------------------------------------------------------------

namespace {

// "0604 0041", as CiA 301 writes abort codes.
std::string abort_text(SdoAbort code) {
  const auto digits = hex_digits(static_cast<std::uint32_t>(code), 8);
  return digits.substr(0, 4) + " " + digits.substr(4);
}

// The written value as people read it: the number for up to 8 bytes, else its size.
std::string written_text(std::span<const std::uint8_t> data) {
  if (data.empty() || data.size() > 8) return std::to_string(data.size()) + " bytes";
  return hex(load_le(data, data.size()), static_cast<int>(data.size() * 2));
}

// The line of the DCF value a write comes from: ParameterValue, else DefaultValue, else the
// sub-object's section.
int line_of(const DeviceDescription& dcf, std::uint16_t index, std::uint8_t sub) {
  const SubObject* s = dcf.sub(index, sub);
  if (s == nullptr) return 0;
  if (s->parameter_value_line != 0) return s->parameter_value_line;
  if (s->default_value_line != 0) return s->default_value_line;
  return s->line;
}

}  // namespace

void check_download(const DeviceDescription& dcf, NodeId node, std::span<const ObjectWrite> writes,
                    const std::string& file, std::string_view label, Diagnostics& diagnostics) {
  auto built = device_entries(dcf, node.value());
  if (!built) return;  // a value that does not parse: the reader said so
  DeviceEntries& device = *built;
  const DeviceWriteRules rules{&dcf.dummy_usage};
  // The writes as the master orders them (CiA 302-2 §3.5 d): a PDO whose COB-ID the writes do
  // not carry gets the invalid/valid pair around its parameters with the COB-ID the master reads
  // from the device (DSP 302 §6.2; an ro COB-ID refuses it).
  const auto current_cob_id = [&device](std::uint16_t comm_index) -> std::optional<std::uint32_t> {
    const DeviceEntry* e = find_entry(device, comm_index, 1);
    const auto value = e != nullptr ? e->unsigned_value() : std::nullopt;
    if (!value) return std::nullopt;
    return static_cast<std::uint32_t>(*value);
  };
  std::set<std::uint32_t> configured;
  for (const ObjectWrite& w : writes) configured.insert(ObjectAddress{w.index, w.sub_index}.key());
  const std::vector<ObjectWrite> plan = pdo_safe_order(writes, current_cob_id);
  std::set<std::uint16_t> reported_mappings;
  std::set<std::uint32_t> reported;
  for (const ObjectWrite& w : plan) {
    const WriteVerdict verdict = check_device_write(device, rules, w.index, w.sub_index, w.data);
    if (verdict.accepted()) {
      auto it = device.find(ObjectAddress{w.index, w.sub_index}.key());
      if (it != device.end()) it->second.bytes = w.data;
      continue;
    }
    // A second refusal of one entry (the master's COB-ID pair) says the same again.
    if (!reported.insert(ObjectAddress{w.index, w.sub_index}.key()).second) continue;
    // After a refusal in a mapping, its count (which checks the entries again) and another
    // "not while the PDO is valid" say the same again.
    const auto pdo = obj::pdo_indices_of(w.index);
    const bool mapping = pdo && w.index == pdo->mapping_index;
    if (mapping && reported_mappings.contains(w.index) &&
        (w.sub_index == 0 || verdict.code == SdoAbort::DeviceState)) {
      continue;
    }
    if (mapping) reported_mappings.insert(w.index);
    std::string message(label);
    message += to_string(ObjectAddress{w.index, w.sub_index}) + " = " + written_text(w.data);
    if (!configured.contains(ObjectAddress{w.index, w.sub_index}.key())) {
      message += " (the master's, to make the PDO invalid around its parameters)";
    }
    message += ": the download will be refused with SDO abort " + abort_text(verdict.code) + ": " +
               verdict.reason +
               " (a CiA 301 device refuses this write; some vendor devices are laxer)";
    diagnostics.add(file, line_of(dcf, w.index, w.sub_index), Severity::Warning,
                    std::move(message));
  }
}

}  // namespace cfg
