// The CiA 306 EDS/DCF reader. CiA 306 is implemented from public knowledge of the standard (its
// text is not in spec/); where real files and the standard part ways, the choices are listed here
// and asserted in tests/cfg/device_reader_test.cpp.
//
// Structure: ini_scanner (on inih) hands over sections and key lines as views into the text. The
// keys of an object or sub-object section are collected and applied when the section ends, because
// how a value is read depends on DataType, which may come after it. Everything that needs the whole
// file (CompactSubObj expansion, [xxxxName]/[xxxxValue]/[xxxxDenotation], object lists, SubNumber)
// is resolved in finish(). Only what the model keeps is allocated.
//
// Choices (tolerant mode recovers and warns; strict mode makes every deviation an error):
// - Duplicate section: its keys are merged into the first occurrence, a key given in both takes
//   the later value. Duplicate key in one section: the later value wins. (As Python's
//   configparser with strict=False, which many tools use to read these files.)
// - Missing ObjectType: VAR, no diagnostic (CiA 306 §4.6.3.2 defines VAR as the default).
// - Missing ParameterName: warning, empty name. Missing DataType on a VAR: warning, type 0
//   (values unchecked); a DOMAIN object without DataType is DOMAIN (000Fh), as lely reads it.
//   Missing AccessType: warning, read as "ro" (a tool will not try to write an entry of unknown
//   access).
// - Comments: whole lines starting with ';' (CiA 306) or '#' (not CiA 306: strict error). An
//   inline comment (';' or '#' at the start of the value or after a blank) is cut from numbers
//   and attribute keys with a warning; strings (ParameterName, VISIBLE_STRING/UNICODE_STRING
//   values, Denotation, file names, [FileInfo]/[DeviceInfo] texts) keep it: it is their text.
// - An empty value of a fixed-size type (`ParameterValue=` as CANopenEditor writes it) is "not
//   given" (strict: error); of a string/DOMAIN type it is the empty value.
// - `0180h` hex (and digit groups `0000 0080h`): warning, read as 0x0180 and stored so.
// - Text after a section's ']': warning, ignored. Keys before the first section: warning, ignored.
// - Sub-index FFh (reserved by CiA 301): warning, kept. Sub-objects of a VAR: warning, ignored.
// - Object listed but without a section: warning, no object. Section of an object that no list
//   names: warning, kept. A file without any object list: one warning.
// - CompactSubObj (CiA 306 §4.6.3.3; names and sub-index 0 as lely-core's dcf.c builds them):
//   sub-index 0 "NrOfObjects" UNSIGNED8 ro = n; sub-indices 1..n named from [xxxxName] or
//   "<ParameterName><i>" (decimal), with DataType/AccessType/PDOMapping/DefaultValue/limits/
//   ParameterValue of the object's section; [xxxxValue] gives ParameterValue, [xxxxDenotation]
//   Denotation per sub-index. An explicit [xxxxsubN] section replaces the expanded entry (warning).
//   Expansion is budgeted (65536 + file size / 8 sub-objects): beyond it an object is not
//   expanded, with an error, so a small hostile file cannot claim gigabytes.
#include <algorithm>
#include <array>
#include <bitset>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <unordered_map>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/value.hpp"
#include "device_file_detail.hpp"
#include "ini_scanner.hpp"

