// Private to libcfg: the CiA 306 EDS/DCF reader, the state it keeps while reading and the parts
// that fill it. device_reader.cpp documents the choices and drives a read; the parts are
//   device_reader_sections.cpp  section dispatch ([FileInfo], [DeviceInfo], [1000], [1000sub1],
//                               [DeviceComissioning], ...) and the key=value sections
//   device_reader_keys.cpp      object and sub-object keys and their values (CiA 306 §4.6.3)
//   device_reader_compact.cpp   each object assembled after the last line: CompactSubObj
//                               (§4.6.3.3), [xxxxName]/[xxxxValue]/[xxxxDenotation], ObjectLinks
//   device_reader_lists.cpp     [MandatoryObjects]/[OptionalObjects]/[ManufacturerObjects]
//   device_reader_dynamic.cpp   [DynamicChannels] (CiA DSP 302 §8.4) and its checks
#pragma once

#include <array>
#include <bitset>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/value.hpp"
#include "device_file_detail.hpp"
#include "dynamic_channels_read.hpp"
#include "ini_scanner.hpp"

namespace cfg::detail::reader {

// Keeps a pathological file from producing gigabytes of messages; the summary keeps
// has_errors() truthful.
constexpr std::size_t kMaxDiagnostics = 5000;
constexpr std::uint8_t kValidationNodeId = 1;  // $NODEID stand-in when checking formulas

inline char ascii_lower(char c) {
  return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c;
}

inline bool istarts_with(std::string_view text, std::string_view prefix) {
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

/// "[1017]": the section of an object, as a message quotes it.
std::string section_of(std::uint16_t index);

/// Text of a value for a message: quoted, long values cut.
std::string shown(std::string_view text);

// A number of an attribute key (SubNumber, DataType, list entries, ...): CiA 306 integer
// syntax, i.e. 0x hex, leading-0 octal, decimal.
struct Number {
  std::uint64_t value = 0;
  bool h_suffix = false;
};
std::optional<Number> parse_number(std::string_view text);

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
inline constexpr std::size_t kKeyCount = 15;

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
  DynamicChannels,
  Other,
};

struct RawKey {
  std::string_view key;
  std::string_view value;
  int line = 0;
};

/// The keys of one object or sub-object section, by Key (nullptr: not given; the later of two
/// wins).
struct ObjectKeys {
  // Which slots are set; the slots themselves are left unset otherwise, so that a section does
  // not start by clearing them (this runs once per section of the file).
  std::uint32_t present = 0;
  std::array<const RawKey*, kKeyCount> slot;  // NOLINT(cppcoreguidelines-pro-type-member-init)
  const RawKey* operator()(Key k) const {
    const auto i = static_cast<std::size_t>(k);
    return (present >> i & 1U) != 0 ? slot[i] : nullptr;
  }
  void set(Key k, const RawKey* key) {
    const auto i = static_cast<std::size_t>(k);
    slot[i] = key;
    present |= 1U << i;
  }
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

// [DynamicChannels] as read: its keys (views into the file) in file order, checked after the last
// line (device_reader_dynamic.cpp). The section itself is kept as a RawSection.
struct DynamicChannelsState {
  bool present = false;
  int line = 0;
  std::vector<DynamicChannelsKey> keys;
};

// A key=value section kept as text, with a case-insensitive index for duplicates.
struct KeyValueBuilder {
  KeyValues* kv = nullptr;
  CaseInsensitiveMap<std::pair<std::size_t, int>> index;  // key -> (entry position, line)
};

class Reader final : public IniSink {
 public:
  explicit Reader(const ReadOptions& options) : options_(options) {
    strict_ = options.mode == ReadMode::Strict;
  }

  /// Reads `text` (the whole file) into a model and diagnostics.
  ReadResult run(std::string_view text);
  /// Reads a file as read_file gave it, giving its pages back behind the reader.
  ReadResult run(const FileText& file);

  // ---- IniSink (device_reader_sections.cpp)
  void on_section(int line, std::string_view name, std::string_view trailing, bool closed) override;
  void on_key(int line, std::string_view key, std::string_view value) override;
  void on_comment(int line, char marker) override;
  void on_junk(int line, std::string_view text) override;

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
  void add(int line, Severity severity, std::string message);
  void error(int line, std::string message) { add(line, Severity::Error, std::move(message)); }
  // A deviation from CiA 306 the reader recovers from: warning (tolerant) or error (strict).
  void warn(int line, std::string message) {
    add(line, strict_ ? Severity::Error : Severity::Warning, std::move(message));
  }
  Diagnostics take_diagnostics();

  std::string where() const {
    if (cur_.kind == Kind::None) return "";
    return "[" + std::string(cur_.name) + "] ";
  }

  // ---- the object a section belongs to (the last one looked up is cached: sections of one
  // object usually follow each other)
  ObjectState& state(std::uint16_t index) {
    if (last_state_ == nullptr || last_state_index_ != index) {
      last_state_ = &states_[index];
      last_state_index_ = index;
    }
    return *last_state_;
  }

