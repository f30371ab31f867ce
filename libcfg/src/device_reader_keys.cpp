// Object and sub-object keys (CiA 306 §4.6.3, DCF additions of §4.7) and their values: numbers of
// attribute keys, DataType/AccessType/PDOMapping, DefaultValue/ParameterValue/limits checked
// against the data type.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <initializer_list>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "device_reader.hpp"

namespace cfg::detail::reader {
namespace {

constexpr std::array<std::string_view, 15> kKeyNames = {
    "ParameterName", "ObjectType",     "DataType",   "AccessType", "DefaultValue",
    "PDOMapping",    "LowLimit",       "HighLimit",  "SubNumber",  "CompactSubObj",
    "ObjFlags",      "ParameterValue", "Denotation", "UploadFile", "DownloadFile"};
static_assert(kKeyNames.size() == kKeyCount);

// Case-insensitive equality with a name made of ASCII letters only: for a letter L,
// (c | 0x20) == lower(L) holds exactly for c == L in either case. Hot: once per key line.
// The same holds for 8 bytes at a time, so names of 8 to 16 letters (all of them) take two
// word comparisons (the last word may overlap the first).
bool equals_letters(std::string_view text, std::string_view letters) {
  const std::size_t n = text.size();
  if (n != letters.size()) return false;
  if (n < 8) {
    for (std::size_t i = 0; i < n; ++i) {
      if ((text[i] | 0x20) != (letters[i] | 0x20)) return false;
    }
    return true;
  }
  constexpr std::uint64_t kCaseBits = 0x2020202020202020ULL;
  auto word = [](const char* p) {
    std::uint64_t w = 0;
    std::memcpy(&w, p, sizeof w);
    return w | kCaseBits;
  };
  for (std::size_t i = 0; i + 8 < n; i += 8) {
    if (word(text.data() + i) != word(letters.data() + i)) return false;
  }
  return word(text.data() + n - 8) == word(letters.data() + n - 8);
}

std::optional<Key> object_key(std::string_view name) {
  if (name.empty()) return std::nullopt;
  // By the first letter, so that a key line compares with one to four names, not fifteen.
  auto one_of = [name](std::initializer_list<Key> keys) -> std::optional<Key> {
    for (Key k : keys) {
      if (equals_letters(name, kKeyNames[static_cast<std::size_t>(k)])) return k;
    }
    return std::nullopt;
  };
  switch (name.front() | 0x20) {
    case 'a':
      return one_of({Key::AccessType});
    case 'c':
      return one_of({Key::CompactSubObj});
    case 'd':
      return one_of({Key::DataType, Key::DefaultValue, Key::Denotation, Key::DownloadFile});
    case 'h':
      return one_of({Key::HighLimit});
    case 'l':
      return one_of({Key::LowLimit});
    case 'o':
      return one_of({Key::ObjectType, Key::ObjFlags});
    case 'p':
      return one_of({Key::ParameterName, Key::PDOMapping, Key::ParameterValue});
    case 's':
      return one_of({Key::SubNumber});
    case 'u':
      return one_of({Key::UploadFile});
    default:
      return std::nullopt;
  }
}

}  // namespace

std::optional<Number> parse_number(std::string_view text) {
  if (auto digits = h_suffix_digits(text)) {
    if (auto v = parse_hex_number(*digits)) return Number{*v, true};
    return std::nullopt;
  }
  const IntegerLiteralResult r = parse_integer_literal(text);
  if (!r.literal) return std::nullopt;
  return Number{r.literal->value, false};
}

// Cuts an inline comment from a number-like value, with a warning.
std::string_view Reader::without_comment(std::string_view value, std::string_view key, int line) {
  const std::size_t c = find_inline_comment(value);
  if (c == std::string_view::npos) return value;
  dropped_comment(line, where() + std::string(key) + ": " + shown(value.substr(c)) +
                            " after the value is a comment and is dropped");
  return trim_blanks(value.substr(0, c));
}

// Hand-written profile files carry a comment after nearly every value: in tolerant mode say
// it once in full and sum up the rest at the end (finish()), so other warnings stay visible.
void Reader::dropped_comment(int line, std::string message) {
  if (strict_ || dropped_comments_ == 0) warn(line, std::move(message));
  ++dropped_comments_;
}

// A number of an attribute key, with diagnostics; nullopt (after a warning) if unreadable
// or larger than `max`.
std::optional<std::uint64_t> Reader::number(std::string_view key, std::string_view value, int line,
                                            std::uint64_t max) {
  // Nearly every attribute number is a plain literal ("7", "0x1A00"): digits only, so there is
  // no comment to cut and no 'h' suffix, and what follows would read the same value.
  if (const IntegerLiteralResult plain = parse_integer_literal(value);
      plain.literal && plain.literal->value <= max) {
    return plain.literal->value;
  }
  const std::string_view text = without_comment(value, key, line);
  auto n = parse_number(text);
  if (!n) {
    warn(line, where() + std::string(key) + " " + shown(text) + " is not a number; ignored");
    return std::nullopt;
  }
  if (n->value > max) {
    warn(line, where() + std::string(key) + " " + shown(text) + " is larger than " +
                   std::to_string(max) + "; ignored");
    return std::nullopt;
  }
  if (n->h_suffix) {
    warn(line, where() + std::string(key) + " " + shown(text) +
                   ": 'h'-suffix hex is not CiA 306 syntax; read as " + hex(n->value, 0));
  }
  return n->value;
}

void Reader::close_object_section() {
  ObjectKeys get;
  for (const RawKey& k : cur_.keys) {
    auto id = object_key(k.key);
    if (!id) {
      unknown_key(k);
      continue;
    }
    if (const RawKey* s = get(*id)) {
      warn(k.line, where() + std::string(k.key) + " is given a second time (first at line " +
                       std::to_string(s->line) + "); the later value is used");
    }
    get.set(*id, &k);
  }

  if (cur_.kind == Kind::Sub) {
    SubObject& s = object(cur_.index).subs[cur_.sub];
    s.sub_index = cur_.sub;
    if (cur_.first) s.line = cur_.line;
    if (const RawKey* k = get(Key::ObjectType)) {
      if (auto t = object_type(*k)) {
        s.object_type = *t;
        if (*t != ObjectType::Var && *t != ObjectType::Domain) {
          warn(k->line, where() + "ObjectType " + std::string(to_string(*t)) +
                            " on a sub-object; sub-objects are VAR");
        }
      }
    }
    for (Key k : {Key::SubNumber, Key::CompactSubObj}) {
      if (const RawKey* r = get(k); r && strict_) {
        error(r->line, where() + std::string(r->key) + " has no meaning on a sub-object");
      }
    }
    if (const RawKey* k = get(Key::ObjFlags)) {
      if (auto n = number(k->key, k->value, k->line, 0xFFFFFFFF)) {
        s.obj_flags = static_cast<std::uint32_t>(*n);
      }
    }
    apply_entry(s, get, /*needs_type=*/true);
    cur_.keys.clear();
    return;
  }

  ObjectState& st = state(cur_.index);
  if (const RawKey* k = get(Key::ObjectType)) {
    if (auto t = object_type(*k)) {
      st.type = *t;
    } else {
      st.type_unreadable = true;
    }
  }
  if (const RawKey* k = get(Key::SubNumber)) {
    if (auto n = number(k->key, k->value, k->line, 0xFF)) {
      st.sub_number = static_cast<std::uint8_t>(*n);
      st.sub_number_line = k->line;
    }
  }
  if (const RawKey* k = get(Key::CompactSubObj)) {
    if (auto n = number(k->key, k->value, k->line, 0xFF)) {
      st.compact = static_cast<std::uint8_t>(*n);
      st.compact_line = k->line;
    }
  }
  if (const RawKey* k = get(Key::ObjFlags)) {
    if (auto n = number(k->key, k->value, k->line, 0xFFFFFFFF)) {
      st.obj_flags = static_cast<std::uint32_t>(*n);
    }
  }
  const ObjectType t = st.object_type();
  const bool has_values = var_like(t) || (st.compact && *st.compact > 0);
  if (t == ObjectType::Domain && !get(Key::DataType) && st.main.data_type == 0) {
    st.main.data_type = static_cast<std::uint16_t>(DataType::Domain);
  }
  apply_entry(st.main, get, has_values);
  cur_.keys.clear();
}

std::optional<ObjectType> Reader::object_type(const RawKey& k) {
  auto n = number(k.key, k.value, k.line, 0xFF);
  if (!n) return std::nullopt;
  auto t = object_type_from_code(static_cast<unsigned>(*n));
  if (!t) {
    warn(k.line, where() + "ObjectType " + hex(*n, 1) +
                     " is not an object code of CiA 301 (0, 2, 5-9); ignored");
  }
  return t;
}

void Reader::apply_entry(SubObject& s, const ObjectKeys& get, bool needs_type) {
  if (const RawKey* k = get(Key::ParameterName)) {
    s.name.assign(k->value);
  } else if (cur_.first) {
    warn(cur_.line, where() + "ParameterName is missing");
  }
  if (const RawKey* k = get(Key::DataType)) {
    if (auto n = number(k->key, k->value, k->line, 0xFFFF)) {
      s.data_type = static_cast<std::uint16_t>(*n);
      if (find_data_type(s.data_type) == nullptr) {
        warn(k->line, where() + "DataType " + hex(*n, 4) +
                          " is not a basic data type of CiA 301; its values are not checked");
      }
    }
  } else if (cur_.first && needs_type && s.data_type == 0) {
    warn(cur_.line, where() + "DataType is missing; values are not checked");
  }
  if (const RawKey* k = get(Key::AccessType)) {
    const std::string_view text = without_comment(k->value, k->key, k->line);
    if (auto a = access_type_from_string(text)) {
      s.access = *a;
      if (strict_ && text != to_string(*a)) {
        error(k->line, where() + "AccessType " + shown(text) + ": CiA 306 writes it in lower case");
      }
    } else {
      warn(k->line, where() + "AccessType " + shown(text) +
                        " is not one of ro, wo, rw, rwr, rww, const; read as ro");
      s.access = AccessType::Ro;
    }
  } else if (cur_.first && needs_type) {
    warn(cur_.line, where() + "AccessType is missing; read as ro");
    s.access = AccessType::Ro;
  }
  if (const RawKey* k = get(Key::PDOMapping)) {
    if (auto n = number(k->key, k->value, k->line, 1)) s.pdo_mapping = *n == 1;
  }
  auto text_key = [&](Key key, OptionalText& field) {
    if (const RawKey* k = get(key)) {
      set_text(field, k->value.empty() ? std::nullopt : std::optional(k->value));
    }
  };
  text_key(Key::Denotation, s.denotation);
  text_key(Key::UploadFile, s.upload_file);
  text_key(Key::DownloadFile, s.download_file);

  std::optional<Value> low, high, def, param;
  auto value_key = [&](Key key, OptionalText& field, std::optional<Value>& parsed,
                       int* line = nullptr) {
    if (const RawKey* k = get(key)) {
      set_text(field, clean_value(cur_.name, *k, s.data_type, &parsed));
      if (line != nullptr) *line = field ? k->line : 0;
    }
  };
  value_key(Key::LowLimit, s.low_limit, low);
  value_key(Key::HighLimit, s.high_limit, high);
  value_key(Key::DefaultValue, s.default_value, def, &s.default_value_line);
  value_key(Key::ParameterValue, s.parameter_value, param, &s.parameter_value_line);
  check_limits(s, get, low, high, def, param);
}

void Reader::check_limits(const SubObject& s, const ObjectKeys& get, std::optional<Value>& low,
                          std::optional<Value>& high, const std::optional<Value>& def,
                          const std::optional<Value>& param) {
  if (!get(Key::LowLimit) && !get(Key::HighLimit) && !get(Key::DefaultValue) &&
      !get(Key::ParameterValue)) {
    return;
  }
  // Limits from an earlier occurrence of a duplicated section still apply.
  auto reparse = [&](const OptionalText& text, std::optional<Value>& v) {
    if (v || !text || mentions_node_id(*text)) return;
    if (auto type = s.basic_type()) {
      if (auto r = parse_value(*type, *text, kValidationNodeId)) v = std::move(r.value());
    }
  };
  reparse(s.low_limit, low);
  reparse(s.high_limit, high);
  const int line = [&] {
    for (Key k : {Key::LowLimit, Key::HighLimit, Key::DefaultValue, Key::ParameterValue}) {
      if (const RawKey* r = get(k)) return r->line;
    }
    return cur_.line;
  }();
  if (low && high) {
    auto c = compare_values(*low, *high);
    if (c && *c > 0) {
      warn(line, where() + "LowLimit " + shown(*s.low_limit) + " is above HighLimit " +
                     shown(*s.high_limit));
    }
  }
  auto check = [&](const std::optional<Value>& v, Key key, const OptionalText& text) {
    if (!v) return;
    const RawKey* r = get(key);
    if (r == nullptr) return;
    if (low) {
      auto c = compare_values(*v, *low);
      if (c && *c < 0) {
        warn(r->line, where() + std::string(r->key) + " " + shown(*text) + " is below LowLimit " +
                          shown(*s.low_limit));
      }
    }
    if (high) {
      auto c = compare_values(*v, *high);
      if (c && *c > 0) {
        warn(r->line, where() + std::string(r->key) + " " + shown(*text) + " is above HighLimit " +
                          shown(*s.high_limit));
      }
    }
  };
  check(def, Key::DefaultValue, s.default_value);
  check(param, Key::ParameterValue, s.parameter_value);
}

// The stored text of a value key: inline comment cut (numbers), empty fixed-size value
// dropped, h-suffix hex normalised; then checked against the data type.
std::optional<std::string_view> Reader::clean_value(std::string_view section_name, const RawKey& k,
                                                    std::uint16_t data_type,
                                                    std::optional<Value>* parsed) {
  const DataTypeInfo* info = find_data_type(data_type);
  auto section = [&] { return "[" + std::string(section_name) + "] "; };
  // Most values of a device file are plain integer literals of an integer type: digits only, so
  // normalize_value would keep them as they are (no comment, no 'h' suffix, not empty), and the
  // literal gives the value without parse_value reading the text again.
  if (info != nullptr &&
      (info->type_class == TypeClass::Unsigned || info->type_class == TypeClass::Signed ||
       info->type_class == TypeClass::Boolean)) {
    if (const auto plain = parse_integer_literal(k.value).literal) {
      if (auto v = integer_value(info->type, *plain)) {
        if (parsed != nullptr) *parsed = std::move(v.value());
        return k.value;
      }
    }
  }
  // Texts normalize_value would keep as they are (nearly all) are not copied.
  std::string_view text = k.value;
  if (!detail::is_normalized_value(k.value, data_type)) {
    detail::NormalizedValue n = detail::normalize_value(k.value, data_type);
    if (!n.comment.empty()) {
      dropped_comment(k.line, section() + std::string(k.key) + ": " + shown(n.comment) +
                                  " after the " + std::string(info->name) +
                                  " value is a comment and is dropped");
    }
    if (!n.text) {
      if (strict_) error(k.line, section() + std::string(k.key) + " is empty");
      return std::nullopt;
    }
    if (n.h_suffix) {
      warn(k.line, section() + std::string(k.key) + " " + shown(k.value) +
                       ": 'h'-suffix hex is not CiA 306 syntax; read as " + *n.text);
    }
    value_scratch_ = std::move(*n.text);  // set_text copies it before the next value
    text = value_scratch_;
  }
  if (info == nullptr || info->type_class == TypeClass::VisibleString) return text;
  auto v = parse_value(info->type, text, kValidationNodeId);
  if (!v) {
    const std::string msg = section() + std::string(k.key) + " " + shown(text) +
                            " is not a valid " + std::string(info->name) + " (DataType " +
                            hex(data_type, 4) + "): " + v.error().message;
    // A ParameterValue is what a configuration manager downloads: one that cannot be encoded
    // is an error in either mode. A vendor's bad DefaultValue or limit stays a warning.
    if (iequals(k.key, "ParameterValue")) {
      error(k.line, msg);
    } else {
      warn(k.line, msg);
    }
  } else if (parsed != nullptr && !mentions_node_id(text)) {
    *parsed = std::move(v.value());
  }
  return text;
}

void Reader::unknown_key(const RawKey& k) {
  auto [it, inserted] = unknown_keys_.emplace(k.key, UnknownKey{k.line, 0});
  ++it->second.count;
}

}  // namespace cfg::detail::reader