namespace cfg {
namespace {

using detail::find_inline_comment;
using detail::h_suffix_digits;
using detail::trim_blanks;
using detail::var_like;

// Keeps a pathological file from producing gigabytes of messages; the summary keeps
// has_errors() truthful.
constexpr std::size_t kMaxDiagnostics = 5000;
constexpr std::uint8_t kValidationNodeId = 1;  // $NODEID stand-in when checking formulas

char ascii_lower(char c) {
  return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c;
}

bool istarts_with(std::string_view text, std::string_view prefix) {
  return text.size() >= prefix.size() && iequals(text.substr(0, prefix.size()), prefix);
}

struct CaseInsensitiveHash {
  std::size_t operator()(std::string_view s) const {
    std::size_t h = 1469598103934665603ULL;
    for (char c : s) {
      h ^= static_cast<unsigned char>(ascii_lower(c));
      h *= 1099511628211ULL;
    }
    return h;
  }
};
struct CaseInsensitiveEqual {
  bool operator()(std::string_view a, std::string_view b) const { return iequals(a, b); }
};
template <class T>
using CaseInsensitiveMap =
    std::unordered_map<std::string_view, T, CaseInsensitiveHash, CaseInsensitiveEqual>;

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// All of `text` as hex digits (1..max_digits of them).
std::optional<std::uint32_t> parse_hex_digits(std::string_view text, std::size_t max_digits) {
  if (text.empty() || text.size() > max_digits) return std::nullopt;
  std::uint32_t v = 0;
  for (char c : text) {
    const int d = hex_digit(c);
    if (d < 0) return std::nullopt;
    v = v * 16 + static_cast<std::uint32_t>(d);
  }
  return v;
}

std::string section_of(std::uint16_t index) {
  return "[" + hex(index, 4).substr(2) + "]";
}

// Text of a value for a message: quoted, long values cut.
std::string shown(std::string_view text) {
  constexpr std::size_t kMax = 48;
  if (text.size() <= kMax) return "\"" + std::string(text) + "\"";
  return "\"" + std::string(text.substr(0, kMax)) + "...\" (" + std::to_string(text.size()) +
         " characters)";
}

// A number of an attribute key (SubNumber, DataType, list entries, ...): CiA 306 integer
// syntax, i.e. 0x hex, leading-0 octal, decimal.
struct Number {
  std::uint64_t value = 0;
  bool h_suffix = false;
};
std::optional<Number> parse_number(std::string_view text) {
  if (text.empty()) return std::nullopt;
  int base = 10;
  std::string_view digits = text;
  bool h_suffix = false;
  std::string h_digits;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    digits = text.substr(2);
  } else if (auto h = h_suffix_digits(text)) {
    base = 16;
    h_digits = std::move(*h);
    digits = h_digits;
    h_suffix = true;
  } else if (text.size() > 1 && text[0] == '0') {
    base = 8;
    digits = text.substr(1);
  }
  for (char c : digits) {
    const int d = hex_digit(c);
    if (d < 0 || d >= base) return std::nullopt;
  }
  std::uint64_t v = 0;
  auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v, base);
  if (ec != std::errc{} || end != digits.data() + digits.size()) return std::nullopt;
  return Number{v, h_suffix};
}

// Object and sub-object keys of CiA 306 §4.6.3 (DCF additions of §4.7).
enum class Key : std::uint8_t {
  ParameterName,
  ObjectType,
  DataType,
  AccessType,
  DefaultValue,
  PDOMapping,
  LowLimit,
  HighLimit,
  SubNumber,
  CompactSubObj,
  ObjFlags,
  ParameterValue,
  Denotation,
  UploadFile,
  DownloadFile,
};
constexpr std::array<std::string_view, 15> kKeyNames = {
    "ParameterName", "ObjectType",     "DataType",   "AccessType", "DefaultValue",
    "PDOMapping",    "LowLimit",       "HighLimit",  "SubNumber",  "CompactSubObj",
    "ObjFlags",      "ParameterValue", "Denotation", "UploadFile", "DownloadFile"};
constexpr std::size_t kKeyCount = kKeyNames.size();

// Case-insensitive equality with a name made of ASCII letters only: for a letter L,
// (c | 0x20) == lower(L) holds exactly for c == L in either case. Hot: once per key line.
bool equals_letters(std::string_view text, std::string_view letters) {
  if (text.size() != letters.size()) return false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if ((text[i] | 0x20) != (letters[i] | 0x20)) return false;
  }
  return true;
}

std::optional<Key> object_key(std::string_view name) {
  for (std::size_t i = 0; i < kKeyCount; ++i) {
    if (equals_letters(name, kKeyNames[i])) return static_cast<Key>(i);
  }
  return std::nullopt;
}

enum class Kind {
  None,  // before the first section
  Ignored,
  FileInfo,
  DeviceInfo,
  DummyUsage,
  Comments,
  List,
  Commissioning,
  Object,
  Sub,
  Names,
  Values,
  Denotations,
  ObjectLinks,
  Other,
};

struct RawKey {
  std::string_view key;
  std::string_view value;
  int line = 0;
};

// A sub-index keyed entry of [xxxxName]/[xxxxValue]/[xxxxDenotation].
struct SubEntry {
  std::uint8_t sub = 0;
  std::string_view text;
  int line = 0;
};
struct SubEntrySection {
  bool present = false;
  int line = 0;
  std::optional<std::uint64_t> count;  // NrOfEntries
  int count_line = 0;
  std::vector<SubEntry> entries;
};

