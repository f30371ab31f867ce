// The reader's section dispatch (CiA 306 §4.3-4.7): which section a header opens, and the
// key=value sections read as they come ([FileInfo], [DeviceInfo], [DummyUsage], [Comments],
// [DeviceComissioning], [xxxxObjectLinks], sections the reader does not know).
#include <limits>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/node_id.hpp"
#include "device_reader.hpp"

namespace cfg::detail::reader {

void Reader::on_section(int line, std::string_view name, std::string_view trailing, bool closed) {
  close_section();
  // Nothing before this section is needed any more but a few views, read back if at all.
  if (file_ != nullptr) release_pages_before(name.data());
  ++sections_seen_;
  std::vector<RawKey> keys = std::move(cur_.keys);  // keep its capacity: no allocation per section
  keys.clear();
  cur_ = Current{};
  cur_.keys = std::move(keys);
  cur_.line = line;
  cur_.name = name;
  if (!closed) {
    warn(line, "section header [" + std::string(name) + " has no closing ']'");
  } else if (!trailing.empty()) {
    warn(line,
         "[" + std::string(name) + "]: text after the section name is ignored: " + shown(trailing));
  }
  open_section();
}

void Reader::on_key(int line, std::string_view key, std::string_view value) {
  if (key.empty()) {
    warn(line, where() + "line without a key name before '=' is ignored");
    return;
  }
  switch (cur_.kind) {
    case Kind::None:
      warn(line, "key " + std::string(key) + " before the first section is ignored");
      return;
    case Kind::Ignored:
      return;
    case Kind::Object:
    case Kind::Sub:
      cur_.keys.push_back({key, value, line});
      return;
    case Kind::FileInfo:
      add_key_value(file_info_, key, value, line);
      return;
    case Kind::DeviceInfo:
      device_info_key(key, value, line);
      return;
    case Kind::DummyUsage:
      dummy_usage_key(key, value, line);
      return;
    case Kind::Other:
      add_key_value(*cur_.other, key, value, line);
      return;
    case Kind::Comments:
      comments_key(key, value, line);
      return;
    case Kind::List:
      list_key(key, value, line);
      return;
    case Kind::Commissioning:
      commissioning_key(key, value, line);
      return;
    case Kind::Names:
      sub_entry_key(state(cur_.index).names, key, value, line);
      return;
    case Kind::Values:
      sub_entry_key(state(cur_.index).values, key, value, line);
      return;
    case Kind::Denotations:
      sub_entry_key(state(cur_.index).denotations, key, value, line);
      return;
    case Kind::ObjectLinks:
      object_links_key(key, value, line);
      return;
    case Kind::DynamicChannels:
      add_key_value(*cur_.other, key, value, line);  // kept as written
      dynamic_.keys.push_back({key, value, line});
      return;
  }
}

void Reader::on_comment(int line, char marker) {
  if (marker == '#' && strict_) {
    error(line, "'#' comment line: CiA 306 comments start with ';'");
  }
}

void Reader::on_junk(int line, std::string_view text) {
  warn(line, where() + "line is neither [section], key=value nor ;comment and is ignored: " +
                 shown(text));
}

void Reader::open_section() {
  const std::string_view name = cur_.name;
  auto known = [&](bool& seen, Kind kind) {
    cur_.kind = kind;
    cur_.first = !seen;
    if (seen) {
      auto it = first_section_line_.find(name);
      duplicate_section(it == first_section_line_.end() ? 0 : it->second);
    } else {
      first_section_line_.emplace(name, cur_.line);
    }
    seen = true;
  };
  // Object sections first: they are nearly all sections, and no named section starts with
  // four hex digits.
  if (name.size() >= 4) {
    if (auto index = parse_hex_number(name.substr(0, 4), 4)) {
      if (open_object_section(static_cast<std::uint16_t>(*index), name.substr(4))) return;
    }
  }
  if (iequals(name, "FileInfo")) return known(seen_.file_info, Kind::FileInfo);
  if (iequals(name, "DeviceInfo")) return known(seen_.device_info, Kind::DeviceInfo);
  if (iequals(name, "DummyUsage")) return known(seen_.dummy_usage, Kind::DummyUsage);
  if (iequals(name, "Comments")) return known(seen_.comments, Kind::Comments);
  if (iequals(name, "DynamicChannels")) {
    // CiA DSP 302 §8.4: kept as written like any other section, and checked at the end.
    if (!dynamic_.present) dynamic_.line = cur_.line;
    dynamic_.present = true;
    open_other_section();
    if (cur_.kind == Kind::Other) cur_.kind = Kind::DynamicChannels;
    return;
  }
  static constexpr std::array<std::string_view, 3> kLists = {"MandatoryObjects", "OptionalObjects",
                                                             "ManufacturerObjects"};
  for (int i = 0; i < 3; ++i) {
    if (iequals(name, kLists[static_cast<std::size_t>(i)])) {
      cur_.list = i;
      ListState& list = lists_[static_cast<std::size_t>(i)];
      if (!list.present) list.line = cur_.line;
      return known(list.present, Kind::List);
    }
  }
  // CiA 306 §4.7 spells it "DeviceComissioning"; the correct English spelling is accepted.
  if (iequals(name, "DeviceComissioning") || iequals(name, "DeviceCommissioning")) {
    if (strict_ && iequals(name, "DeviceCommissioning")) {
      error(cur_.line, "[DeviceCommissioning]: CiA 306 spells it [DeviceComissioning]");
    }
    if (!model_.commissioning) model_.commissioning.emplace();
    commissioning_other_.kv = &model_.commissioning->other;
    return known(seen_.commissioning, Kind::Commissioning);
  }
  open_other_section();
}

// Sections named after an object index; false if the name only starts like one.
bool Reader::open_object_section(std::uint16_t index, std::string_view rest) {
  cur_.index = index;
  if (rest.empty()) {
    if (index == 0) {
      warn(cur_.line, "[" + std::string(cur_.name) +
                          "]: index 0000h is not a valid object index; section ignored");
      cur_.kind = Kind::Ignored;
      return true;
    }
    ObjectState& st = state(index);
    cur_.kind = Kind::Object;
    cur_.first = !st.has_main;
    if (st.has_main) duplicate_section(st.main_line);
    if (!st.has_main) st.main_line = cur_.line;
    st.has_main = true;
    return true;
  }
  if (istarts_with(rest, "sub")) {
    const std::string_view digits = rest.substr(3);
    std::optional<std::uint64_t> sub = parse_hex_number(digits, 8);
    if (!sub) {
      warn(cur_.line, "[" + std::string(cur_.name) +
                          "]: cannot read the sub-index (hex digits after 'sub'); section "
                          "ignored");
      cur_.kind = Kind::Ignored;
      return true;
    }
    if (*sub > 0xFF) {
      warn(cur_.line, "[" + std::string(cur_.name) + "]: sub-index " + hex_digits(*sub, 2) + "h" +
                          " is larger than FFh; section ignored");
      cur_.kind = Kind::Ignored;
      return true;
    }
    if (*sub == 0xFF) {
      warn(cur_.line, "[" + std::string(cur_.name) +
                          "]: sub-index FFh is reserved by CiA 301 (highest usable is FEh); "
                          "kept");
    }
    ObjectState& st = state(index);
    cur_.kind = Kind::Sub;
    cur_.sub = static_cast<std::uint8_t>(*sub);
    cur_.first = !st.sub_seen[cur_.sub];
    if (!cur_.first) duplicate_section(object(index).subs[cur_.sub].line);
    if (st.sub_seen.none()) st.first_sub_line = cur_.line;
    st.sub_seen[cur_.sub] = true;
    return true;
  }
  auto entry_section = [&](SubEntrySection& s, Kind kind) {
    cur_.kind = kind;
    cur_.first = !s.present;
    if (s.present) duplicate_section(s.line);
    if (!s.present) s.line = cur_.line;
    s.present = true;
    return true;
  };
  if (iequals(rest, "Name")) return entry_section(state(index).names, Kind::Names);
  if (iequals(rest, "Value")) return entry_section(state(index).values, Kind::Values);
  if (iequals(rest, "Denotation")) {
    return entry_section(state(index).denotations, Kind::Denotations);
  }
  if (iequals(rest, "ObjectLinks")) {
    ObjectState& st = state(index);
    cur_.kind = Kind::ObjectLinks;
    cur_.first = !st.has_links;
    if (st.has_links) duplicate_section(st.links_line);
    if (!st.has_links) st.links_line = cur_.line;
    st.has_links = true;
    return true;
  }
  return false;
}

void Reader::open_other_section() {
  cur_.kind = Kind::Other;
  if (cur_.name.empty()) {
    warn(cur_.line, "section without a name ([]) is ignored");
    cur_.kind = Kind::Ignored;
    return;
  }
  auto [it, inserted] = other_index_.emplace(cur_.name, other_builders_.size());
  if (inserted) {
    model_.other_sections.push_back({std::string(cur_.name), {}});
    other_builders_.emplace_back();
    first_section_line_.emplace(cur_.name, cur_.line);
  } else {
    cur_.first = false;
    duplicate_section(first_section_line_[cur_.name]);
  }
  // Pointers are taken per section: both containers may grow when a new section opens.
  cur_.other = &other_builders_[it->second];
  cur_.other->kv = &model_.other_sections[it->second].keys;
}

void Reader::duplicate_section(int first_line) {
  warn(cur_.line, "[" + std::string(cur_.name) + "] appears a second time (first at line " +
                      std::to_string(first_line) +
                      "); its keys are merged into the first, a key given in both takes the "
                      "later value");
}

void Reader::close_section() {
  if (cur_.kind == Kind::Object || cur_.kind == Kind::Sub) close_object_section();
  cur_.kind = Kind::None;
}

void Reader::add_key_value(KeyValueBuilder& b, std::string_view key, std::string_view value,
                           int line) {
  auto [it, inserted] =
      b.index.emplace(key, std::pair<std::size_t, int>{b.kv->entries.size(), line});
  if (!inserted) {
    warn(line, where() + std::string(key) + " is given a second time (first at line " +
                   std::to_string(it->second.second) + "); the later value is used");
    b.kv->entries[it->second.first].second.assign(value);
    return;
  }
  b.kv->entries.emplace_back(std::string(key), std::string(value));
}

void Reader::device_info_key(std::string_view key, std::string_view value, int line) {
  if (detail::is_numeric_device_info_key(key) && !value.empty()) {
    const std::string_view text = without_comment(value, key, line);
    auto n = parse_number(text);
    if (!n) {
      warn(line, where() + std::string(key) + " " + shown(text) + " is not a number");
    } else if (n->h_suffix) {
      warn(line, where() + std::string(key) + " " + shown(text) +
                     ": 'h'-suffix hex is not CiA 306 syntax (kept as written)");
    }
    add_key_value(device_info_, key, text, line);
    return;
  }
  add_key_value(device_info_, key, value, line);
}

void Reader::dummy_usage_key(std::string_view key, std::string_view value, int line) {
  // CiA 306 §4.5: Dummy<type index>=0|1.
  const bool named = istarts_with(key, "Dummy") && parse_hex_number(key.substr(5), 4);
  if (!named) warn(line, where() + std::string(key) + " is not a DummyXXXX key");
  std::string_view text = without_comment(value, key, line);
  auto n = parse_number(text);
  if (!n || n->value > 1) {
    warn(line, where() + std::string(key) + " " + shown(text) + " should be 0 or 1");
  }
  add_key_value(dummy_usage_, key, text, line);
}

void Reader::comments_key(std::string_view key, std::string_view value, int line) {
  if (iequals(key, "Lines")) {
    if (comment_lines_) {
      warn(line, where() + "Lines is given a second time; the later value is used");
    }
    comment_lines_ = number(key, value, line, std::numeric_limits<std::uint32_t>::max());
    comment_lines_line_ = line;
    return;
  }
  if (istarts_with(key, "Line")) {
    auto n = parse_number(key.substr(4));
    if (n && n->value >= 1 && !n->h_suffix && key.size() > 4 && key[4] != '0') {
      auto [it, inserted] = comment_text_.emplace(n->value, std::pair{value, line});
      if (!inserted) {
        warn(line, where() + std::string(key) + " is given a second time (first at line " +
                       std::to_string(it->second.second) + "); the later value is used");
        it->second = {value, line};
      }
      return;
    }
  }
  warn(line, where() + "key " + std::string(key) + " is not Lines or Line<n>; ignored");
}

void Reader::commissioning_key(std::string_view key, std::string_view value, int line) {
  DeviceCommissioning& c = *model_.commissioning;
  auto [it, inserted] = commissioning_keys_.emplace(key, line);
  if (!inserted) {
    warn(line, where() + std::string(key) + " is given a second time (first at line " +
                   std::to_string(it->second) + "); the later value is used");
  }
  // CiA 306 §4.7.
  if (iequals(key, "NodeID")) {
    auto n = number(key, value, line, 0xFF);
    if (n && !is_node_id(*n)) {
      warn(line, where() + "NodeID " + std::to_string(*n) + " is not a node-ID (1..127); ignored");
      n.reset();
    }
    if (n) c.node_id = static_cast<std::uint8_t>(*n);
    return;
  }
  if (iequals(key, "NodeName")) {
    c.node_name.assign(value);
    return;
  }
  if (iequals(key, "Baudrate")) {
    if (auto n = number(key, value, line, 0xFFFF)) c.baudrate_kbps = static_cast<std::uint16_t>(*n);
    return;
  }
  if (iequals(key, "NetNumber")) {
    if (auto n = number(key, value, line, 0xFFFFFFFF))
      c.net_number = static_cast<std::uint32_t>(*n);
    return;
  }
  if (iequals(key, "NetworkName")) {
    c.network_name.assign(value);
    return;
  }
  if (iequals(key, "CANopenManager")) {
    if (auto n = number(key, value, line, 1)) c.canopen_manager = *n == 1;
    return;
  }
  if (iequals(key, "LSS_SerialNumber")) {
    if (auto n = number(key, value, line, 0xFFFFFFFF)) {
      c.lss_serial_number = static_cast<std::uint32_t>(*n);
    }
    return;
  }
  add_key_value(commissioning_other_, key, value, line);
}

void Reader::object_links_key(std::string_view key, std::string_view value, int line) {
  ObjectState& st = state(cur_.index);
  if (iequals(key, "ObjectLinks")) {
    st.links_count = number(key, value, line, 0xFFFF);
    return;
  }
  auto n = parse_number(key);
  if (!n || n->h_suffix || n->value == 0) {
    warn(line, where() + "key " + std::string(key) +
                   " is neither ObjectLinks nor an entry number; ignored");
    return;
  }
  if (auto index = number(key, value, line, 0xFFFF)) {
    st.links.emplace_back(n->value, static_cast<std::uint16_t>(*index));
  }
}

void Reader::finish_comments() {
  if (!seen_.comments) return;
  for (auto& [n, text] : comment_text_) model_.comments.emplace_back(text.first);
  if (!comment_lines_) {
    if (!comment_text_.empty()) warn(comment_section_line(), "[Comments] has no Lines count");
  } else if (*comment_lines_ != comment_text_.size()) {
    warn(comment_lines_line_, "[Comments] Lines " + std::to_string(*comment_lines_) + " but " +
                                  std::to_string(comment_text_.size()) +
                                  " lines are given; the given lines are kept");
  }
}

int Reader::comment_section_line() const {
  auto it = first_section_line_.find(std::string_view("Comments"));
  return it == first_section_line_.end() ? 0 : it->second;
}

}  // namespace cfg::detail::reader
