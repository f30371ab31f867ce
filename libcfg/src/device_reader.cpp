// The CiA 306 EDS/DCF reader. CiA 306 is implemented from public knowledge of the standard (its
// text is not in spec/); where real files and the standard part ways, the choices are listed here
// and asserted in tests/cfg/device_reader_test.cpp.
//
// Structure: ini_scanner hands over sections and key lines as views into the text
// (device_reader_sections.cpp dispatches them). The keys of an object or sub-object section are
// collected and applied when the section ends, because how a value is read depends on DataType,
// which may come after it (device_reader_keys.cpp). Everything that needs the whole file
// (CompactSubObj expansion, [xxxxName]/[xxxxValue]/[xxxxDenotation], SubNumber:
// device_reader_compact.cpp; object lists: device_reader_lists.cpp) is resolved in finish(). Only
// what the model keeps is allocated.
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
// - DOMAIN/OCTET_STRING values as one 0x-prefixed run of hex digits, as motor-controller vendor
//   tools export them: no diagnostic, stored without the prefix (the same bytes, the writer's
//   form). An odd number of digits is an error like any value that is not of its type.
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
#include <cerrno>
#include <cstring>
#include <limits>

#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "device_reader.hpp"

namespace cfg {
namespace detail::reader {

std::string section_of(std::uint16_t index) {
  return "[" + hex_digits(index, 4) + "]";
}

std::string shown(std::string_view text) {
  constexpr std::size_t kMax = 48;
  if (text.size() <= kMax) return "\"" + std::string(text) + "\"";
  return "\"" + std::string(text.substr(0, kMax)) + "...\" (" + std::to_string(text.size()) +
         " characters)";
}

ReadResult Reader::run(std::string_view text) {
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
  // The model's nodes take about 1.3 bytes per byte of a typical file (1.7 for terse files):
  // one block of 1.5x mostly holds them, and untouched pages of it cost no memory.
  arena_ = std::make_shared<ModelArena>(text.size() + text.size() / 2);
  model_.objects = Objects(ModelAllocator<Objects::value_type>(arena_));
  file_info_.kv = &model_.file_info;
  device_info_.kv = &model_.device_info;
  dummy_usage_.kv = &model_.dummy_usage;
  detail::scan_ini(text, *this);
  close_section();
  // The model holds copies: what finish() still looks up in the file (section names, the
  // texts of [xxxxName]/[xxxxValue], comments) is read back page by page if at all.
  if (file_ != nullptr) release_pages_before(text.data() + text.size());
  if (sections_seen_ == 0) {
    diagnostics_.clear();  // line-by-line complaints about a non-INI file help nobody
    suppressed_ = {};
    error(0, "no [section] header found: this is not an EDS/DCF file");
    result.diagnostics = take_diagnostics();
    return result;
  }
  finish();
  arena_->seal();  // edits of the model from here on allocate from the heap
  result.device = std::move(model_);
  result.diagnostics = take_diagnostics();
  return result;
}

ReadResult Reader::run(const FileText& file) {
  file_ = &file;
  file_released_ = 0;
  ReadResult result = run(file.view());
  file_ = nullptr;
  return result;
}

void Reader::release_pages_before(const char* at) {
  // A madvise call per step: the file's resident part stays within a step and the current
  // section, at a few calls per megabyte.
  constexpr std::size_t kStep = std::size_t{256} << 10;
  const auto offset = static_cast<std::size_t>(at - file_->view().data());
  const bool to_end = offset >= file_->size();
  if (!to_end && offset - file_released_ < kStep) return;
  file_->release_pages(file_released_, offset);
  file_released_ = offset;
}

void Reader::add(int line, Severity severity, std::string message) {
  if (diagnostics_.size() >= kMaxDiagnostics) {
    ++suppressed_[static_cast<int>(severity)];
    return;
  }
  diagnostics_.push_back({options_.file_name, line, severity, std::move(message)});
}

Diagnostics Reader::take_diagnostics() {
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

void Reader::finish_node_id_values() {
  // A DCF saved from a device at one node-ID and edited to another keeps the first one's
  // pre-defined COB-IDs (a vendor tool's DCF of a device at node 1, NodeID=12, records 1200h
  // sub 1 = 0x601). The device at node 12 derives its own (CiA 301 §7.3.5; simulated devices
  // do too, cfg::device_entries), so the recorded value says something the device never does.
  const std::optional<std::uint8_t> node = model_.node_id();
  if (!node) return;
  const std::optional<std::uint8_t> at = recorded_node_id(model_);
  if (!at || *at == *node) return;
  for (const auto& [index, object] : model_.objects) {
    for (const auto& [sub_index, sub] : object.subs) {
      if (!sub.parameter_value || !sub.default_value) continue;
      const auto type = sub.basic_type();
      if (!type || !is_default_at(*type, *sub.default_value, *sub.parameter_value, *at)) continue;
      auto derived = parse_value(*type, *sub.default_value, *node);
      add(sub.parameter_value_line, Severity::Warning,
          to_string(ObjectAddress{index, sub_index}) + ": ParameterValue " +
              std::string(*sub.parameter_value) + " is DefaultValue " +
              std::string(*sub.default_value) + " for node-ID " + std::to_string(*at) +
              ", but NodeID is " + std::to_string(*node) +
              ": a value recorded for another node-ID; the device at node " +
              std::to_string(*node) + " derives " +
              (derived ? format_value(*derived) : std::string("its own")) + " (CiA 301 §7.3.5)");
    }
  }
}

void Reader::finish() {
  for (auto& [index, st] : states_) finish_object(index, st);
  check_object_lists();
  finish_comments();
  finish_dynamic_channels();
  finish_node_id_values();
  if (!strict_ && dropped_comments_ > 1) {
    warn(0, std::to_string(dropped_comments_ - 1) +
                " more values have a comment after them, dropped the same way (strict mode lists "
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
        warn(0, "mandatory object " + object_name(index) + " is missing (CiA 301)");
      }
    }
  }
}

}  // namespace detail::reader

ReadResult parse_device_description(std::string_view text, const ReadOptions& options) {
  detail::reader::Reader reader(options);
  return reader.run(text);
}

ReadResult parse_device_description(const FileText& text, const ReadOptions& options) {
  detail::reader::Reader reader(options);
  return reader.run(text);
}

ReadResult read_device_file(const std::string& path, ReadOptions options) {
  if (options.file_name.empty()) options.file_name = path;
  auto text = read_file(path);
  if (!text) {
    ReadResult result;
    result.diagnostics.add(options.file_name, 0, Severity::Error, text.error().message);
    return result;
  }
  return parse_device_description(*text, options);
}

}  // namespace cfg