// What the reader knows about one object index while reading.
struct ObjectState {
  bool has_main = false;
  int main_line = 0;
  SubObject main;  // attributes of the object's own section
  std::optional<ObjectType> type;
  bool type_unreadable = false;  // ObjectType given but not understood
  std::optional<std::uint8_t> sub_number;
  int sub_number_line = 0;
  std::optional<std::uint8_t> compact;
  int compact_line = 0;
  std::optional<std::uint32_t> obj_flags;
  std::bitset<256> sub_seen;
  int first_sub_line = 0;
  SubEntrySection names, values, denotations;
  bool has_links = false;
  int links_line = 0;
  std::optional<std::uint64_t> links_count;
  std::vector<std::pair<std::uint64_t, std::uint16_t>> links;  // (key number, index)

  ObjectType object_type() const { return type.value_or(ObjectType::Var); }
};

struct ListState {
  bool present = false;
  int line = 0;
  std::optional<std::uint64_t> supported;
  int supported_line = 0;
  std::vector<std::pair<std::uint16_t, int>> entries;  // index, line
};

// A key=value section kept as text, with a case-insensitive index for duplicates.
struct KeyValueBuilder {
  KeyValues* kv = nullptr;
  CaseInsensitiveMap<std::pair<std::size_t, int>> index;  // key -> (entry position, line)
};

class Reader final : public detail::IniSink {
 public:
  explicit Reader(const ReadOptions& options) : options_(options) {
    strict_ = options.mode == ReadMode::Strict;
  }

  ReadResult run(std::string_view text) {
    ReadResult result;
    if (text.size() >= 3 && std::memcmp(text.data(), "\xEF\xBB\xBF", 3) == 0) {
      text.remove_prefix(3);
      if (strict_) error(1, "the file starts with a UTF-8 byte order mark (not CiA 306)");
    }
    if (text.find_first_not_of(" \t\r\n\v\f") == std::string_view::npos) {
      error(0,
            "the file is empty: an EDS/DCF has at least a [DeviceInfo] section and object "
            "sections");
      result.diagnostics = take_diagnostics();
      return result;
    }
    // A few bytes of CompactSubObj=254 become 255 sub-objects of a few hundred bytes each; the
    // budget keeps a hostile file from turning kilobytes into gigabytes (real files expand to a
    // few thousand sub-objects).
    expanded_budget_ = 65536 + text.size() / 8;
    file_info_.kv = &model_.file_info;
    device_info_.kv = &model_.device_info;
    dummy_usage_.kv = &model_.dummy_usage;
    if (!detail::scan_ini(text, *this)) {
      error(0, "internal error: the INI scanner lost track of the file structure");
    }
    close_section();
    if (sections_seen_ == 0) {
      diagnostics_.clear();  // line-by-line complaints about a non-INI file help nobody
      suppressed_ = {};
      error(0, "no [section] header found: this is not an EDS/DCF file");
      result.diagnostics = take_diagnostics();
      return result;
    }
    finish();
    result.device = std::move(model_);
    result.diagnostics = take_diagnostics();
    return result;
  }

  // ---- IniSink
  void on_section(int line, std::string_view name, std::string_view trailing,
                  bool closed) override {
    close_section();
    ++sections_seen_;
    std::vector<RawKey> keys =
        std::move(cur_.keys);  // keep its capacity: no allocation per section
    keys.clear();
    cur_ = Current{};
    cur_.keys = std::move(keys);
    cur_.line = line;
    cur_.name = name;
    if (!closed) {
      warn(line, "section header [" + std::string(name) + " has no closing ']'");
    } else if (!trailing.empty()) {
      warn(line, "[" + std::string(name) +
                     "]: text after the section name is ignored: " + shown(trailing));
    }
    open_section();
  }

