// dcf2concise --decode: a concise DCF as one line per entry, with names and typed values when a
// device file says what the entries are.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "cfg/bytes.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "dcf2concise.hpp"

namespace dcf2concise {
namespace {

// How much of a long value a line shows.
constexpr std::size_t kShownBytes = 16;

struct Row {
  std::string entry;  // "1017sub0"
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  std::size_t size = 0;
  std::string name;   // empty without a device file
  std::string type;   // "UNSIGNED16"; empty when unknown
  std::string words;  // "1000 (0x03E8)"
  std::string value;  // canonical DCF text (format_value); empty when not decoded
  std::string data;   // hex (first kShownBytes for text, all for JSON)
};

std::string hex_bytes(std::span<const std::uint8_t> data, std::size_t limit) {
  std::string out;
  for (std::size_t i = 0; i < data.size() && i < limit; ++i) {
    if (i != 0) out += ' ';
    out += cfg::hex_digits(data[i], 2);
  }
  if (data.size() > limit) out += " ...";
  return out;
}

// Without a device file: the bytes, and for 1 to 8 bytes their little-endian unsigned reading.
std::string raw_words(std::span<const std::uint8_t> data) {
  if (data.empty()) return "(empty)";
  if (data.size() > 8) {
    return hex_bytes(data, kShownBytes) + " (" + std::to_string(data.size()) + " bytes)";
  }
  const std::uint64_t v = cfg::load_le(data, data.size());
  return std::to_string(v) + " (" + cfg::hex(v, static_cast<int>(data.size() * 2)) + ")";
}

// COB-IDs and PDO mapping entries are bit fields (CiA 301 §7.5.2: bit 31 valid, bit 29 frame
// format, then the CAN-ID; a mapping entry is index << 16 | sub-index << 8 | length in bits), so
// their hex digits say what they are and their decimal value says nothing: shown as hex alone.
bool is_bit_field_entry(std::uint16_t index, std::uint8_t sub_index) {
  namespace o = cfg::object;
  if (index == o::kCobIdSync || index == o::kCobIdTime || index == o::kCobIdEmcy) {
    return sub_index == 0;
  }
  if (o::is_sdo_server_parameter(index) || o::is_sdo_client_parameter(index)) {
    return sub_index == 1 || sub_index == 2;  // COB-ID client -> server, server -> client
  }
  if (o::is_pdo_communication(index)) return sub_index == 1;
  if (o::is_pdo_mapping(index)) return sub_index >= 1;  // sub-index 0 is the entry count
  return false;
}

// "0x80000202": a 4-byte bit field entry (little-endian) as hex, all 8 digits.
std::optional<std::string> bit_field_words(std::uint16_t index, std::uint8_t sub_index,
                                           std::span<const std::uint8_t> data) {
  if (data.size() != 4 || !is_bit_field_entry(index, sub_index)) return std::nullopt;
  return cfg::hex(cfg::load_le32(data), 8);
}

class Describer {
 public:
  Describer(const cfg::DeviceDescription* device, std::string device_name, std::string input)
      : device_(device), device_name_(std::move(device_name)), input_(std::move(input)) {}

  Row describe(std::uint16_t index, std::uint8_t sub_index, std::span<const std::uint8_t> data,
               std::uint32_t entry_number, cfg::Diagnostics& diagnostics) const {
    Row row;
    row.entry = cfg::hex_digits(index, 4) + "sub" + cfg::hex_digits(sub_index);  // as DCF sections
    row.index = index;
    row.sub_index = sub_index;
    row.size = data.size();
    row.data = tools::hex_string(data);
    const auto bit_field = bit_field_words(index, sub_index, data);
    row.words = bit_field ? *bit_field : raw_words(data);
    if (device_ == nullptr) return row;

    auto warn = [&](const std::string& what) {
      diagnostics.add(input_, 0, cfg::Severity::Warning,
                      "entry " + std::to_string(entry_number) + " (" + row.entry + "): " + what);
    };
    const cfg::Object* object = device_->object(index);
    const cfg::SubObject* sub = object != nullptr ? object->sub(sub_index) : nullptr;
    if (sub == nullptr) {
      row.name = "(not in " + device_name_ + ")";
      warn("not in " + device_name_);
      return row;
    }
    row.name =
        object->is_var() || sub->name.empty() ? object->name : object->name + ": " + sub->name;
    auto type = sub->basic_type();
    if (!type) {
      warn("DataType " + cfg::hex(sub->data_type, 4) + " is not a basic type; shown as bytes");
      return row;
    }
    row.type = std::string(cfg::to_string(*type));
    auto value = cfg::decode(*type, data);
    if (!value) {
      warn(value.error().message);
      return row;
    }
    row.value = cfg::format_value(*value);
    const bool long_bytes = cfg::is_variable_size(*type) && data.size() > kShownBytes;
    const bool unsigned32 = *type == cfg::DataType::Unsigned32;
    row.words = long_bytes
                    ? hex_bytes(data, kShownBytes) + " (" + std::to_string(data.size()) + " bytes)"
                : bit_field && unsigned32 ? *bit_field
                                          : cfg::describe_value(*value);
    return row;
  }