  Object& object(std::uint16_t index) {
    if (last_object_ == nullptr || last_object_index_ != index) {
      auto [it, inserted] = model_.objects.try_emplace(index);
      // The object's sub-objects go to the arena too (a default map is on the heap).
      if (inserted) it->second.subs = SubObjects(model_.objects.get_allocator());
      last_object_ = &it->second;
      last_object_->index = index;
      last_object_index_ = index;
    }
    return *last_object_;
  }
  // A value text of the model, kept in the arena (nullopt: none).
  void set_text(OptionalText& field, const std::optional<std::string_view>& text) {
    if (text) {
      field.emplace_in(*arena_, *text);
    } else {
      field.reset();
    }
  }

  // ---- sections (device_reader_sections.cpp)
  void open_section();
  // Sections named after an object index; false if the name only starts like one.
  bool open_object_section(std::uint16_t index, std::string_view rest);
  void open_other_section();
  void duplicate_section(int first_line);
  void close_section();
  void add_key_value(KeyValueBuilder& b, std::string_view key, std::string_view value, int line);
  void device_info_key(std::string_view key, std::string_view value, int line);
  void dummy_usage_key(std::string_view key, std::string_view value, int line);
  void comments_key(std::string_view key, std::string_view value, int line);
  void commissioning_key(std::string_view key, std::string_view value, int line);
  void object_links_key(std::string_view key, std::string_view value, int line);
  void finish_comments();
  int comment_section_line() const;

  // ---- object and sub-object keys and values (device_reader_keys.cpp)
  // Cuts an inline comment from a number-like value, with a warning.
  std::string_view without_comment(std::string_view value, std::string_view key, int line);
  // Hand-written profile files carry a comment after nearly every value: in tolerant mode say
  // it once in full and sum up the rest at the end (finish()), so other warnings stay visible.
  void dropped_comment(int line, std::string message);
  // A number of an attribute key, with diagnostics; nullopt (after a warning) if unreadable
  // or larger than `max`.
  std::optional<std::uint64_t> number(std::string_view key, std::string_view value, int line,
                                      std::uint64_t max);
  void close_object_section();
  std::optional<ObjectType> object_type(const RawKey& k);
  void apply_entry(SubObject& s, const ObjectKeys& get, bool needs_type);
  void check_limits(const SubObject& s, const ObjectKeys& get, std::optional<Value>& low,
                    std::optional<Value>& high, const std::optional<Value>& def,
                    const std::optional<Value>& param);
  // The stored text of a value key: inline comment cut (numbers), empty fixed-size value
  // dropped, h-suffix hex normalised; then checked against the data type.
  // The view is into the file, or into value_scratch_ until the next call.
  std::optional<std::string_view> clean_value(std::string_view section_name, const RawKey& k,
                                              std::uint16_t data_type,
                                              std::optional<Value>* parsed);
  void unknown_key(const RawKey& k);

  // ---- objects after the last line (device_reader_compact.cpp)
  void sub_entry_key(SubEntrySection& s, std::string_view key, std::string_view value, int line);
  void finish_object(std::uint16_t index, ObjectState& st);
  void expand_compact(Object& obj, ObjectState& st, const std::string& sec);
  void apply_sub_entries(Object& obj, const SubEntrySection& s, std::string_view what,
                         void (*apply)(SubObject&, std::string_view));
  void check_entry_count(const SubEntrySection& s, const std::string& sec);
  void apply_values(Object& obj, ObjectState& st);
  void finish_links(Object& obj, const ObjectState& st);

  // ---- object lists (device_reader_lists.cpp)
  void list_key(std::string_view key, std::string_view value, int line);
  void check_object_lists();

  // ---- [DynamicChannels] (device_reader_dynamic.cpp)
  void finish_dynamic_channels();
  void finish_node_id_values();

  // ---- after the last line (device_reader.cpp)
  void finish();
  // Gives back the pages of the file before `at` (a position in it), a step at a time.
  void release_pages_before(const char* at);

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
  // The file being read, when its pages are given back as the reader passes them (run(const
  // FileText&)); views into it stay valid, a page read again is read again from the file cache.
  const FileText* file_ = nullptr;
  std::size_t file_released_ = 0;  // bytes before this are given back
  // The model's maps and value texts live here (cfg/model_memory.hpp), sealed after the read.
  std::shared_ptr<ModelArena> arena_;
  DeviceDescription model_;
  std::vector<Diagnostic> diagnostics_;
  std::array<std::size_t, 3> suppressed_{};
  Current cur_;
  std::size_t sections_seen_ = 0;
  std::size_t expanded_budget_ = 0;  // sub-objects CompactSubObj may still create
  Seen seen_;
  std::array<ListState, 3> lists_;
  DynamicChannelsState dynamic_;
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
  std::string value_scratch_;  // a value text clean_value had to rewrite ('h' suffix, comment)
  std::size_t dropped_comments_ = 0;  // inline comments cut from numeric values
  std::optional<std::uint64_t> comment_lines_;
  int comment_lines_line_ = 0;
  std::map<std::uint64_t, std::pair<std::string_view, int>> comment_text_;
};

}  // namespace cfg::detail::reader
