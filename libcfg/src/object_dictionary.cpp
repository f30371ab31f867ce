#include "cfg/object_dictionary.hpp"

#include <algorithm>
#include <tuple>

namespace cfg {

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto lower = [](char c) {
      return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c;
    };
    if (lower(a[i]) != lower(b[i])) return false;
  }
  return true;
}

std::string_view to_string(ObjectType type) {
  switch (type) {
    case ObjectType::Null:
      return "NULL";
    case ObjectType::Domain:
      return "DOMAIN";
    case ObjectType::Deftype:
      return "DEFTYPE";
    case ObjectType::Defstruct:
      return "DEFSTRUCT";
    case ObjectType::Var:
      return "VAR";
    case ObjectType::Array:
      return "ARRAY";
    case ObjectType::Record:
      return "RECORD";
  }
  return "VAR";
}

std::optional<ObjectType> object_type_from_code(unsigned code) {
  switch (code) {
    case 0x0:
    case 0x2:
    case 0x5:
    case 0x6:
    case 0x7:
    case 0x8:
    case 0x9:
      return static_cast<ObjectType>(code);
    default:
      return std::nullopt;
  }
}

std::string_view to_string(AccessType access) {
  switch (access) {
    case AccessType::Ro:
      return "ro";
    case AccessType::Wo:
      return "wo";
    case AccessType::Rw:
      return "rw";
    case AccessType::Rwr:
      return "rwr";
    case AccessType::Rww:
      return "rww";
    case AccessType::Const:
      return "const";
  }
  return "rw";
}

std::optional<AccessType> access_type_from_string(std::string_view text) {
  // Files write it in lower case nearly always: exact matches first, then any case.
  if (text == "rw") return AccessType::Rw;
  if (text == "ro") return AccessType::Ro;
  for (auto a : {AccessType::Ro, AccessType::Wo, AccessType::Rw, AccessType::Rwr, AccessType::Rww,
                 AccessType::Const}) {
    if (iequals(text, to_string(a))) return a;
  }
  return std::nullopt;
}

bool is_writable(AccessType access) {
  return access == AccessType::Rw || access == AccessType::Wo || access == AccessType::Rwr ||
         access == AccessType::Rww;
}

bool is_readable(AccessType access) {
  return access != AccessType::Wo;
}

std::optional<DataType> SubObject::basic_type() const {
  const DataTypeInfo* info = find_data_type(data_type);
  if (info == nullptr) return std::nullopt;
  return info->type;
}

bool SubObject::operator==(const SubObject& o) const {
  auto tie = [](const SubObject& s) {
    return std::tie(s.sub_index, s.name, s.object_type, s.data_type, s.access, s.pdo_mapping,
                    s.default_value, s.parameter_value, s.low_limit, s.high_limit, s.denotation,
                    s.upload_file, s.download_file, s.obj_flags);
  };
  return tie(*this) == tie(o);
}

const SubObject* Object::sub(std::uint8_t sub_index) const {
  auto it = subs.find(sub_index);
  return it == subs.end() ? nullptr : &it->second;
}

SubObject* Object::sub(std::uint8_t sub_index) {
  auto it = subs.find(sub_index);
  return it == subs.end() ? nullptr : &it->second;
}

bool Object::operator==(const Object& o) const {
  auto tie = [](const Object& x) {
    return std::tie(x.index, x.name, x.object_type, x.sub_number, x.compact_sub_obj, x.obj_flags,
                    x.object_links, x.subs);
  };
  return tie(*this) == tie(o);
}

const std::string* KeyValues::find(std::string_view key) const {
  for (const auto& [k, v] : entries) {
    if (iequals(k, key)) return &v;
  }
  return nullptr;
}

void KeyValues::set(std::string_view key, std::string value) {
  for (auto& [k, v] : entries) {
    if (iequals(k, key)) {
      v = std::move(value);
      return;
    }
  }
  entries.emplace_back(std::string(key), std::move(value));
}

bool KeyValues::erase(std::string_view key) {
  auto it = std::find_if(entries.begin(), entries.end(),
                         [&](const auto& kv) { return iequals(kv.first, key); });
  if (it == entries.end()) return false;
  entries.erase(it);
  return true;
}

const Object* DeviceDescription::object(std::uint16_t index) const {
  auto it = objects.find(index);
  return it == objects.end() ? nullptr : &it->second;
}

Object* DeviceDescription::object(std::uint16_t index) {
  auto it = objects.find(index);
  return it == objects.end() ? nullptr : &it->second;
}

const SubObject* DeviceDescription::sub(std::uint16_t index, std::uint8_t sub_index) const {
  const Object* obj = object(index);
  return obj == nullptr ? nullptr : obj->sub(sub_index);
}

SubObject* DeviceDescription::sub(std::uint16_t index, std::uint8_t sub_index) {
  Object* obj = object(index);
  return obj == nullptr ? nullptr : obj->sub(sub_index);
}

ObjectList object_list_for(std::uint16_t index) {
  if (index == 0x1000 || index == 0x1001 || index == 0x1018) return ObjectList::Mandatory;
  if (index >= 0x2000 && index <= 0x5FFF) return ObjectList::Manufacturer;
  return ObjectList::Optional;
}

std::string_view to_string(ObjectList list) {
  switch (list) {
    case ObjectList::Mandatory:
      return "MandatoryObjects";
    case ObjectList::Optional:
      return "OptionalObjects";
    case ObjectList::Manufacturer:
      return "ManufacturerObjects";
  }
  return "OptionalObjects";
}

}  // namespace cfg
