// Each object assembled after the last line, when everything about it is known: CompactSubObj
// expansion (CiA 306 §4.6.3.3), [xxxxName]/[xxxxValue]/[xxxxDenotation], SubNumber against the
// sub-object sections, [xxxxObjectLinks].
#include <algorithm>
#include <array>

#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "device_reader.hpp"

namespace cfg::detail::reader {
namespace {

// `to = std::move(from)`, but the value texts keep their place in the arena: they are swapped,
// where a move would copy them to the heap (OptionalText leaving a model).
void move_entry(SubObject& to, SubObject& from) {
  auto texts = [](SubObject& s) {
    return std::array<OptionalText*, 7>{&s.default_value, &s.parameter_value, &s.low_limit,
                                        &s.high_limit,    &s.denotation,      &s.upload_file,
                                        &s.download_file};
  };
  std::array<OptionalText, 7> held;
  const auto from_texts = texts(from);
  for (std::size_t i = 0; i < held.size(); ++i) swap(held[i], *from_texts[i]);
  to = std::move(from);
  const auto to_texts = texts(to);
  for (std::size_t i = 0; i < held.size(); ++i) swap(held[i], *to_texts[i]);
}

}  // namespace

void Reader::sub_entry_key(SubEntrySection& s, std::string_view key, std::string_view value,
                           int line) {
  if (iequals(key, "NrOfEntries")) {
    s.count = number(key, value, line, 0xFF);
    s.count_line = line;
    return;
  }
  auto n = parse_number(key);
  if (!n || n->h_suffix || n->value < 1 || n->value > 0xFE) {
    warn(line, where() + "key " + std::string(key) +
                   " is neither NrOfEntries nor a sub-index 1..254; ignored");
    return;
  }
  s.entries.push_back({static_cast<std::uint8_t>(n->value), value, line});
}

void Reader::finish_object(std::uint16_t index, ObjectState& st) {
  const std::string sec = section_of(index);
  if (!st.has_main) {
    const int line = st.sub_seen.any()        ? st.first_sub_line
                     : st.names.present       ? st.names.line
                     : st.values.present      ? st.values.line
                     : st.denotations.present ? st.denotations.line
                                              : st.links_line;
    warn(line, "sections for object " + object_name(index) + " but no " + sec +
                   " section; they are ignored");
    model_.objects.erase(index);
    last_object_ = nullptr;
    return;
  }
  Object& obj = object(index);
  obj.index = index;
  obj.name = st.main.name;
  if (!st.type && st.type_unreadable && st.sub_seen.any()) {
    warn(st.main_line, sec +
                           " has sub-object sections and an unreadable ObjectType; read as "
                           "a RECORD");
    st.type = ObjectType::Record;
  }
  obj.object_type = st.object_type();
  obj.line = st.main_line;
  obj.sub_number = st.sub_number;
  obj.compact_sub_obj = st.compact;
  obj.obj_flags = st.obj_flags;
  finish_links(obj, st);

  if (var_like(obj.object_type)) {
    if (!obj.subs.empty()) {
      warn(obj.subs.begin()->second.line, sec + " is a " + std::string(to_string(obj.object_type)) +
                                              ": its sub-object sections are ignored");
      obj.subs.clear();
    }
    if (st.sub_number && strict_) {
      error(st.sub_number_line,
            sec + " SubNumber has no meaning on a " + std::string(to_string(obj.object_type)));
    }
    const std::pair<const SubEntrySection*, std::string_view> entry_sections[] = {
        {&st.names, "Name"}, {&st.values, "Value"}, {&st.denotations, "Denotation"}};
    for (const auto& [s, what] : entry_sections) {
      if (s->present) {
        warn(s->line, "[" + hex_digits(index, 4) + std::string(what) + "] is for " + sec +
                          ", which is a " + std::string(to_string(obj.object_type)) +
                          " and has no sub-objects; ignored");
      }
    }
    SubObject& entry = obj.subs[0];
    move_entry(entry, st.main);
    entry.sub_index = 0;
    entry.object_type = obj.object_type;
    entry.line = st.main_line;
    return;
  }

  const std::size_t explicit_subs = obj.subs.size();
  bool compact = st.compact && *st.compact > 0;
  if (compact && expanded_budget_ < *st.compact) {
    error(st.compact_line, sec + " CompactSubObj " + std::to_string(*st.compact) +
                               ": the file expands to more sub-objects than its size can "
                               "justify; this object is not expanded");
    compact = false;
  }
  if (compact) {
    expanded_budget_ -= *st.compact;
    expand_compact(obj, st, sec);
  } else if (st.compact && *st.compact > 0) {
    // not expanded (budget): only the explicit sub-object sections
  } else {
    if (!st.sub_number) {
      warn(st.main_line, sec + " " + std::string(to_string(obj.object_type)) +
                             " has no SubNumber (and no CompactSubObj)");
    } else if (*st.sub_number != explicit_subs) {
      warn(st.sub_number_line, sec + " SubNumber " + std::to_string(*st.sub_number) +
                                   " but the file has " + std::to_string(explicit_subs) +
                                   " sub-object sections for it");
    }
  }
  apply_sub_entries(obj, st.names, "Name",
                    [](SubObject& s, std::string_view text) { s.name.assign(text); });
  apply_sub_entries(obj, st.denotations, "Denotation", [](SubObject& s, std::string_view text) {
    if (text.empty()) {
      s.denotation.reset();
    } else {
      s.denotation.emplace(text);
    }
  });
  apply_values(obj, st);
  if (!compact && (st.names.present || st.values.present || st.denotations.present) && strict_) {
    error(st.main_line, sec + " has [" + hex_digits(index, 4) +
                            "Name/Value/Denotation] sections but no CompactSubObj");
  }
  if (obj.subs.empty()) {
    warn(st.main_line, sec + " " + std::string(to_string(obj.object_type)) + " has no sub-objects");
  } else if (!obj.sub(0)) {
    warn(st.main_line, sec + " has no sub-index 0 (highest sub-index supported)");
  }
}

void Reader::expand_compact(Object& obj, ObjectState& st, const std::string& sec) {
  std::uint8_t n = *st.compact;
  if (n == 0xFF) {
    warn(st.compact_line, sec +
                              " CompactSubObj 255 would use the reserved sub-index FFh; "
                              "254 sub-objects are used");
    n = 0xFE;
  }
  // lely's dcfgen writes PDO mapping RECORDs this way and lely reads them; only lint.
  if (obj.object_type != ObjectType::Array && strict_) {
    error(st.compact_line, sec + " CompactSubObj on a " + std::string(to_string(obj.object_type)) +
                               "; CiA 306 defines it for ARRAY objects");
  }
  if (st.sub_number) {
    warn(st.sub_number_line, sec + " has both SubNumber and CompactSubObj; CompactSubObj is used");
  }
  SubObjects explicit_subs = std::move(obj.subs);
  obj.subs.clear();
  SubObject count;
  count.sub_index = 0;
  count.name = "NrOfObjects";
  count.data_type = static_cast<std::uint16_t>(DataType::Unsigned8);
  count.access = AccessType::Ro;
  count.default_value = std::to_string(n);
  count.line = st.main_line;
  obj.subs.emplace(0, std::move(count));
  for (unsigned i = 1; i <= n; ++i) {
    SubObject s = st.main;
    s.sub_index = static_cast<std::uint8_t>(i);
    s.name = st.main.name + std::to_string(i);
    s.object_type = ObjectType::Var;
    s.denotation.reset();
    s.obj_flags.reset();
    s.line = st.main_line;
    obj.subs.emplace(static_cast<std::uint8_t>(i), std::move(s));
  }
  if (!explicit_subs.empty()) {
    std::string list;
    for (const auto& [sub, s] : explicit_subs)
      list += (list.empty() ? "" : ", ") + hex_digits(sub, 2) + "h";
    warn(explicit_subs.begin()->second.line,
         sec + " uses CompactSubObj, but sub-index " + list +
             " also has its own section, which replaces the expanded entry");
  }
  for (auto& [sub, s] : explicit_subs) obj.subs[sub] = std::move(s);
}

void Reader::apply_sub_entries(Object& obj, const SubEntrySection& s, std::string_view what,
                               void (*apply)(SubObject&, std::string_view)) {
  if (!s.present) return;
  const std::string sec = "[" + hex_digits(obj.index, 4) + std::string(what) + "]";
  check_entry_count(s, sec);
  for (const SubEntry& e : s.entries) {
    SubObject* sub = obj.sub(e.sub);
    if (sub == nullptr) {
      warn(e.line, sec + " names sub-index " + std::to_string(e.sub) + ", which " +
                       section_of(obj.index) + " does not have; ignored");
      continue;
    }
    apply(*sub, e.text);
  }
}

void Reader::check_entry_count(const SubEntrySection& s, const std::string& sec) {
  if (!s.count) {
    warn(s.line, sec + " has no NrOfEntries");
  } else if (*s.count != s.entries.size()) {
    warn(s.count_line, sec + " NrOfEntries " + std::to_string(*s.count) + " but " +
                           std::to_string(s.entries.size()) + " entries are given");
  }
}

void Reader::apply_values(Object& obj, ObjectState& st) {
  if (!st.values.present) return;
  const std::string name = hex_digits(obj.index, 4) + "Value";
  const std::string sec = "[" + name + "] ";
  check_entry_count(st.values, sec.substr(0, sec.size() - 1));
  for (const SubEntry& e : st.values.entries) {
    SubObject* sub = obj.sub(e.sub);
    if (sub == nullptr) {
      warn(e.line, sec + "sets sub-index " + std::to_string(e.sub) + ", which " +
                       section_of(obj.index) + " does not have; ignored");
      continue;
    }
    const std::string key = std::to_string(e.sub);
    RawKey raw{key, e.text, e.line};
    std::optional<Value> parsed;
    set_text(sub->parameter_value, clean_value(name, raw, sub->data_type, &parsed));
    sub->parameter_value_line = sub->parameter_value ? e.line : 0;
    if (parsed && sub->basic_type()) {
      std::optional<Value> low, high;
      auto limit = [&](const OptionalText& text, std::optional<Value>& v) {
        if (!text || mentions_node_id(*text)) return;
        if (auto r = parse_value(*sub->basic_type(), *text, kValidationNodeId))
          v = std::move(r.value());
      };
      limit(sub->low_limit, low);
      limit(sub->high_limit, high);
      auto c_low = low ? compare_values(*parsed, *low) : std::nullopt;
      auto c_high = high ? compare_values(*parsed, *high) : std::nullopt;
      if ((c_low && *c_low < 0) || (c_high && *c_high > 0)) {
        warn(e.line, sec + key + " " + shown(e.text) + " is outside LowLimit..HighLimit");
      }
    }
  }
}

void Reader::finish_links(Object& obj, const ObjectState& st) {
  if (!st.has_links) return;
  std::vector<std::pair<std::uint64_t, std::uint16_t>> links = st.links;
  std::stable_sort(links.begin(), links.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  obj.object_links.clear();
  for (const auto& l : links) obj.object_links.push_back(l.second);
  const std::string lsec = "[" + hex_digits(obj.index, 4) + "ObjectLinks]";
  if (!st.links_count) {
    warn(st.links_line, lsec + " has no ObjectLinks count");
  } else if (*st.links_count != links.size()) {
    warn(st.links_line, lsec + " ObjectLinks " + std::to_string(*st.links_count) + " but " +
                            std::to_string(links.size()) + " entries are given");
  }
}

}  // namespace cfg::detail::reader
