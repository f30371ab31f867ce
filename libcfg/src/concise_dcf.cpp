#include "cfg/concise_dcf.hpp"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/download_order.hpp"
#include "cfg/hex.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "download_order_detail.hpp"

namespace cfg {
namespace {

// DSP 302 v3.2.1 §6.2: "Number of supported entries UNSIGNED32", then per entry "Index
// UNSIGNED16, Sub-index UNSIGNED8, Data size of parameter UNSIGNED32, Data of parameter
// DOMAIN". CANopen encodes every basic type little-endian (CiA 301 §7.1).
constexpr std::size_t kCountSize = 4;
constexpr std::size_t kHeaderSize = 2 + 1 + 4;

}  // namespace

std::vector<std::uint8_t> encode_concise_dcf(std::span<const ObjectWrite> entries) {
  if (entries.size() > std::numeric_limits<std::uint32_t>::max()) {
    throw std::length_error("concise DCF: more than 2^32-1 entries");
  }
  std::size_t total = kCountSize;
  for (const auto& e : entries) {
    // The size field is UNSIGNED32; a larger entry cannot be represented (programming error:
    // concise_writes_from_dcf rejects such DOMAIN files with a diagnostic).
    if (e.data.size() > std::numeric_limits<std::uint32_t>::max()) {
      throw std::length_error("concise DCF: entry " +
                              to_string(ObjectAddress{e.index, e.sub_index}) +
                              " larger than 4 GiB");
    }
    total += kHeaderSize + e.data.size();
  }
  // Sized once and filled in place: a DCF gives tens of thousands of entries.
  std::vector<std::uint8_t> out(total);
  std::uint8_t* p = out.data();
  store_le(entries.size(), {p, kCountSize}, kCountSize);
  p += kCountSize;
  for (const auto& e : entries) {
    store_le(e.index, {p, 2}, 2);
    p[2] = e.sub_index;
    store_le(e.data.size(), {p + 3, 4}, 4);
    p += kHeaderSize;
    if (!e.data.empty()) std::memcpy(p, e.data.data(), e.data.size());
    p += e.data.size();
  }
  return out;
}

ConciseDcfDecoder::ConciseDcfDecoder(EntryHandler on_entry) : on_entry_(std::move(on_entry)) {}

Status ConciseDcfDecoder::fail(std::string message) {
  stage_ = Stage::Failed;
  error_ = Error{std::move(message)};
  data_ = {};  // release the partial entry
  return error_;
}

void ConciseDcfDecoder::deliver() {
  if (on_entry_) on_entry_(index_, sub_index_, data_);
  ++entries_read_;
  data_.clear();
  entry_start_ = offset_;
  stage_ = entries_read_ == entries_announced_ ? Stage::Done : Stage::Header;
}

Status ConciseDcfDecoder::feed(std::span<const std::uint8_t> bytes) {
  std::size_t pos = 0;
  while (pos < bytes.size()) {
    const std::size_t available = bytes.size() - pos;
    switch (stage_) {
      case Stage::Failed:
        return error_;
      case Stage::Count:
      case Stage::Header: {
        const std::size_t need = stage_ == Stage::Count ? kCountSize : kHeaderSize;
        const std::size_t take = std::min(need - header_fill_, available);
        std::copy_n(bytes.begin() + static_cast<std::ptrdiff_t>(pos), take, header_ + header_fill_);
        header_fill_ += take;
        pos += take;
        offset_ += take;
        if (header_fill_ < need) break;
        header_fill_ = 0;
        if (stage_ == Stage::Count) {
          entries_announced_ = load_le32(header_);
          entry_start_ = offset_;
          // DSP 302 §6.2 application hint: a count of 0 is the valid empty data set.
          stage_ = entries_announced_ == 0 ? Stage::Done : Stage::Header;
          break;
        }
        index_ = load_le16(header_);
        sub_index_ = header_[2];
        size_ = load_le32(std::span(header_).subspan(3));
        stage_ = Stage::Data;
        // Data grows as bytes arrive: the announced size may be anything up to 4 GiB and is
        // not trusted until the bytes are there.
        if (size_ == 0) deliver();
        break;
      }
      case Stage::Data: {
        const std::size_t take =
            static_cast<std::size_t>(std::min<std::uint64_t>(size_ - data_.size(), available));
        auto first = bytes.begin() + static_cast<std::ptrdiff_t>(pos);
        data_.insert(data_.end(), first, first + static_cast<std::ptrdiff_t>(take));
        pos += take;
        offset_ += take;
        if (data_.size() == size_) deliver();
        break;
      }
      case Stage::Done:
        return fail("concise DCF has trailing bytes: byte offset " + std::to_string(offset_) +
                    " follows the last of the " + std::to_string(entries_announced_) +
                    " announced entries");
    }
  }
  return stage_ == Stage::Failed ? Status{error_} : Status{};
}

Status ConciseDcfDecoder::finish() {
  const std::string at = "the stream ends at byte offset " + std::to_string(offset_);
  const std::string which = "entry " + std::to_string(entries_read_ + 1) + " of " +
                            std::to_string(entries_announced_) + " (starts at byte offset " +
                            std::to_string(entry_start_) + ")";
  switch (stage_) {
    case Stage::Failed:
      return error_;
    case Stage::Done:
      return {};
    case Stage::Count:
      return fail("concise DCF truncated: " + at + ", inside the 4-byte entry count");
    case Stage::Header:
      if (header_fill_ == 0) {
        return fail("concise DCF truncated: " + std::to_string(entries_announced_) +
                    " entries announced, but " + at + " after " + std::to_string(entries_read_));
      }
      return fail("concise DCF truncated: " + at + ", inside the 7-byte header of " + which);
    case Stage::Data:
      return fail("concise DCF truncated: " + at + ", inside the data of " + which + ": " +
                  to_string(ObjectAddress{index_, sub_index_}) + " announces " +
                  std::to_string(size_) + " bytes, " + std::to_string(data_.size()) + " present");
  }
  return {};
}

Result<std::vector<ObjectWrite>> decode_concise_dcf(std::span<const std::uint8_t> bytes) {
  std::vector<ObjectWrite> entries;
  ConciseDcfDecoder decoder(
      [&entries](std::uint16_t index, std::uint8_t sub_index, std::span<const std::uint8_t> data) {
        entries.push_back({index, sub_index, {data.begin(), data.end()}});
      });
  if (auto status = decoder.feed(bytes); !status) return status.error();
  if (auto status = decoder.finish(); !status) return status.error();
  return entries;
}

// ---------------------------------------------------------------------------------------------
// DCF -> writes

namespace {

// CiA 306 §4.6.3 ObjFlags bit 0: "refuse write on download" - the value is not written when a
// configuration is downloaded (e.g. 1003h sub 0, whose write clears the error history).
constexpr std::uint32_t kObjFlagRefuseWriteOnDownload = 0x1;

// An empty value ("ParameterValue=") means "not configured": CANopenEditor writes the key
// empty for every entry the user did not set.
std::optional<std::string_view> value_text(const OptionalText& text) {
  if (!text) return std::nullopt;
  std::string_view v = *text;
  while (!v.empty() && (v.front() == ' ' || v.front() == '\t')) v.remove_prefix(1);
  while (!v.empty() && (v.back() == ' ' || v.back() == '\t' || v.back() == '\r')) {
    v.remove_suffix(1);
  }
  if (v.empty()) return std::nullopt;
  return v;
}

// "[1400sub1]" or "[1017]": the section that defines the entry, as a user finds it in the file.
std::string section_name(const Object& object, const SubObject& sub) {
  // Built by append: GCC 12 -O2 reports a false -Wrestrict on `"[" + std::string` (GCC bug
  // 105329).
  std::string name = "[";
  name += hex_digits(object.index, 4);
  if (!object.is_var()) {
    name += "sub";
    name += hex_digits(sub.sub_index);
  }
  name += ']';
  return name;
}

class WriteBuilder {
 public:
  WriteBuilder(const DeviceDescription& dcf, const ConciseOptions& options,
               Diagnostics& diagnostics)
      : dcf_(dcf), options_(options), diagnostics_(diagnostics) {
    node_id_ = options.node_id ? options.node_id : dcf.node_id();
  }

