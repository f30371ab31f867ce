#include "nmt/sim/device_state.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
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

/// The program lines of a state file: number -> (size, CRC-32) of its image file.
using ProgramListing = std::map<std::uint8_t, std::pair<std::uint64_t, std::uint32_t>>;

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

// "7E57C0DE:00000305:00010002:00001001", as `cfgmgr lss` writes an LSS address.
// "node 5" / "the device with LSS address ...": whose a file is, in messages.
std::string owner_words(const DeviceStateOwner& owner) {
  if (owner.node) return "node " + std::to_string(owner.node->value());
  return "the device with LSS address " + address_digits(owner.lss, ':');
}

}  // namespace

std::string format_device_state(const DeviceStateOwner& owner, const DeviceState& state) {
  std::string text = "; what simulated " + owner_words(owner) +
                     " saved with 1010h (CiA 301 §7.5.2.13) and LSS store configuration "
                     "(CiA 305): its non-volatile memory\n";
  text += owner.node ? "node=" + std::to_string(owner.node->value())
                     : "lss=" + address_digits(owner.lss, ':');
  text += '\n';
  for (const auto& [key, bytes] : state.values) {
    text += cfg::hex_digits(key >> 8 & 0xFFFF, 4) + "sub" + cfg::hex_digits(key & 0xFF, 2) + "=";
    for (const std::uint8_t b : bytes) text += cfg::hex_digits(b, 2);
    text += '\n';
  }
  if (state.lss) {
    text += "lss_node=" + std::to_string(state.lss->node_id) +
            "\nlss_bit_timing=" + std::to_string(state.lss->bit_timing_index) + "\n";
  }
  for (const auto& [program, image] : state.programs) {
    text += "program" + cfg::hex_digits(program, 2) + "=" + std::to_string(image.size()) + "," +
            cfg::hex_digits(cfg::crc32(image), 8) + "\n";
  }
  return text + "end=" + std::to_string(state.values.size()) + "\n";
}

