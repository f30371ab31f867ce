// The CiA 306 EDS/DCF writer. It writes canonical_form() of the model verbatim, so that what it
// writes reads back as exactly that model (the round-trip contract in cfg/device_file.hpp).
#include <algorithm>
#include <array>
#include <charconv>
#include <cstring>
#include <memory>
#include <span>
#include <unordered_map>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/node_id.hpp"
#include "device_file_detail.hpp"
#include "ini_scanner.hpp"

namespace cfg {
namespace {

using detail::trim_blanks;

// Text as one trimmed line: a line break inside would end the key or start a new one.
std::string one_line(std::string_view text) {
  std::string out(text);
  std::replace(out.begin(), out.end(), '\r', ' ');
  std::replace(out.begin(), out.end(), '\n', ' ');
  return std::string(trim_blanks(out));
}

// Already what one_line() makes of it: nearly every text of a file, so no copy is made.
bool is_one_line(std::string_view text) {
  // A plain loop: find_first_of("\r\n") calls memchr on the set for every character.
  for (const char c : text) {
    if (c == '\r' || c == '\n') return false;
  }
  return trim_blanks(text).size() == text.size();
}

void clean_text(std::string& text) {
  if (!is_one_line(text)) text = one_line(text);
}

void clean_text(OptionalText& text, bool drop_empty) {
  if (!text) return;
  clean_text(*text);
  if (drop_empty && text->empty()) text.reset();
}

// A key that reads back as itself: not empty, no '=' (the first '=' ends the key), not taken
// for a comment or a section header. Input is one_line()d.
bool writable_key(std::string_view key) {
  if (key.empty() || key.find('=') != std::string_view::npos) return false;
  return key.front() != ';' && key.front() != '#' && key.front() != '[';
}

bool writable_section_name(std::string_view name) {
  return !name.empty() && name.find(']') == std::string_view::npos &&
         !detail::is_reserved_section_name(name);
}

struct CaseInsensitiveHash {
  std::size_t operator()(std::string_view s) const {
    std::size_t h = 1469598103934665603ULL;
    for (char c : s) {
      h ^= static_cast<unsigned char>((c >= 'A' && c <= 'Z') ? c - 'A' + 'a' : c);
      h *= 1099511628211ULL;
    }
    return h;
  }
};
struct CaseInsensitiveEqual {
  bool operator()(std::string_view a, std::string_view b) const { return iequals(a, b); }
};

// Merges `from` into `into` as the reader does a repeated key: the first position, the later
// value. Keys and values become single trimmed lines; unwritable keys go.
void merge_key_values(KeyValues& into, const KeyValues& from) {
  std::unordered_map<std::string, std::size_t, CaseInsensitiveHash, CaseInsensitiveEqual> index;
  for (std::size_t i = 0; i < into.entries.size(); ++i) index.emplace(into.entries[i].first, i);
  for (const auto& [key, value] : from.entries) {
    std::string k = one_line(key);
    if (!writable_key(k)) continue;
    std::string v = one_line(value);
    auto it = index.find(k);
    if (it != index.end()) {
      into.entries[it->second].second = std::move(v);
      continue;
    }
    index.emplace(k, into.entries.size());
    into.entries.emplace_back(std::move(k), std::move(v));
  }
}

KeyValues canonical_key_values(const KeyValues& kv) {
  KeyValues out;
  merge_key_values(out, kv);
  return out;
}

// What the reader keeps of a number-valued key: the text before an inline comment.
void cut_comment(std::string& value) {
  const std::size_t c = detail::find_inline_comment(value);
  if (c != std::string::npos)
    value = std::string(trim_blanks(std::string_view(value).substr(0, c)));
}

// Proleptic Gregorian calendar date of a day count since 1970-01-01 (H. Hinnant's
// days_from_civil inverse); no locale, no time zone: the stamp is UTC.
struct Civil {
  std::int64_t year;
  unsigned month, day, hour, minute;
};
Civil civil_from_unix(std::int64_t t) {
  std::int64_t days = t / 86400;
  std::int64_t secs = t % 86400;
  if (secs < 0) {
    secs += 86400;
    --days;
  }
  const std::int64_t z = days + 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const auto doe = static_cast<std::uint64_t>(z - era * 146097);
  const std::uint64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const std::int64_t y = static_cast<std::int64_t>(yoe) + era * 400;
  const std::uint64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const std::uint64_t mp = (5 * doy + 2) / 153;
  const auto d = static_cast<unsigned>(doy - (153 * mp + 2) / 5 + 1);
  const auto m = static_cast<unsigned>(mp < 10 ? mp + 3 : mp - 9);
  return {m <= 2 ? y + 1 : y, m, d, static_cast<unsigned>(secs / 3600),
          static_cast<unsigned>((secs % 3600) / 60)};
}

std::string two_digits(unsigned v) {
  return std::string{static_cast<char>('0' + v / 10 % 10), static_cast<char>('0' + v % 10)};
}

// CiA 306 §4.3 [FileInfo]: time "hh:mm(AM|PM)", date "mm-dd-yyyy".
std::string stamp_time(const Civil& c) {
  const unsigned h12 = c.hour % 12 == 0 ? 12 : c.hour % 12;
  return two_digits(h12) + ":" + two_digits(c.minute) + (c.hour < 12 ? "AM" : "PM");
}
std::string stamp_date(const Civil& c) {
  return two_digits(c.month) + "-" + two_digits(c.day) + "-" + std::to_string(c.year);
}

void apply_stamp(KeyValues& file_info, const WriteOptions::Stamp& stamp) {
  const Civil c = civil_from_unix(stamp.unix_time_s);
  const std::string time = stamp_time(c), date = stamp_date(c);
  if (!file_info.find("CreatedBy")) file_info.set("CreatedBy", stamp.modified_by);
  if (!file_info.find("CreationTime")) file_info.set("CreationTime", time);
  if (!file_info.find("CreationDate")) file_info.set("CreationDate", date);
  file_info.set("ModificationTime", time);
  file_info.set("ModificationDate", date);
  file_info.set("ModifiedBy", stamp.modified_by);
}

// The text itself when it is already one line (nearly always: no copy), else its one_line(),
// kept in `scratch`.
std::string_view clean_view(std::string_view text, std::string& scratch) {
  if (is_one_line(text)) return text;
  scratch = one_line(text);
  return scratch;
}

// A value as canonical_form() stores it; nullopt when it is dropped.
std::optional<std::string> canonical_value(std::string_view text, std::uint16_t data_type) {
  std::string scratch;
  return detail::normalize_value(clean_view(text, scratch), data_type).text;
}

void canonical_entry(SubObject& s, FileKind kind) {
  clean_text(s.name);
  for (OptionalText* v : {&s.default_value, &s.parameter_value, &s.low_limit, &s.high_limit}) {
    if (!*v) continue;
    auto normalized = canonical_value(**v, s.data_type);
    if (!normalized) {
      v->reset();
    } else if (*normalized != **v) {
      **v = std::move(*normalized);
    }
  }
  clean_text(s.denotation, true);
  clean_text(s.upload_file, true);
  clean_text(s.download_file, true);
  if (kind == FileKind::Eds) {
    s.parameter_value.reset();
    s.denotation.reset();
  }
}

// ---- output
// Collects the text in a block of about kBlock bytes and hands each full block to the sink, so
// that a whole file's text is never held at once. Once the sink says stop, nothing more is kept.
// Lines are formatted straight into the block (this runs for every key of a file: no temporary
// strings).
class Out {
 public:
  static constexpr std::size_t kBlock = std::size_t{64} * 1024;
  static constexpr std::size_t kSlack = 16;