  std::optional<std::vector<ObjectWrite>> build();

 private:
  struct Location {
    const Object* object;
    const SubObject* sub;
  };

  void error(const Location& at, std::string message) {
    report(at, Severity::Error, std::move(message));
  }
  // `key_line`: the line of the key the message is about, when the model knows it.
  void report(const Location& at, Severity severity, std::string message, int key_line = 0) {
    const int line = key_line != 0 ? key_line : at.sub->line != 0 ? at.sub->line : at.object->line;
    diagnostics_.add(options_.file_name, line, severity,
                     section_name(*at.object, *at.sub) + " " + std::move(message));
    if (severity == Severity::Error) failed_ = true;
  }

  std::optional<Value> parse(const Location& at, std::string_view key, std::string_view text,
                             Severity severity = Severity::Error);
  std::optional<std::vector<std::uint8_t>> read_domain_file(const Location& at);
  void add_entry(const Location& at);
  void complete_pdo_mappings();
  std::optional<std::uint32_t> dcf_cob_id(std::uint16_t comm_index);

  const DeviceDescription& dcf_;
  const ConciseOptions& options_;
  Diagnostics& diagnostics_;
  std::optional<std::uint8_t> node_id_;
  std::vector<ObjectWrite> writes_;
  bool failed_ = false;
};

std::optional<Value> WriteBuilder::parse(const Location& at, std::string_view key,
                                         std::string_view text, Severity severity) {
  // Messages about the value name the line of its own key, not its section's: that is the line
  // a person has to change.
  const int key_line = key == "ParameterValue" ? at.sub->parameter_value_line
                       : key == "DefaultValue" ? at.sub->default_value_line
                                               : 0;
  auto type = at.sub->basic_type();
  if (!type) {
    report(at, severity,
           std::string(key) + " '" + std::string(text) + "': DataType " +
               hex(at.sub->data_type, 4) +
               " is not a basic CiA 301 type, so the value cannot be encoded",
           key_line);
    return std::nullopt;
  }
  if (mentions_node_id(text) && !node_id_) {
    report(at, severity,
           std::string(key) + " '" + std::string(text) +
               "' uses $NODEID, but no node-ID is known ([DeviceComissioning] has no NodeID)" +
               (options_.node_id_hint.empty() ? std::string() : "; " + options_.node_id_hint),
           key_line);
    return std::nullopt;
  }
  auto value = parse_value(*type, text, node_id_);
  if (!value) {
    report(at, severity,
           std::string(key) + " '" + std::string(text) + "' is not a valid " +
               std::string(to_string(*type)) + ": " + value.error().message,
           key_line);
    return std::nullopt;
  }
  return std::move(value).value();
}

std::optional<std::vector<std::uint8_t>> WriteBuilder::read_domain_file(const Location& at) {
  namespace fs = std::filesystem;
  const fs::path path = fs::path(options_.base_dir) / fs::path(*at.sub->download_file);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error(at, "DownloadFile '" + *at.sub->download_file + "': cannot open '" + path.string() + "'");
    return std::nullopt;
  }
  std::vector<std::uint8_t> data{std::istreambuf_iterator<char>(in),
                                 std::istreambuf_iterator<char>()};
  if (in.bad()) {
    error(at, "DownloadFile '" + path.string() + "': read error");
    return std::nullopt;
  }
  if (data.size() > std::numeric_limits<std::uint32_t>::max()) {
    error(at, "DownloadFile '" + path.string() +
                  "' is larger than a concise DCF entry can hold (4 GiB - 1)");
    return std::nullopt;
  }
  return data;
}

void WriteBuilder::add_entry(const Location& at) {
  const SubObject& sub = *at.sub;
  const auto parameter = value_text(sub.parameter_value);
  const auto default_value = value_text(sub.default_value);

  const std::uint32_t flags = sub.obj_flags.value_or(at.object->obj_flags.value_or(0));
  if ((flags & kObjFlagRefuseWriteOnDownload) != 0) {
    if (parameter) {
      report(at, Severity::Note,
             "ParameterValue not written: ObjFlags bit 0 says refuse write on download",
             sub.parameter_value_line);
    }
    return;
  }

  // CiA 306: a DOMAIN's configured content is the file DownloadFile names.
  if (sub.basic_type() == DataType::Domain && value_text(sub.download_file)) {
    if (auto data = read_domain_file(at)) {
      writes_.push_back({at.object->index, sub.sub_index, std::move(*data)});
    }
    return;
  }

  std::optional<Value> value;
  switch (options_.selection) {
    case ConciseSelection::Configured:
      if (!parameter) return;
      value = parse(at, "ParameterValue", *parameter);
      break;
    case ConciseSelection::WithDefaults:
      if (parameter) {
        value = parse(at, "ParameterValue", *parameter);
      } else if (default_value) {
        value = parse(at, "DefaultValue", *default_value);
      } else {
        return;
      }
      break;
    case ConciseSelection::ChangedOnly: {
      if (!parameter) return;
      value = parse(at, "ParameterValue", *parameter);
      if (!value || !default_value) break;
      // Compare values, not text: "0x0A" and "10" are the same UNSIGNED8.
      auto reference = parse(at, "DefaultValue", *default_value, Severity::Warning);
      if (reference && *reference == *value) return;
      break;
    }
  }
  if (value) writes_.push_back({at.object->index, sub.sub_index, encode(*value)});
}

std::optional<std::uint32_t> WriteBuilder::dcf_cob_id(std::uint16_t comm_index) {
  const Object* object = dcf_.object(comm_index);
  if (comm_index == object::kCobIdEmcy) {
    // The EMCY COB-ID the device has before the stream: its DefaultValue (CiA 301 §7.3.5).
    const SubObject* sub = object != nullptr ? object->sub(0) : nullptr;
    if (sub == nullptr || !sub->default_value || !sub->basic_type()) return std::nullopt;
    auto value = parse_value(*sub->basic_type(), *sub->default_value, node_id_);
    if (!value || data_type_info(value->type()).type_class != TypeClass::Unsigned) {
      return std::nullopt;
    }
    return static_cast<std::uint32_t>(value->as_unsigned());
  }
  const SubObject* sub = object != nullptr ? object->sub(1) : nullptr;
  // DSP 302 §6.2 step 1 applies "if it is not readonly".
  if (sub == nullptr || !is_writable(sub->access)) return std::nullopt;
  auto text = value_text(sub->configured_value());
  if (!text) return std::nullopt;
  auto value =
      parse({object, sub}, sub->parameter_value ? "ParameterValue" : "DefaultValue", *text);
  if (!value) return std::nullopt;
  if (data_type_info(value->type()).type_class != TypeClass::Unsigned ||
      data_type_info(value->type()).size_bytes != 4) {
    report({object, sub}, Severity::Warning,
           "PDO COB-ID has DataType " + std::string(to_string(value->type())) +
               ", expected UNSIGNED32 (CiA 301)");
    return std::nullopt;
  }
  return static_cast<std::uint32_t>(value->as_unsigned());
}

// A mapping entry cannot be written while sub-index 0 is not 0 (CiA 301 §7.5.2.36), and after
// the entries sub-index 0 must be set again: when entries are written without sub-index 0
// (ChangedOnly, or a DCF that configures entries only), add sub-index 0 with the DCF's value.
void WriteBuilder::complete_pdo_mappings() {
  std::map<std::uint16_t, bool> mappings;  // mapping index -> has sub 0
  for (const auto& w : writes_) {
    auto pdo = pdo_indices_of(w.index);
    if (!pdo || w.index != pdo->mapping_index) continue;
    mappings[w.index] = mappings[w.index] || w.sub_index == 0;
  }
  for (const auto& [index, has_count] : mappings) {
    if (has_count) continue;
    const Object* object = dcf_.object(index);
    const SubObject* sub = object != nullptr ? object->sub(0) : nullptr;
    if (sub == nullptr || !is_writable(sub->access)) continue;
    auto text = value_text(sub->configured_value());
    if (!text) continue;
    if (auto value =
            parse({object, sub}, sub->parameter_value ? "ParameterValue" : "DefaultValue", *text)) {
      writes_.push_back({index, 0, encode(*value)});
    }
  }
}

std::optional<std::vector<ObjectWrite>> WriteBuilder::build() {
  if (node_id_ && !is_node_id(*node_id_)) {
    diagnostics_.add(
        options_.file_name, 0, Severity::Error,
        "node-ID " + std::to_string(*node_id_) + " is out of range: CANopen node-IDs are 1..127");
    return std::nullopt;
  }
  // At most one write per sub-object: one allocation instead of a doubling series.
  std::size_t entries = 0;
  for (const auto& [index, object] : dcf_.objects) entries += object.subs.size();
  writes_.reserve(entries);
  for (const auto& [index, object] : dcf_.objects) {
    // 0001h-0FFFh define data types, they are not parameters (CiA 301 §7.4.1); 1010h/1011h
    // are store/restore commands, not configuration values.
    if (index < 0x1000 || index == 0x1010 || index == 0x1011) continue;
    for (const auto& [sub_index, sub] : object.subs) {
      if (!is_writable(sub.access)) continue;
      add_entry({&object, &sub});
    }
  }
  if (failed_) return std::nullopt;
  complete_pdo_mappings();
  if (failed_) return std::nullopt;

  auto order = detail::order_for_download_moving(
      std::move(writes_), [this](std::uint16_t comm_index) { return dcf_cob_id(comm_index); });
  if (failed_) return std::nullopt;

  // Say where the PDO rule could not be applied in full (unless the DCF makes it
  // unnecessary: a read-only COB-ID or mapping count cannot be written anyway).
  for (std::uint16_t comm_index : order.unknown_cob_id) {
    const Object* object = dcf_.object(comm_index);
    const SubObject* sub = object != nullptr ? object->sub(1) : nullptr;
    if (sub != nullptr && !is_writable(sub->access)) continue;
    diagnostics_.add(options_.file_name, object != nullptr ? object->line : 0, Severity::Warning,
                     "PDO " + object_name(comm_index) +
                         ": parameters are written but its COB-ID (sub-index 1) has no value "
                         "in the DCF, so the PDO is not disabled around them (DSP 302 §6.2)");
  }
  for (std::uint16_t mapping_index : order.unknown_mapping_count) {
    const Object* object = dcf_.object(mapping_index);
    const SubObject* sub = object != nullptr ? object->sub(0) : nullptr;
    if (sub != nullptr && !is_writable(sub->access)) continue;
    diagnostics_.add(options_.file_name, object != nullptr ? object->line : 0, Severity::Warning,
                     "PDO mapping " + object_name(mapping_index) +
                         ": entries are written but sub-index 0 has no value in the DCF, so "
                         "the mapping is not deactivated around them (DSP 302 §6.2)");
  }
  return std::move(order.writes);
}

}  // namespace

std::optional<std::vector<ObjectWrite>> concise_writes_from_dcf(const DeviceDescription& dcf,
                                                                const ConciseOptions& options,
                                                                Diagnostics& diagnostics) {
  return WriteBuilder(dcf, options, diagnostics).build();
}

}  // namespace cfg