namespace {

cfg::Result<DeviceState> parse_state(std::string_view text, const std::string& file,
                                     const DeviceStateOwner& owner, ProgramListing& programs) {
  SavedValues values;
  std::optional<std::uint64_t> node_id;
  std::optional<std::string> lss_owner;
  std::optional<std::uint64_t> lss_node;
  std::optional<std::uint64_t> lss_bit_timing;
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
    if (name == "lss") {
      lss_owner = std::string(value);
      continue;
    }
    if (name.size() == 9 && name.substr(0, 7) == "program") {
      // programNN=SIZE,CRC32 (DSP 302 §9 program memory; the image is a file of its own)
      const auto program = cfg::parse_hex_number(name.substr(7, 2), 2);
      const auto comma = value.find(',');
      const auto size = comma == std::string_view::npos
                            ? cfg::IntegerLiteralResult{}
                            : cfg::parse_integer_literal(value.substr(0, comma));
      const auto crc = comma == std::string_view::npos
                           ? std::nullopt
                           : cfg::parse_hex_number(value.substr(comma + 1), 8);
      if (!program || *program == 0 || *program > 0xFE || !size.literal || !crc) {
        return parse_error(file, number,
                           "expected programNN=SIZE,CRC32 (NN 01..FE), e.g. program01=1024,"
                           "89ABCDEF");
      }
      if (!programs
               .emplace(static_cast<std::uint8_t>(*program),
                        std::pair{size.literal->value, static_cast<std::uint32_t>(*crc)})
               .second) {
        return parse_error(file, number, std::string(name) + " is given twice");
      }
      continue;
    }
    if (name == "node" || name == "end" || name == "lss_node" || name == "lss_bit_timing") {
      const auto parsed = cfg::parse_integer_literal(value);
      if (!parsed.literal) {
        return parse_error(file, number, "expected a number after " + std::string(name) + "=");
      }
      const std::uint64_t n = parsed.literal->value;
      if (name == "node") {
        node_id = n;
      } else if (name == "lss_node") {
        // CiA 305: 1..127, or FFh "not configured".
        if (n != lss::kUnconfigured && !cfg::is_node_id(n)) {
          return parse_error(
              file, number,
              "lss_node=" + std::string(value) + " is neither a node-ID 1..127 nor 255");
        }
        lss_node = n;
      } else if (name == "lss_bit_timing") {
        if (n > lss::kAutoBitRateIndex) {
          return parse_error(file, number,
                             "lss_bit_timing=" + std::string(value) +
                                 " is no index of the CiA 305 bit timing table (0..9)");
        }
        lss_bit_timing = n;
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
  const bool owned = owner.node ? node_id == owner.node->value() && !lss_owner
                                : !node_id && lss_owner == address_digits(owner.lss, ':');
  if (!owned) return parse_error(file, 1, "the file is not " + owner_words(owner) + "'s");
  if (lss_node.has_value() != lss_bit_timing.has_value()) {
    return parse_error(file, number,
                       "lss_node= and lss_bit_timing= come together: the file is damaged");
  }
  DeviceState state{std::move(values), std::nullopt, {}};
  if (lss_node) {
    state.lss = LssStoredConfig{static_cast<std::uint8_t>(*lss_node),
                                static_cast<std::uint8_t>(*lss_bit_timing)};
  }
  return state;
}

}  // namespace

cfg::Result<DeviceState> parse_device_state(std::string_view text, const std::string& file,
                                            const DeviceStateOwner& owner) {
  ProgramListing programs;
  return parse_state(text, file, owner, programs);
}

std::filesystem::path program_image_file(const std::filesystem::path& directory,
                                         const DeviceStateOwner& owner, std::uint8_t program) {
  auto file = device_state_file(directory, owner);
  file.replace_extension(".program" + cfg::hex_digits(program, 2) + ".bin");
  return file;
}

std::filesystem::path device_state_file(const std::filesystem::path& directory,
                                        const DeviceStateOwner& owner) {
  if (!owner.node) return directory / ("lss-" + address_digits(owner.lss, '-') + ".saved");
  return directory / ("node-" + cfg::hex_digits(owner.node->value(), 2) + ".saved");
}

cfg::Status save_device_state(const std::filesystem::path& directory, const DeviceStateOwner& owner,
                              const SlaveNode& node) {
  std::error_code ec;
  std::filesystem::create_directories(directory, ec);
  if (ec) {
    return cfg::Error{"cannot create '" + directory.string() + "': " + ec.message(),
                      cfg::ErrorCategory::Io};
  }
  // The images first: the text file lists only images that are complete on disk.
  for (const auto& [program, image] : node.program_images()) {
    if (auto written = cfg::write_file_atomically(
            directory.string(), program_image_file(directory, owner, program).filename(), image);
        !written) {
      return written;
    }
  }
  const std::string text =
      format_device_state(owner, {node.stored(), node.lss_stored(), node.program_images()});
  const auto* data = reinterpret_cast<const std::uint8_t*>(text.data());
  auto status =
      cfg::write_file_atomically(directory.string(), device_state_file(directory, owner).filename(),
                                 std::span(data, text.size()));
  if (!status) return status;
  // A cleared program's image is no longer listed; its file goes (a leftover would be ignored).
  for (unsigned program = 1; program <= 0xFE; ++program) {
    const auto n = static_cast<std::uint8_t>(program);
    if (node.program_images().count(n) != 0) continue;
    std::filesystem::remove(program_image_file(directory, owner, n), ec);
  }
  return status;
}

cfg::Result<std::optional<DeviceState>> load_device_state(const std::filesystem::path& directory,
                                                          const DeviceStateOwner& owner) {
  const std::filesystem::path file = device_state_file(directory, owner);
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    if (errno == ENOENT) return std::optional<DeviceState>();
    return cfg::Error{"cannot read '" + file.string() + "': " + std::strerror(errno),
                      cfg::ErrorCategory::Io};
  }
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  ProgramListing programs;
  auto state = parse_state(text, file.string(), owner, programs);
  if (!state) return state.error();
  for (const auto& [program, expected] : programs) {
    const auto image_file = program_image_file(directory, owner, program);
    std::ifstream image_in(image_file, std::ios::binary);
    if (!image_in) {
      return cfg::Error{file.string() + ": error: program " + std::to_string(program) +
                            " is listed, but '" + image_file.string() +
                            "' cannot be read: " + std::strerror(errno),
                        cfg::ErrorCategory::Input};
    }
    std::vector<std::uint8_t> image{std::istreambuf_iterator<char>(image_in),
                                    std::istreambuf_iterator<char>()};
    if (image.size() != expected.first || cfg::crc32(image) != expected.second) {
      return cfg::Error{file.string() + ": error: '" + image_file.string() + "' has " +
                            std::to_string(image.size()) + " bytes, CRC-32 " +
                            cfg::hex_digits(cfg::crc32(image), 8) + ", the file lists " +
                            std::to_string(expected.first) + " bytes, " +
                            cfg::hex_digits(expected.second, 8) + ": the image is damaged",
                        cfg::ErrorCategory::Input};
    }
    state.value().programs.emplace(program, std::move(image));
  }
  return std::optional<DeviceState>(std::move(state).value());
}

void restore_device_state(SlaveNode& node, DeviceState state) {
  node.set_stored(std::move(state.values));
  node.set_lss_stored(state.lss);
  node.set_program_images(std::move(state.programs));
}

bool changes_device_state(SlaveEvent::Kind kind) {
  return kind == SlaveEvent::Kind::Stored || kind == SlaveEvent::Kind::Restored ||
         kind == SlaveEvent::Kind::Lss || kind == SlaveEvent::Kind::Program;
}

}  // namespace nmt