  void on_key(int line, std::string_view key, std::string_view value) override {
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
    }
  }

  void on_comment(int line, char marker) override {
    if (marker == '#' && strict_) {
      error(line, "'#' comment line: CiA 306 comments start with ';'");
    }
  }

  void on_junk(int line, std::string_view text) override {
    warn(line, where() + "line is neither [section], key=value nor ;comment and is ignored: " +
                   shown(text));
  }

 private:
  struct Current {
    Kind kind = Kind::None;
    std::string_view name;
    int line = 0;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    int list = 0;  // 0 mandatory, 1 optional, 2 manufacturer
    bool first = true;
    KeyValueBuilder* other = nullptr;
    std::vector<RawKey> keys;
  };

  // ---- diagnostics
  void add(int line, Severity severity, std::string message) {
    if (diagnostics_.size() >= kMaxDiagnostics) {
      ++suppressed_[static_cast<int>(severity)];
      return;
    }
    diagnostics_.push_back({options_.file_name, line, severity, std::move(message)});
  }
  void error(int line, std::string message) { add(line, Severity::Error, std::move(message)); }
  // A deviation from CiA 306 the reader recovers from: warning (tolerant) or error (strict).
  void warn(int line, std::string message) {
    add(line, strict_ ? Severity::Error : Severity::Warning, std::move(message));
  }

  Diagnostics take_diagnostics() {
    // File order reads best; whole-file messages (line 0) last.
    std::stable_sort(diagnostics_.begin(), diagnostics_.end(),
                     [](const Diagnostic& a, const Diagnostic& b) {
                       const int la = a.line == 0 ? std::numeric_limits<int>::max() : a.line;
                       const int lb = b.line == 0 ? std::numeric_limits<int>::max() : b.line;
                       return la < lb;
                     });
    Diagnostics out;
    for (auto& d : diagnostics_) out.add(std::move(d));
    const std::size_t n = suppressed_[0] + suppressed_[1] + suppressed_[2];
    if (n > 0) {
      const Severity worst = suppressed_[2]   ? Severity::Error
                             : suppressed_[1] ? Severity::Warning
                                              : Severity::Note;
      out.add(options_.file_name, 0, worst,
              std::to_string(n) + " more diagnostics not shown (" + std::to_string(suppressed_[2]) +
                  " errors, " + std::to_string(suppressed_[1]) + " warnings)");
    }
    return out;
  }

  std::string where() const {
    if (cur_.kind == Kind::None) return "";
    return "[" + std::string(cur_.name) + "] ";
  }

  // ---- sections
  ObjectState& state(std::uint16_t index) {
    if (last_state_ == nullptr || last_state_index_ != index) {
      last_state_ = &states_[index];
      last_state_index_ = index;
    }
    return *last_state_;
  }

  Object& object(std::uint16_t index) {
    if (last_object_ == nullptr || last_object_index_ != index) {
      last_object_ = &model_.objects[index];
      last_object_->index = index;
      last_object_index_ = index;
    }
    return *last_object_;
  }

  void open_section() {
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
      if (auto index = parse_hex_digits(name.substr(0, 4), 4)) {
        if (open_object_section(static_cast<std::uint16_t>(*index), name.substr(4))) return;
      }
    }
    if (iequals(name, "FileInfo")) return known(seen_.file_info, Kind::FileInfo);
    if (iequals(name, "DeviceInfo")) return known(seen_.device_info, Kind::DeviceInfo);
    if (iequals(name, "DummyUsage")) return known(seen_.dummy_usage, Kind::DummyUsage);
    if (iequals(name, "Comments")) return known(seen_.comments, Kind::Comments);
    static constexpr std::array<std::string_view, 3> kLists = {
        "MandatoryObjects", "OptionalObjects", "ManufacturerObjects"};
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
  bool open_object_section(std::uint16_t index, std::string_view rest) {
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
      std::optional<std::uint32_t> sub = parse_hex_digits(digits, 8);
      if (!sub) {
        warn(cur_.line, "[" + std::string(cur_.name) +
                            "]: cannot read the sub-index (hex digits after 'sub'); section "
                            "ignored");
        cur_.kind = Kind::Ignored;
        return true;
      }
      if (*sub > 0xFF) {
        warn(cur_.line, "[" + std::string(cur_.name) + "]: sub-index " + hex(*sub, 2) +
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

  void open_other_section() {
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

  void duplicate_section(int first_line) {
    warn(cur_.line, "[" + std::string(cur_.name) + "] appears a second time (first at line " +
                        std::to_string(first_line) +
                        "); its keys are merged into the first, a key given in both takes the "
                        "later value");
  }

  void close_section() {
    if (cur_.kind == Kind::Object || cur_.kind == Kind::Sub) close_object_section();
    cur_.kind = Kind::None;
  }

  // ---- key=value sections
  void add_key_value(KeyValueBuilder& b, std::string_view key, std::string_view value, int line) {
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

  // Cuts an inline comment from a number-like value, with a warning.
  std::string_view without_comment(std::string_view value, std::string_view key, int line) {
    const std::size_t c = find_inline_comment(value);
    if (c == std::string_view::npos) return value;
    dropped_comment(line, where() + std::string(key) + ": " + shown(value.substr(c)) +
                              " after the value is a comment and is dropped");
    return trim_blanks(value.substr(0, c));
  }

  // Hand-written profile files carry a comment after nearly every value: in tolerant mode say
  // it once in full and sum up the rest at the end (finish()), so other warnings stay visible.
  void dropped_comment(int line, std::string message) {
    if (strict_ || dropped_comments_ == 0) warn(line, std::move(message));
    ++dropped_comments_;
  }

  // A number of an attribute key, with diagnostics; nullopt (after a warning) if unreadable
  // or larger than `max`.
  std::optional<std::uint64_t> number(std::string_view key, std::string_view value, int line,
                                      std::uint64_t max) {
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

  void device_info_key(std::string_view key, std::string_view value, int line) {
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

  void dummy_usage_key(std::string_view key, std::string_view value, int line) {
    // CiA 306 §4.5: Dummy<type index>=0|1.
    const bool named = istarts_with(key, "Dummy") && parse_hex_digits(key.substr(5), 4);
    if (!named) warn(line, where() + std::string(key) + " is not a DummyXXXX key");
    std::string_view text = without_comment(value, key, line);
    auto n = parse_number(text);
    if (!n || n->value > 1) {
      warn(line, where() + std::string(key) + " " + shown(text) + " should be 0 or 1");
    }
    add_key_value(dummy_usage_, key, text, line);
  }

  void comments_key(std::string_view key, std::string_view value, int line) {
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

  void list_key(std::string_view key, std::string_view value, int line) {
    ListState& list = lists_[static_cast<std::size_t>(cur_.list)];
    if (iequals(key, "SupportedObjects")) {
      if (list.supported) {
        warn(line, where() + "SupportedObjects is given a second time; the later value is used");
      }
      list.supported = number(key, value, line, 0xFFFF);
      list.supported_line = line;
      return;
    }
    auto n = parse_number(key);
    if (!n || n->value == 0 || n->h_suffix) {
      warn(line, where() + "key " + std::string(key) +
                     " is neither SupportedObjects nor an entry number; ignored");
      return;
    }
    if (auto index = number(key, value, line, 0xFFFF)) {
      list.entries.emplace_back(static_cast<std::uint16_t>(*index), line);
    }
  }

  void commissioning_key(std::string_view key, std::string_view value, int line) {
    DeviceCommissioning& c = *model_.commissioning;
    auto [it, inserted] = commissioning_keys_.emplace(key, line);
    if (!inserted) {
      warn(line, where() + std::string(key) + " is given a second time (first at line " +
                     std::to_string(it->second) + "); the later value is used");
    }
    // CiA 306 §4.7.
    if (iequals(key, "NodeID")) {
      auto n = number(key, value, line, 0xFF);
      if (n && (*n < 1 || *n > 127)) {
        warn(line,
             where() + "NodeID " + std::to_string(*n) + " is not a node-ID (1..127); ignored");
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
      if (auto n = number(key, value, line, 0xFFFF))
        c.baudrate_kbps = static_cast<std::uint16_t>(*n);
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

  void sub_entry_key(SubEntrySection& s, std::string_view key, std::string_view value, int line) {
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

  void object_links_key(std::string_view key, std::string_view value, int line) {
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

  // ---- object and sub-object sections
  void close_object_section() {
    std::array<const RawKey*, kKeyCount> slot{};
    for (const RawKey& k : cur_.keys) {
      auto id = object_key(k.key);
      if (!id) {
        unknown_key(k);
        continue;
      }
      const RawKey*& s = slot[static_cast<std::size_t>(*id)];
      if (s != nullptr) {
        warn(k.line, where() + std::string(k.key) + " is given a second time (first at line " +
                         std::to_string(s->line) + "); the later value is used");
      }
      s = &k;
    }
    auto get = [&](Key k) { return slot[static_cast<std::size_t>(k)]; };

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

  std::optional<ObjectType> object_type(const RawKey& k) {
    auto n = number(k.key, k.value, k.line, 0xFF);
    if (!n) return std::nullopt;
    auto t = object_type_from_code(static_cast<unsigned>(*n));
    if (!t) {
      warn(k.line, where() + "ObjectType " + hex(*n, 1) +
                       " is not an object code of CiA 301 (0, 2, 5-9); ignored");
    }
    return t;
  }

  template <class Get>
  void apply_entry(SubObject& s, Get&& get, bool needs_type) {
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
          error(k->line,
                where() + "AccessType " + shown(text) + ": CiA 306 writes it in lower case");
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
        if (k->value.empty()) {
          field.reset();
        } else {
          field.emplace(k->value);
        }
      }
    };
    text_key(Key::Denotation, s.denotation);
    text_key(Key::UploadFile, s.upload_file);
    text_key(Key::DownloadFile, s.download_file);

    std::optional<Value> low, high, def, param;
    auto value_key = [&](Key key, OptionalText& field, std::optional<Value>& parsed) {
      if (const RawKey* k = get(key)) {
        field = clean_value(cur_.name, *k, s.data_type, &parsed);
      }
    };
    value_key(Key::LowLimit, s.low_limit, low);
    value_key(Key::HighLimit, s.high_limit, high);
    value_key(Key::DefaultValue, s.default_value, def);
    value_key(Key::ParameterValue, s.parameter_value, param);
    check_limits(s, get, low, high, def, param);
  }

  template <class Get>
  void check_limits(const SubObject& s, Get&& get, std::optional<Value>& low,
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
          warn(r->line, where() + std::string(r->key) + " " + shown(*text) +
                            " is above HighLimit " + shown(*s.high_limit));
        }
      }
    };
    check(def, Key::DefaultValue, s.default_value);
    check(param, Key::ParameterValue, s.parameter_value);
  }

  // The stored text of a value key: inline comment cut (numbers), empty fixed-size value
  // dropped, h-suffix hex normalised; then checked against the data type.
  std::optional<std::string> clean_value(std::string_view section_name, const RawKey& k,
                                         std::uint16_t data_type, std::optional<Value>* parsed) {
    const DataTypeInfo* info = find_data_type(data_type);
    auto section = [&] { return "[" + std::string(section_name) + "] "; };
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
    if (info == nullptr || info->type_class == TypeClass::VisibleString) return n.text;
    auto v = parse_value(info->type, *n.text, kValidationNodeId);
    if (!v) {
      const std::string msg = section() + std::string(k.key) + " " + shown(*n.text) +
                              " is not a valid " + std::string(info->name) + " (DataType " +
                              hex(data_type, 4) + "): " + v.error().message;
      // A ParameterValue is what a configuration manager downloads: one that cannot be encoded
      // is an error in either mode. A vendor's bad DefaultValue or limit stays a warning.
      if (iequals(k.key, "ParameterValue")) {
        error(k.line, msg);
      } else {
        warn(k.line, msg);
      }
    } else if (parsed != nullptr && !mentions_node_id(*n.text)) {
      *parsed = std::move(v.value());
    }
    return n.text;
  }

  void unknown_key(const RawKey& k) {
    auto [it, inserted] = unknown_keys_.emplace(k.key, UnknownKey{k.line, 0});
    ++it->second.count;
  }

  // ---- after the last line
  void finish() {
    for (auto& [index, st] : states_) finish_object(index, st);
    check_object_lists();
    finish_comments();
    if (!strict_ && dropped_comments_ > 1) {
      warn(0, std::to_string(dropped_comments_ - 1) +
                  " more values have a comment after them, dropped the same way (--strict lists "
                  "each)");
    }
    for (const auto& [key, u] : unknown_keys_) {
      const std::string msg = "key " + std::string(key) +
                              " is not a CiA 306 object key and is ignored" +
                              (u.count > 1 ? " (" + std::to_string(u.count) + " times)" : "");
      if (strict_) {
        error(u.line, msg);
      } else {
        add(u.line, Severity::Note, msg);
      }
    }
    if (strict_ && !seen_.file_info) error(0, "the file has no [FileInfo] section");
    if (!seen_.device_info) warn(0, "the file has no [DeviceInfo] section");
    if (!model_.objects.empty()) {
      for (std::uint16_t index :
           {std::uint16_t{0x1000}, std::uint16_t{0x1001}, std::uint16_t{0x1018}}) {
        if (!model_.object(index)) {
          warn(0, "mandatory object " + hex(index, 4) + " is missing (CiA 301)");
        }
      }
    }
  }

  void finish_object(std::uint16_t index, ObjectState& st) {
    const std::string sec = section_of(index);
    if (!st.has_main) {
      const int line = st.sub_seen.any()        ? st.first_sub_line
                       : st.names.present       ? st.names.line
                       : st.values.present      ? st.values.line
                       : st.denotations.present ? st.denotations.line
                                                : st.links_line;
      warn(line, "sections for object " + hex(index, 4) + " but no " + sec +
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
        warn(obj.subs.begin()->second.line, sec + " is a " +
                                                std::string(to_string(obj.object_type)) +
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
          warn(s->line, "[" + hex(index, 4).substr(2) + std::string(what) + "] is for " + sec +
                            ", which is a " + std::string(to_string(obj.object_type)) +
                            " and has no sub-objects; ignored");
        }
      }
      SubObject entry = std::move(st.main);
      entry.sub_index = 0;
      entry.object_type = obj.object_type;
      entry.line = st.main_line;
      obj.subs.emplace(0, std::move(entry));
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
      error(st.main_line, sec + " has [" + hex(index, 4).substr(2) +
                              "Name/Value/Denotation] sections but no CompactSubObj");
    }
    if (obj.subs.empty()) {
      warn(st.main_line,
           sec + " " + std::string(to_string(obj.object_type)) + " has no sub-objects");
    } else if (!obj.sub(0)) {
      warn(st.main_line, sec + " has no sub-index 0 (highest sub-index supported)");
    }
  }

  void expand_compact(Object& obj, ObjectState& st, const std::string& sec) {
    std::uint8_t n = *st.compact;
    if (n == 0xFF) {
      warn(st.compact_line, sec +
                                " CompactSubObj 255 would use the reserved sub-index FFh; "
                                "254 sub-objects are used");
      n = 0xFE;
    }
    // lely's dcfgen writes PDO mapping RECORDs this way and lely reads them; only lint.
    if (obj.object_type != ObjectType::Array && strict_) {
      error(st.compact_line, sec + " CompactSubObj on a " +
                                 std::string(to_string(obj.object_type)) +
                                 "; CiA 306 defines it for ARRAY objects");
    }
    if (st.sub_number) {
      warn(st.sub_number_line,
           sec + " has both SubNumber and CompactSubObj; CompactSubObj is used");
    }
    std::map<std::uint8_t, SubObject> explicit_subs = std::move(obj.subs);
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
      for (const auto& [sub, s] : explicit_subs) list += (list.empty() ? "" : ", ") + hex(sub, 2);
      warn(explicit_subs.begin()->second.line,
           sec + " uses CompactSubObj, but sub-index " + list +
               " also has its own section, which replaces the expanded entry");
    }
    for (auto& [sub, s] : explicit_subs) obj.subs[sub] = std::move(s);
  }

  template <class Apply>
  void apply_sub_entries(Object& obj, const SubEntrySection& s, std::string_view what,
                         Apply&& apply) {
    if (!s.present) return;
    const std::string sec = "[" + hex(obj.index, 4).substr(2) + std::string(what) + "]";
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

  void check_entry_count(const SubEntrySection& s, const std::string& sec) {
    if (!s.count) {
      warn(s.line, sec + " has no NrOfEntries");
    } else if (*s.count != s.entries.size()) {
      warn(s.count_line, sec + " NrOfEntries " + std::to_string(*s.count) + " but " +
                             std::to_string(s.entries.size()) + " entries are given");
    }
  }

  void apply_values(Object& obj, ObjectState& st) {
    if (!st.values.present) return;
    const std::string name = hex(obj.index, 4).substr(2) + "Value";
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
      sub->parameter_value = clean_value(name, raw, sub->data_type, &parsed);
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

  void finish_links(Object& obj, const ObjectState& st) {
    if (!st.has_links) return;
    std::vector<std::pair<std::uint64_t, std::uint16_t>> links = st.links;
    std::stable_sort(links.begin(), links.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    obj.object_links.clear();
    for (const auto& l : links) obj.object_links.push_back(l.second);
    const std::string lsec = "[" + hex(obj.index, 4).substr(2) + "ObjectLinks]";
    if (!st.links_count) {
      warn(st.links_line, lsec + " has no ObjectLinks count");
    } else if (*st.links_count != links.size()) {
      warn(st.links_line, lsec + " ObjectLinks " + std::to_string(*st.links_count) + " but " +
                              std::to_string(links.size()) + " entries are given");
    }
  }

  void check_object_lists() {
    static constexpr std::array<std::string_view, 3> kNames = {
        "MandatoryObjects", "OptionalObjects", "ManufacturerObjects"};
    static constexpr std::array<ObjectList, 3> kKinds = {
        ObjectList::Mandatory, ObjectList::Optional, ObjectList::Manufacturer};
    std::map<std::uint16_t, int> listed;  // index -> line
    bool any_list = false;
    for (std::size_t i = 0; i < 3; ++i) {
      const ListState& list = lists_[i];
      if (!list.present) continue;
      any_list = true;
      const std::string sec = "[" + std::string(kNames[i]) + "]";
      if (!list.supported) {
        warn(list.line, sec + " has no SupportedObjects");
      } else if (*list.supported != list.entries.size()) {
        warn(list.supported_line, sec + " SupportedObjects " + std::to_string(*list.supported) +
                                      " but " + std::to_string(list.entries.size()) +
                                      " objects are listed; the listed objects are used");
      }
      for (const auto& [index, line] : list.entries) {
        auto [it, inserted] = listed.emplace(index, line);
        if (!inserted) {
          warn(line, sec + " lists " + hex(index, 4) + " again (first at line " +
                         std::to_string(it->second) + ")");
          continue;
        }
        if (strict_ && object_list_for(index) != kKinds[i]) {
          error(line, sec + " lists " + hex(index, 4) + ", which belongs in [" +
                          std::string(to_string(object_list_for(index))) + "]");
        }
        if (!model_.object(index)) {
          warn(line, sec + " lists " + hex(index, 4) + " but the file has no " + section_of(index) +
                         " section; no such object");
        }
      }
    }
    if (!any_list) {
      if (!model_.objects.empty()) {
        warn(0,
             "the file has no object lists ([MandatoryObjects], [OptionalObjects], "
             "[ManufacturerObjects]); objects are taken from their sections");
      }
      return;
    }
    // One warning for all of them: some files leave out whole groups (all PDO objects).
    std::vector<const Object*> unlisted;
    for (const auto& [index, obj] : model_.objects) {
      if (!listed.count(index)) unlisted.push_back(&obj);
    }
    if (!unlisted.empty()) {
      constexpr std::size_t kShown = 8;
      std::string names;
      for (std::size_t i = 0; i < unlisted.size() && i < kShown; ++i) {
        names += (i ? ", " : "") + section_of(unlisted[i]->index);
      }
      if (unlisted.size() > kShown) {
        names += " and " + std::to_string(unlisted.size() - kShown) + " more";
      }
      warn(unlisted.front()->line, names + (unlisted.size() == 1 ? " is" : " are") +
                                       " in no object list ([MandatoryObjects], [OptionalObjects], "
                                       "[ManufacturerObjects]); kept");
    }
  }

  void finish_comments() {
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

  int comment_section_line() const {
    auto it = first_section_line_.find(std::string_view("Comments"));
    return it == first_section_line_.end() ? 0 : it->second;
  }

  struct Seen {
    bool file_info = false, device_info = false, dummy_usage = false, comments = false,
         commissioning = false;
  };
  struct UnknownKey {
    int line = 0;
    std::size_t count = 0;
  };

  ReadOptions options_;
  bool strict_ = false;
  DeviceDescription model_;
  std::vector<Diagnostic> diagnostics_;
  std::array<std::size_t, 3> suppressed_{};
  Current cur_;
  std::size_t sections_seen_ = 0;
  std::size_t expanded_budget_ = 0;  // sub-objects CompactSubObj may still create
  Seen seen_;
  std::array<ListState, 3> lists_;
  std::map<std::uint16_t, ObjectState> states_;
  ObjectState* last_state_ = nullptr;
  std::uint16_t last_state_index_ = 0;
  Object* last_object_ = nullptr;
  std::uint16_t last_object_index_ = 0;
  KeyValueBuilder file_info_, device_info_, dummy_usage_, commissioning_other_;
  CaseInsensitiveMap<std::size_t> other_index_;
  std::vector<KeyValueBuilder> other_builders_;
  CaseInsensitiveMap<int> first_section_line_;
  CaseInsensitiveMap<int> commissioning_keys_;
  CaseInsensitiveMap<UnknownKey> unknown_keys_;
  std::size_t dropped_comments_ = 0;  // inline comments cut from numeric values
  std::optional<std::uint64_t> comment_lines_;
  int comment_lines_line_ = 0;
  std::map<std::uint64_t, std::pair<std::string_view, int>> comment_text_;
};

}  // namespace

ReadResult parse_device_description(std::string_view text, const ReadOptions& options) {
  Reader reader(options);
  return reader.run(text);
}

ReadResult read_device_file(const std::string& path, ReadOptions options) {
  if (options.file_name.empty()) options.file_name = path;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    ReadResult result;
    result.diagnostics.add(options.file_name, 0, Severity::Error,
                           std::string("cannot open the file: ") + std::strerror(errno));
    return result;
  }
  std::string text;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(0, std::ios::beg);
  if (size > 0) {
    text.resize(static_cast<std::size_t>(size));
    in.read(text.data(), size);
    text.resize(static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) {
    ReadResult result;
    result.diagnostics.add(options.file_name, 0, Severity::Error, "cannot read the file");
    return result;
  }
  return parse_device_description(text, options);
}

}  // namespace cfg