  Out(LineEnding ending, const TextSink& sink)
      : eol_(ending == LineEnding::Crlf ? "\r\n" : "\n"),
        eol_size_(ending == LineEnding::Crlf ? 2 : 1),
        capacity_(kBlock + 512),
        text_(std::make_unique<char[]>(capacity_)),
        sink_(sink) {}

  void section(std::string_view name) {
    char* p = section_start(name.size());
    p = put(p, name);
    section_end(p);
  }
  // [XXXXsubYY] of a sub-object (CiA 306 §4.6.2).
  void sub_section(std::uint16_t index, std::uint8_t sub) {
    char* p = section_start(16 + 3 + 16);  // write_hex_digits needs room for 16
    p = write_hex_digits(p, index, 4);
    p = put(p, "sub");
    p = write_hex_digits(p, sub);
    section_end(p);
  }
  // `prefix` is the key with its '=' ("DataType="): a line of a key of the standard.
  void line(std::string_view prefix, std::string_view value) {
    char* p = room(prefix.size() + value.size());
    p = put(p, prefix);
    p = put(p, value);
    end_line(p);
  }
  // `prefix` followed by "0x" and hex_digits(value, min_digits).
  void hex_line(std::string_view prefix, std::uint64_t value, int min_digits = 1) {
    char* p = room(prefix.size() + 2 + 16);
    p = put(p, prefix);
    p = put(p, "0x");
    p = write_hex_digits(p, value, min_digits);
    end_line(p);
  }
  // `prefix` followed by `value` in decimal.
  void number_line(std::string_view prefix, std::uint64_t value) {
    char* p = room(prefix.size() + 20);
    p = put(p, prefix);
    p = std::to_chars(p, p + 20, value).ptr;
    end_line(p);
  }
  // `count_prefix` with the number of entries, then "1=0xXXXX" .. "n=0xXXXX": the index lists
  // of CiA 306 (the object lists of §4.5, [xxxxObjectLinks]).
  void index_list(std::string_view count_prefix, std::span<const std::uint16_t> indices) {
    number_line(count_prefix, indices.size());
    for (std::size_t i = 0; i < indices.size(); ++i) {
      char* p = room(20 + 1 + 2 + 16);
      p = std::to_chars(p, p + 20, i + 1).ptr;
      *p++ = '=';
      p = put(p, "0x");
      p = write_hex_digits(p, indices[i], 4);
      end_line(p);
    }
  }
  void key(std::string_view key, std::string_view value) {
    char* p = room(key.size() + 1 + value.size());
    p = put(p, key);
    *p++ = '=';
    p = put(p, value);
    end_line(p);
  }
  void key_values(const KeyValues& kv) {
    for (const auto& [k, v] : kv.entries) key(k, v);
  }
  /// Hands what is left to the sink; false when the sink stopped the output.
  bool finish() {
    if (!stopped_ && size_ != 0) stopped_ = !sink_(std::string_view(text_.get(), size_));
    size_ = 0;
    return !stopped_;
  }
  bool stopped() const { return stopped_; }

