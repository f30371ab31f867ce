#include "nmt/local_dictionary.hpp"

#include <algorithm>

#include "cfg/bytes.hpp"

namespace nmt {

namespace {

bool is_numeric(cfg::DataType type) {
  auto c = cfg::data_type_info(type).type_class;
  return c == cfg::TypeClass::Signed || c == cfg::TypeClass::Unsigned || c == cfg::TypeClass::Real;
}

}  // namespace

std::optional<std::size_t> DictionaryEntry::fixed_size() const {
  if (!basic_type) return std::nullopt;
  auto size = cfg::data_type_info(*basic_type).size_bytes;
  if (size == 0) return std::nullopt;
  return size;
}

cfg::Result<LocalDictionary> LocalDictionary::from_device(const cfg::DeviceDescription& device,
                                                          std::uint8_t node_id) {
  if (!cfg::is_node_id(node_id)) {
    return cfg::Error{"node-ID " + std::to_string(node_id) + " is outside 1..127"};
  }
  LocalDictionary dict;
  dict.node_id_ = cfg::NodeId::from(node_id);
  for (const auto& [index, object] : device.objects) {
    for (const auto& [sub_index, sub] : object.subs) {
      DictionaryEntry e;
      e.index = index;
      e.sub_index = sub_index;
      e.name = sub.name;
      e.data_type = sub.data_type;
      e.basic_type = sub.basic_type();
      e.access = sub.access;
      e.pdo_mapping = sub.pdo_mapping;
      const auto where = [&](std::string_view key, const std::string& text) {
        return "object " + cfg::to_string({e.index, e.sub_index}) + ": " + std::string(key) + " '" +
               text + "': ";
      };
      if (!e.basic_type) {
        // Unknown or complex type: kept as DOMAIN-like bytes; its value text cannot be read.
        e.max_size = kDefaultMaxVariableSize;
        dict.entries_.emplace(key(index, sub_index), std::move(e));
        continue;
      }
      const auto type = *e.basic_type;
      const auto fixed = e.fixed_size();
      e.max_size = fixed ? *fixed : kDefaultMaxVariableSize;
      if (const auto& text = sub.configured_value()) {
        auto value = cfg::parse_value(type, *text, node_id);
        if (!value) {
          return cfg::Error{where(sub.parameter_value ? "ParameterValue" : "DefaultValue", *text) +
                            value.error().message};
        }
        e.bytes = cfg::encode(*value);
      } else if (fixed) {
        e.bytes.assign(*fixed, 0);
      }
      if (is_numeric(type)) {
        if (sub.low_limit) {
          auto v = cfg::parse_value(type, *sub.low_limit, node_id);
          if (!v) return cfg::Error{where("LowLimit", *sub.low_limit) + v.error().message};
          e.low_limit = *v;
        }
        if (sub.high_limit) {
          auto v = cfg::parse_value(type, *sub.high_limit, node_id);
          if (!v) return cfg::Error{where("HighLimit", *sub.high_limit) + v.error().message};
          e.high_limit = *v;
        }
      }
      dict.entries_.emplace(key(index, sub_index), std::move(e));
    }
  }
  return dict;
}

const DictionaryEntry* LocalDictionary::entry(std::uint16_t index, std::uint8_t sub) const {
  auto it = entries_.find(key(index, sub));
  return it == entries_.end() ? nullptr : &it->second;
}

DictionaryEntry* LocalDictionary::find(std::uint16_t index, std::uint8_t sub) {
  auto it = entries_.find(key(index, sub));
  return it == entries_.end() ? nullptr : &it->second;
}

bool LocalDictionary::has_object(std::uint16_t index) const {
  auto it = entries_.lower_bound(key(index, 0));
  return it != entries_.end() && it->second.index == index;
}

SdoAbort LocalDictionary::read(std::uint16_t index, std::uint8_t sub,
                               std::vector<std::uint8_t>& out, TimePoint now) const {
  const auto* e = entry(index, sub);
  if (!e) return has_object(index) ? SdoAbort::SubIndexDoesNotExist : SdoAbort::ObjectDoesNotExist;
  if (!cfg::is_readable(e->access)) return SdoAbort::ReadOfWriteOnly;
  for (const auto& hook : read_hooks_) {
    if (auto code = hook(index, sub, now); code != SdoAbort::None) return code;
  }
  // The hook may have replaced the value; look it up again.
  e = entry(index, sub);
  if (!e) return SdoAbort::ObjectDoesNotExist;
  out = e->bytes;
  return SdoAbort::None;
}

SdoAbort LocalDictionary::check_write(std::uint16_t index, std::uint8_t sub,
                                      std::optional<std::size_t> size) const {
  const auto* e = entry(index, sub);
  if (!e) return has_object(index) ? SdoAbort::SubIndexDoesNotExist : SdoAbort::ObjectDoesNotExist;
  // the CiA 301 abort code table: "attempt to write a read only object" covers ro and const.
  if (!cfg::is_writable(e->access)) return SdoAbort::WriteOfReadOnly;
  if (size) {
    if (auto fixed = e->fixed_size()) {
      if (*size > *fixed) return SdoAbort::LengthTooHigh;
      if (*size < *fixed) return SdoAbort::LengthTooLow;
    } else if (*size > e->max_size) {
      return SdoAbort::LengthTooHigh;
    }
  }
  return SdoAbort::None;
}

SdoAbort LocalDictionary::check_value(const DictionaryEntry& e,
                                      std::span<const std::uint8_t> data) const {
  if (!e.basic_type) return SdoAbort::None;
  const auto type = *e.basic_type;
  const auto type_class = cfg::data_type_info(type).type_class;
  if (type_class == cfg::TypeClass::UnicodeString && data.size() % 2 != 0) {
    return SdoAbort::LengthMismatch;  // UTF-16 code units are two bytes
  }
  if (type_class == cfg::TypeClass::Boolean && data[0] > 1) return SdoAbort::ValueRangeExceeded;
  if (!e.low_limit && !e.high_limit) return SdoAbort::None;
  auto value = cfg::decode(type, data);
  if (!value) return SdoAbort::ValueRangeExceeded;
  if (e.low_limit && e.high_limit) {
    const auto order = cfg::compare_values(*e.high_limit, *e.low_limit);
    if (order && *order < 0) return SdoAbort::MaxLessThanMin;
  }
  const auto above = e.high_limit ? cfg::compare_values(*value, *e.high_limit) : -1;
  const auto below = e.low_limit ? cfg::compare_values(*value, *e.low_limit) : 1;
  if (!above || !below) return SdoAbort::ValueRangeExceeded;  // NaN is in no range
  if (*above > 0) return SdoAbort::ValueTooHigh;
  if (*below < 0) return SdoAbort::ValueTooLow;
  return SdoAbort::None;
}

SdoAbort LocalDictionary::write(std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data, TimePoint now) {
  if (auto code = check_write(index, sub, data.size()); code != SdoAbort::None) return code;
  if (auto code = check_value(*entry(index, sub), data); code != SdoAbort::None) return code;
  for (const auto& hook : write_hooks_) {
    if (auto code = hook(index, sub, data, now); code != SdoAbort::None) return code;
  }
  auto* e = find(index, sub);
  if (!e) return SdoAbort::ObjectDoesNotExist;  // a hook removed it
  e->bytes.assign(data.begin(), data.end());
  // Observers get a copy's view: an observer may change this entry.
  const std::vector<std::uint8_t> stored = e->bytes;
  for (const auto& observer : observers_) observer(index, sub, stored, now);
  return SdoAbort::None;
}

std::optional<std::span<const std::uint8_t>> LocalDictionary::get_bytes(std::uint16_t index,
                                                                        std::uint8_t sub) const {
  const auto* e = entry(index, sub);
  if (!e) return std::nullopt;
  return std::span<const std::uint8_t>(e->bytes);
}

std::optional<std::uint64_t> LocalDictionary::get_unsigned(std::uint16_t index,
                                                           std::uint8_t sub) const {
  const auto* e = entry(index, sub);
  if (!e || !e->basic_type) return std::nullopt;
  auto c = cfg::data_type_info(*e->basic_type).type_class;
  if (c != cfg::TypeClass::Boolean && c != cfg::TypeClass::Signed &&
      c != cfg::TypeClass::Unsigned) {
    return std::nullopt;
  }
  const std::size_t size = std::min<std::size_t>(e->bytes.size(), 8);
  return size == 0 ? 0 : cfg::load_le(e->bytes, size);
}

std::optional<cfg::CobId> LocalDictionary::get_cob_id(std::uint16_t index, std::uint8_t sub) const {
  const auto word = get_unsigned(index, sub);
  if (!word || *word > 0xFFFFFFFFu) return std::nullopt;
  return cfg::CobId::from_word(static_cast<std::uint32_t>(*word));
}

std::optional<cfg::Value> LocalDictionary::get_value(std::uint16_t index, std::uint8_t sub) const {
  const auto* e = entry(index, sub);
  if (!e || !e->basic_type) return std::nullopt;
  auto v = cfg::decode(*e->basic_type, e->bytes);
  if (!v) return std::nullopt;
  return std::move(v).value();
}

bool LocalDictionary::set_bytes(std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data) {
  auto* e = find(index, sub);
  if (!e) return false;
  e->bytes.assign(data.begin(), data.end());
  return true;
}

bool LocalDictionary::set_unsigned(std::uint16_t index, std::uint8_t sub, std::uint64_t value) {
  auto* e = find(index, sub);
  if (!e) return false;
  auto size = e->fixed_size();
  if (!size) return false;
  e->bytes.assign(*size, 0);
  cfg::store_le(value, e->bytes, std::min<std::size_t>(*size, 8));
  return true;
}

bool LocalDictionary::set_max_size(std::uint16_t index, std::uint8_t sub, std::size_t max_size) {
  auto* e = find(index, sub);
  if (!e || e->fixed_size()) return false;
  e->max_size = max_size;
  return true;
}

void LocalDictionary::insert(DictionaryEntry entry) {
  if (entry.max_size == 0) {
    auto fixed = entry.fixed_size();
    entry.max_size = fixed ? *fixed : kDefaultMaxVariableSize;
  }
  auto k = key(entry.index, entry.sub_index);
  entries_.insert_or_assign(k, std::move(entry));
}

}  // namespace nmt
