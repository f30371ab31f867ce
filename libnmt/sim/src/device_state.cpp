#include "nmt/device_state.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

#include "cfg/atomic_file.hpp"
#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"

namespace nmt {
namespace {

cfg::Error parse_error(const std::string& file, std::size_t line, std::string what) {
  return cfg::Error{file + ":" + std::to_string(line) + ": error: " + std::move(what)};
}

// "E803" -> {E8h, 03h}; nullopt for an odd count or a non-hex digit.
std::optional<std::vector<std::uint8_t>> parse_bytes(std::string_view text) {
  if (text.size() % 2 != 0) return std::nullopt;
  std::vector<std::uint8_t> out;
  out.reserve(text.size() / 2);
  for (std::size_t i = 0; i < text.size(); i += 2) {
    const int high = cfg::hex_digit_value(text[i]);
    const int low = cfg::hex_digit_value(text[i + 1]);
    if (high < 0 || low < 0) return std::nullopt;
    out.push_back(static_cast<std::uint8_t>(high << 4 | low));
  }
  return out;
}

}  // namespace

std::string format_device_state(cfg::NodeId node, const SavedValues& values) {
  std::string text = "; values simulated node " + std::to_string(node.value()) +
                     " saved with 1010h (CiA 301 §7.5.2.13): its non-volatile memory\nnode=" +
                     std::to_string(node.value()) + "\n";
  for (const auto& [key, bytes] : values) {
    text += cfg::hex_digits(key >> 8 & 0xFFFF, 4) + "sub" + cfg::hex_digits(key & 0xFF, 2) + "=";
    for (const std::uint8_t b : bytes) text += cfg::hex_digits(b, 2);
    text += '\n';
  }
  return text + "end=" + std::to_string(values.size()) + "\n";
}

cfg::Result<SavedValues> parse_device_state(std::string_view text, const std::string& file,
                                            cfg::NodeId node) {
  SavedValues values;
  std::optional<std::uint64_t> node_id;
  bool ended = false;
  std::size_t number = 0;
  while (!text.empty()) {
    const std::size_t newline = text.find('\n');
    std::string_view line = text.substr(0, newline);
    text = newline == std::string_view::npos ? std::string_view() : text.substr(newline + 1);
    ++number;
    if (line.empty() || line.front() == ';') continue;
    if (ended) return parse_error(file, number, "text after end=");
    const auto eq = line.find('=');
    if (eq == std::string_view::npos) return parse_error(file, number, "expected NAME=VALUE");
    const std::string_view name = line.substr(0, eq);
    const std::string_view value = line.substr(eq + 1);
    if (name == "node" || name == "end") {
      const auto parsed = cfg::parse_integer_literal(value);
      if (!parsed.literal) {
        return parse_error(file, number, "expected a number after " + std::string(name) + "=");
      }
      if (name == "node") {
        node_id = parsed.literal->value;
      } else if (parsed.literal->value != values.size()) {
        return parse_error(file, number,
                           "end=" + std::string(value) + " but " + std::to_string(values.size()) +
                               " values: the file is damaged");
      } else {
        ended = true;
      }
      continue;
    }
    // IIIIsubSS=BYTES
    const auto index = name.size() == 9 && name.substr(4, 3) == "sub"
                           ? cfg::parse_hex_number(name.substr(0, 4), 4)
                           : std::nullopt;
    const auto sub = index ? cfg::parse_hex_number(name.substr(7, 2), 2) : std::nullopt;
    auto bytes = parse_bytes(value);
    if (!index || !sub || !bytes) {
      return parse_error(file, number, "expected IIIIsubSS=HEXBYTES, e.g. 1017sub00=E803");
    }
    const auto key = static_cast<std::uint32_t>(*index << 8 | *sub);
    if (!values.emplace(key, std::move(*bytes)).second) {
      return parse_error(file, number, std::string(name) + " is given twice");
    }
  }
  if (!ended) return parse_error(file, number, "no end= line: the file is cut short");
  if (node_id != node.value()) {
    return parse_error(file, 1, "the file is not node " + std::to_string(node.value()) + "'s");
  }
  return values;
}

std::filesystem::path device_state_file(const std::filesystem::path& directory, cfg::NodeId node) {
  return directory / ("node-" + cfg::hex_digits(node.value(), 2) + ".saved");
}

cfg::Status save_device_state(const std::filesystem::path& directory, const SlaveNode& node) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) {
    return cfg::Error{"cannot create '" + directory.string() + "': " + ec.message(),
                      cfg::ErrorCategory::Io};
  }
  const std::string text = format_device_state(node.node_id(), node.stored());
  const auto* data = reinterpret_cast<const std::uint8_t*>(text.data());
  return cfg::write_file_atomically(directory.string(),
                                    device_state_file(directory, node.node_id()).filename(),
                                    std::span(data, text.size()));
}

cfg::Result<std::optional<SavedValues>> load_device_state(const std::filesystem::path& directory,
                                                          cfg::NodeId node) {
  const std::filesystem::path file = device_state_file(directory, node);
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    if (errno == ENOENT) return std::optional<SavedValues>();
    return cfg::Error{"cannot read '" + file.string() + "': " + std::strerror(errno),
                      cfg::ErrorCategory::Io};
  }
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  auto values = parse_device_state(text, file.string(), node);
  if (!values) return values.error();
  return std::optional<SavedValues>(std::move(values).value());
}

}  // namespace nmt