 private:
  // Nearly every piece is short (a key name, a number): copied inline with at most two
  // overlapping moves, which costs less than a call of memcpy.
  static char* put(char* p, std::string_view s) {
    const char* from = s.data();
    const std::size_t n = s.size();
    if (n >= 8 && n <= 16) {
      std::memcpy(p, from, 8);
      std::memcpy(p + n - 8, from + n - 8, 8);
    } else if (n >= 4 && n < 8) {
      std::memcpy(p, from, 4);
      std::memcpy(p + n - 4, from + n - 4, 4);
    } else if (n != 0 && n < 4) {
      p[0] = from[0];
      p[n / 2] = from[n / 2];
      p[n - 1] = from[n - 1];
    } else if (n != 0) {
      std::memcpy(p, from, n);
    }
    return p + n;
  }
  // Room for `n` more characters and a line end at the end of the text, plus slack for the
  // fixed-size stores of put_eol; returns where they go.
  char* room(std::size_t n) {
    n += kSlack;
    if (capacity_ - size_ < n) grow(n);
    return text_.get() + size_;
  }
  void grow(std::size_t n) {  // only for a line longer than the slack (a long DOMAIN value)
    capacity_ = std::max(2 * capacity_, size_ + n);
    auto bigger = std::make_unique<char[]>(capacity_);
    std::memcpy(bigger.get(), text_.get(), size_);
    text_ = std::move(bigger);
  }
  // The line end as one 2-byte store (the second byte of "\n" is overwritten or unused).
  char* put_eol(char* p) const {
    std::memcpy(p, eol_, 2);
    return p + eol_size_;
  }
  char* section_start(std::size_t name_size) {
    char* p = room(2 + 2 + name_size + 2);
    if (started_) p = put_eol(p);  // a blank line between sections
    started_ = true;
    *p++ = '[';
    return p;
  }
  void section_end(char* p) {
    *p++ = ']';
    end_line(p);
  }
  void end_line(char* p) {
    p = put_eol(p);
    size_ = static_cast<std::size_t>(p - text_.get());
    if (size_ < kBlock) return;
    if (!stopped_) stopped_ = !sink_(std::string_view(text_.get(), size_));
    size_ = 0;
  }

