#include "nmt/slave/local_dictionary.hpp"

#include <algorithm>

#include "cfg/bytes.hpp"

namespace nmt {

cfg::Result<LocalDictionary> LocalDictionary::from_device(const cfg::DeviceDescription& device,
                                                          cfg::NodeId node_id) {
  auto entries = cfg::device_entries(device, node_id);
  if (!entries) return entries.error();
  LocalDictionary dict;
  dict.node_id_ = node_id;
  dict.entries_ = std::move(entries).value();
  return dict;
}

const DictionaryEntry* LocalDictionary::entry(std::uint16_t index, std::uint8_t sub) const {
  return cfg::find_entry(entries_, index, sub);
}

DictionaryEntry* LocalDictionary::find(std::uint16_t index, std::uint8_t sub) {
  auto it = entries_.find(key(index, sub));
  return it == entries_.end() ? nullptr : &it->second;
}

bool LocalDictionary::has_object(std::uint16_t index) const {
  return cfg::has_object(entries_, index);
}

SdoAbort LocalDictionary::read(std::uint16_t index, std::uint8_t sub,
                               std::vector<std::uint8_t>& out, TimePoint now,
                               HookOutput hooks) const {
  const auto* e = entry(index, sub);
  if (!e) return has_object(index) ? SdoAbort::SubIndexDoesNotExist : SdoAbort::ObjectDoesNotExist;
  if (!cfg::is_readable(e->access)) return SdoAbort::ReadOfWriteOnly;
  for (const auto& hook : read_hooks_) {
    if (auto code = hook(index, sub, now, hooks); code != SdoAbort::None) return code;
  }
  // The hook may have replaced the value; look it up again.
  e = entry(index, sub);
  if (!e) return SdoAbort::ObjectDoesNotExist;
  out = e->bytes;
  return SdoAbort::None;
}

SdoAbort LocalDictionary::check_write(std::uint16_t index, std::uint8_t sub,
                                      std::optional<std::size_t> size) const {
  if (size && !size_hooks_.empty()) {
    if (auto code = check_write(index, sub, std::nullopt); code != SdoAbort::None) return code;
    for (const auto& hook : size_hooks_) {
      if (auto code = hook(index, sub, *size); code != SdoAbort::None) return code;
    }
  }
  return cfg::check_entry_access(entries_, index, sub, size).code;
}

SdoAbort LocalDictionary::write(std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data, TimePoint now, HookOutput out) {
  return write_download(index, sub, data, now, out).abort;
}

WriteVerdict LocalDictionary::write_download(std::uint16_t index, std::uint8_t sub,
                                             std::span<const std::uint8_t> data, TimePoint now,
                                             HookOutput out) {
  if (auto code = check_write(index, sub, data.size()); code != SdoAbort::None) return code;
  if (auto value = cfg::check_entry_value(*entry(index, sub), data); !value.accepted()) {
    return value.code;
  }
  WriteVerdict accepted;
  for (const auto& hook : write_hooks_) {
    auto verdict = hook(index, sub, data, now, out);
    if (verdict.abort != SdoAbort::None) return verdict.abort;
    if (verdict.held) accepted.held = verdict.held;
  }
  auto* e = find(index, sub);
  if (!e) return SdoAbort::ObjectDoesNotExist;  // a hook removed it
  e->bytes.assign(data.begin(), data.end());
  // Observers get a copy's view: an observer may change this entry.
  const std::vector<std::uint8_t> stored = e->bytes;
  for (const auto& observer : observers_) observer(index, sub, stored, now, out);
  return accepted;
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
  return e != nullptr ? e->unsigned_value() : std::nullopt;
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