 private:
  const cfg::DeviceDescription* device_;
  std::string device_name_;
  std::string input_;
};

void print_text(const std::vector<Row>& rows, bool with_names) {
  std::size_t name_width = 0;
  for (const auto& r : rows) name_width = std::max(name_width, r.name.size());
  for (const auto& r : rows) {
    std::string line = r.entry + "  ";
    if (with_names) {
      line += r.name + std::string(name_width - r.name.size(), ' ') + "  ";
    } else {
      // "  1 byte   = ..." keeps "=" in the column of "  2 bytes  = ...".
      line += std::string(r.size < 10    ? 2
                          : r.size < 100 ? 1
                                         : 0,
                          ' ') +
              tools::plural(r.size, "byte") + (r.size == 1 ? "   " : "  ");
    }
    line += "= " + r.words;
    std::cout << line << '\n';
  }
}

void print_json(const std::string& input, const std::vector<Row>& rows, bool ok,
                std::uint32_t announced, const cfg::Diagnostics& diagnostics) {
  std::string out = "{\"input\": " + tools::json_string(input) +
                    ", \"ok\": " + (ok ? "true" : "false") +
                    ", \"announced\": " + std::to_string(announced) + ", \"entries\": [";
  bool first = true;
  for (const auto& r : rows) {
    if (!first) out += ", ";
    first = false;
    out += "{\"index\": " + std::to_string(r.index) + ", \"index_hex\": \"" + r.entry.substr(0, 4) +
           "\", \"sub_index\": " + std::to_string(r.sub_index) +
           ", \"size\": " + std::to_string(r.size) + ", \"data\": \"" + r.data + "\"";
    if (!r.name.empty()) out += ", \"name\": " + tools::json_string(r.name);
    if (!r.type.empty()) out += ", \"type\": " + tools::json_string(r.type);
    if (!r.value.empty() || !r.type.empty()) out += ", \"value\": " + tools::json_string(r.value);
    out += "}";
  }
  out += "], \"diagnostics\": " + tools::json_diagnostics(diagnostics) + "}\n";
  std::cout << out;
}

}  // namespace

int run_decode(const DecodeOptions& options) {
  const std::string name = options.input == "-" ? "<stdin>" : options.input;
  cfg::Diagnostics diagnostics;

  std::optional<cfg::DeviceDescription> device;
  if (!options.device_file.empty()) {
    auto text = tools::read_input(options.device_file);
    if (!text) tools::exit_with(tools::exit_code_for(text.error()), text.error().message);
    cfg::ReadOptions read_options;
    read_options.mode = options.strict ? cfg::ReadMode::Strict : cfg::ReadMode::Tolerant;
    read_options.file_name = options.device_file;
    auto read = cfg::parse_device_description(*text, read_options);
    diagnostics.append(read.diagnostics);
    if (!read.ok()) {
      tools::print_diagnostics(diagnostics);
      return tools::kExitInputErrors;
    }
    device = std::move(read.device);
  }

  // The stream is opened once and read in chunks (read(2): a directory fails at the first
  // read with EISDIR, an I/O error like any other).
  int fd = STDIN_FILENO;
  struct Closer {
    int fd = -1;
    ~Closer() {
      if (fd >= 0) ::close(fd);
    }
  } closer;
  if (options.input != "-") {
    fd = ::open(options.input.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      tools::exit_with(
          tools::kExitIo,
          tools::io_error(name, std::string("cannot open: ") + std::strerror(errno)).message);
    }
    closer.fd = fd;
  }

  const Describer describer(device ? &*device : nullptr,
                            std::filesystem::path(options.device_file).filename().string(), name);
  std::vector<Row> rows;
  cfg::ConciseDcfDecoder decoder(
      [&](std::uint16_t index, std::uint8_t sub_index, std::span<const std::uint8_t> data) {
        rows.push_back(describer.describe(
            index, sub_index, data, static_cast<std::uint32_t>(rows.size() + 1), diagnostics));
      });
  // Streams of any size: fed in chunks, never held whole.
  std::vector<char> chunk(std::size_t{64} * 1024);
  cfg::Status status;
  while (status) {
    const ssize_t n = ::read(fd, chunk.data(), chunk.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      tools::exit_with(
          tools::kExitIo,
          tools::io_error(name, std::string("read error: ") + std::strerror(errno)).message);
    }
    if (n == 0) break;
    status = decoder.feed(
        {reinterpret_cast<const std::uint8_t*>(chunk.data()), static_cast<std::size_t>(n)});
  }
  if (status) status = decoder.finish();
  if (!status) diagnostics.add(name, 0, cfg::Severity::Error, status.error().message);
  if (options.strict) diagnostics = tools::promote_warnings(diagnostics);

  if (options.json) {
    print_json(name, rows, !diagnostics.has_errors(), decoder.entries_announced(), diagnostics);
  } else {
    print_text(rows, device.has_value());
  }
  tools::print_diagnostics(diagnostics);
  return diagnostics.has_errors() ? tools::kExitInputErrors : tools::kExitOk;
}

}  // namespace dcf2concise