  const char* eol_;  // 2 characters are there: "\r\n", or "\n" and its terminator
  std::size_t eol_size_;
  std::size_t capacity_;
  std::unique_ptr<char[]> text_;
  std::size_t size_ = 0;
  const TextSink& sink_;
  bool started_ = false;
  bool stopped_ = false;
};

// The value text canonical_form() stores for `text` (nullopt: it is dropped). The text itself
// when the reader made it canonical already (nearly always: no copy); else made in `scratch`.
std::optional<std::string_view> canonical_value_view(std::string_view text, std::uint16_t data_type,
                                                     std::string& scratch) {
  if (detail::is_normalized_value(text, data_type)) return text;
  auto normalized = canonical_value(text, data_type);
  if (!normalized) return std::nullopt;
  scratch = std::move(*normalized);
  return scratch;
}

// The keys of an entry in CiA 306 §4.6.3 order (DCF keys of §4.7 after them), as
// canonical_entry() makes them, written from the model as it is (no copy of the entry).
void write_entry(Out& out, const SubObject& s, const std::optional<std::uint32_t>& obj_flags,
                 FileKind kind) {
  std::string scratch;
  auto value = [&](std::string_view prefix, const OptionalText& text) {
    if (!text) return;
    if (auto v = canonical_value_view(*text, s.data_type, scratch)) out.line(prefix, *v);
  };
  auto text = [&](std::string_view prefix, const OptionalText& t) {
    if (!t) return;
    const std::string_view clean = clean_view(*t, scratch);
    if (!clean.empty()) out.line(prefix, clean);
  };
  out.hex_line("DataType=", s.data_type, 4);
  out.line("AccessType=", to_string(s.access));
  value("DefaultValue=", s.default_value);
  out.line("PDOMapping=", s.pdo_mapping ? "1" : "0");
  value("LowLimit=", s.low_limit);
  value("HighLimit=", s.high_limit);
  if (obj_flags) out.hex_line("ObjFlags=", *obj_flags);
  if (kind == FileKind::Dcf) {
    value("ParameterValue=", s.parameter_value);
    text("Denotation=", s.denotation);
  }
  text("UploadFile=", s.upload_file);
  text("DownloadFile=", s.download_file);
}

// canonical_object() of `obj`, written from the model as it is (no copy of the object).
void write_object(Out& out, std::uint16_t index, const Object& obj, FileKind kind) {
  std::string scratch;
  // A 16-bit index is exactly four hex digits (CiA 306 §4.6.1): a fixed length also tells GCC at
  // -O3 which of put()'s copies runs (it warned of the 8..16-byte one reading past the buffer).
  char name_buf[16];
  write_hex_digits(name_buf, index, 4);
  const std::string_view name(name_buf, 4);
  out.section(name);
  out.line("ParameterName=", clean_view(obj.name, scratch));
  out.hex_line("ObjectType=", static_cast<unsigned>(obj.object_type));
  if (detail::var_like(obj.object_type)) {
    const SubObject* s = obj.sub(0);
    write_entry(out, s != nullptr ? *s : SubObject{}, obj.obj_flags, kind);
  } else {
    if (obj.subs.size() <= 0xFF) out.hex_line("SubNumber=", obj.subs.size());
    if (obj.obj_flags) out.hex_line("ObjFlags=", *obj.obj_flags);
    for (const auto& [sub, s] : obj.subs) {
      out.sub_section(index, sub);
      out.line("ParameterName=", clean_view(s.name, scratch));
      out.hex_line("ObjectType=", static_cast<unsigned>(s.object_type));
      write_entry(out, s, s.obj_flags, kind);
    }
  }
  if (!obj.object_links.empty()) {
    out.section(std::string(name) + "ObjectLinks");
    out.index_list("ObjectLinks=", obj.object_links);
  }
}

void write_commissioning(Out& out, const DeviceCommissioning& c) {
  // CiA 306 §4.7, with the standard's spelling of the section name.
  out.section("DeviceComissioning");
  if (c.node_id) out.key("NodeID", std::to_string(*c.node_id));
  out.key("NodeName", c.node_name);
  if (c.baudrate_kbps) out.key("Baudrate", std::to_string(*c.baudrate_kbps));
  if (c.net_number) out.key("NetNumber", std::to_string(*c.net_number));
  out.key("NetworkName", c.network_name);
  if (c.canopen_manager) out.key("CANopenManager", *c.canopen_manager ? "1" : "0");
  if (c.lss_serial_number) out.key("LSS_SerialNumber", hex(*c.lss_serial_number, 8));
  out.key_values(c.other);
}

// canonical_form() of one object, in place; index 0000h is no object and is left to the caller.
void canonical_object(std::uint16_t index, Object& obj, FileKind kind) {
  obj.index = index;
  clean_text(obj.name);
  obj.compact_sub_obj.reset();
  if (detail::var_like(obj.object_type)) {
    SubObject entry;
    if (SubObject* s = obj.sub(0)) entry = std::move(*s);
    obj.subs.clear();
    entry.sub_index = 0;
    entry.name = obj.name;
    entry.object_type = obj.object_type;
    entry.obj_flags.reset();
    canonical_entry(entry, kind);
    obj.subs.emplace(0, std::move(entry));
    obj.sub_number.reset();
  } else {
    for (auto& [sub, s] : obj.subs) {
      s.sub_index = sub;
      canonical_entry(s, kind);
    }
    if (obj.subs.size() <= 0xFF) {
      obj.sub_number = static_cast<std::uint8_t>(obj.subs.size());
    } else {
      obj.sub_number.reset();
    }
  }
}

// canonical_form() of everything but the objects, in place.
void canonical_file_parts(DeviceDescription& d, const WriteOptions& options) {
  if (options.stamp) apply_stamp(d.file_info, *options.stamp);
  d.file_info = canonical_key_values(d.file_info);
  d.device_info = canonical_key_values(d.device_info);
  for (auto& [key, value] : d.device_info.entries) {
    if (detail::is_numeric_device_info_key(key)) cut_comment(value);
  }
  d.dummy_usage = canonical_key_values(d.dummy_usage);
  for (auto& [key, value] : d.dummy_usage.entries) cut_comment(value);
  for (std::string& line : d.comments) clean_text(line);

  if (options.kind == FileKind::Eds) {
    d.commissioning.reset();
  } else if (d.commissioning) {
    DeviceCommissioning& c = *d.commissioning;
    if (c.node_id && !is_node_id(*c.node_id)) c.node_id.reset();
    clean_text(c.node_name);
    clean_text(c.network_name);
    KeyValues other = canonical_key_values(c.other);
    c.other.entries.clear();
    // Keys the reader takes into the fields above cannot come back as `other`.
    static constexpr std::array<std::string_view, 7> kKnown = {
        "NodeID",      "NodeName",       "Baudrate",        "NetNumber",
        "NetworkName", "CANopenManager", "LSS_SerialNumber"};
    for (auto& kv : other.entries) {
      const bool known = std::any_of(kKnown.begin(), kKnown.end(),
                                     [&](std::string_view k) { return iequals(kv.first, k); });
      if (!known) c.other.entries.push_back(std::move(kv));
    }
  }

  std::vector<RawSection> others;
  std::unordered_map<std::string, std::size_t, CaseInsensitiveHash, CaseInsensitiveEqual> index;
  for (RawSection& section : d.other_sections) {
    std::string name = one_line(section.name);
    if (!writable_section_name(name)) continue;
    auto [it, inserted] = index.emplace(name, others.size());
    if (inserted) others.push_back({std::move(name), {}});
    merge_key_values(others[it->second].keys, section.keys);
  }
  d.other_sections = std::move(others);
}

void write_file_info(Out& out, const KeyValues& file_info) {
  out.section("FileInfo");
  out.key_values(file_info);
}

}  // namespace

DeviceDescription canonical_form(DeviceDescription d, const WriteOptions& options) {
  canonical_file_parts(d, options);
  d.objects.erase(0);  // index 0000h is no object (CiA 301)
  for (auto& [index, obj] : d.objects) canonical_object(index, obj, options.kind);
  return d;
}

namespace {

// The file-level parts of `device`, copied and made canonical (the objects, nearly all of a
// file, are made canonical one at a time as they are written, so the model is never copied).
DeviceDescription canonical_head(const DeviceDescription& device, const WriteOptions& options) {
  DeviceDescription head;
  head.file_info = device.file_info;
  head.device_info = device.device_info;
  head.dummy_usage = device.dummy_usage;
  head.commissioning = device.commissioning;
  head.comments = device.comments;
  head.other_sections = device.other_sections;
  canonical_file_parts(head, options);
  return head;
}

// The whole text, `head` standing for device's file-level parts; stops early when the sink does.
bool write_text(const DeviceDescription& device, const DeviceDescription& head,
                const WriteOptions& options, const TextSink& sink) {
  Out out(options.line_ending, sink);
  write_file_info(out, head.file_info);
  out.section("DeviceInfo");
  out.key_values(head.device_info);
  if (!head.dummy_usage.entries.empty()) {
    out.section("DummyUsage");
    out.key_values(head.dummy_usage);
  }
  if (!head.comments.empty()) {
    out.section("Comments");
    out.key("Lines", std::to_string(head.comments.size()));
    for (std::size_t i = 0; i < head.comments.size(); ++i) {
      out.key("Line" + std::to_string(i + 1), head.comments[i]);
    }
  }
  // CiA 306 §4.5: the object lists, each with SupportedObjects and entries 1..n.
  for (ObjectList list : {ObjectList::Mandatory, ObjectList::Optional, ObjectList::Manufacturer}) {
    std::vector<std::uint16_t> indices;
    for (const auto& [index, obj] : device.objects) {
      if (index != 0 && object_list_for(index) == list) indices.push_back(index);
    }
    out.section(to_string(list));
    out.index_list("SupportedObjects=", indices);
  }
  for (const auto& [index, obj] : device.objects) {
    if (out.stopped()) return false;
    if (index == 0) continue;  // index 0000h is no object (CiA 301)
    write_object(out, index, obj, options.kind);
  }
  if (options.kind == FileKind::Dcf && head.commissioning) {
    write_commissioning(out, *head.commissioning);
  }
  for (const RawSection& section : head.other_sections) {
    out.section(section.name);
    out.key_values(section.keys);
  }
  return out.finish();
}

}  // namespace

bool write_device_description(const DeviceDescription& device, const WriteOptions& options,
                              const TextSink& sink) {
  if (!options.stamp || !options.stamp_only_if_changed_from) {
    return write_text(device, canonical_head(device, options), options, sink);
  }
  // Stamp only a change: the unstamped text is compared with the old one block by block as it
  // is made (nothing kept), stopping at the first difference.
  const std::string_view old_text = *options.stamp_only_if_changed_from;
  WriteOptions unstamped = options;
  unstamped.stamp.reset();
  std::size_t compared = 0;
  const bool same = write_text(device, canonical_head(device, unstamped), unstamped,
                               [&](std::string_view block) {
                                 if (old_text.substr(compared, block.size()) != block) return false;
                                 compared += block.size();
                                 return true;
                               }) &&
                    compared == old_text.size();
  if (same) return old_text.empty() || sink(old_text);  // the unstamped text is the old one
  return write_text(device, canonical_head(device, options), options, sink);
}

std::string write_device_description(const DeviceDescription& device, const WriteOptions& options) {
  std::string text;
  write_device_description(device, options, [&text](std::string_view block) {
    text += block;
    return true;
  });
  return text;
}

}  // namespace cfg
