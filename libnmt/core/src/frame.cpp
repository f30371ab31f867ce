#include "nmt/frame.hpp"

#include <algorithm>
#include <cstdio>

namespace nmt {

CanFrame CanFrame::make(std::uint32_t id, std::span<const std::uint8_t> bytes, bool extended) {
  CanFrame f;
  f.id = id;
  f.extended = extended;
  f.dlc = static_cast<std::uint8_t>(std::min<std::size_t>(bytes.size(), 8));
  std::copy_n(bytes.begin(), f.dlc, f.data.begin());
  return f;
}

bool CanFrame::operator==(const CanFrame& other) const {
  return id == other.id && extended == other.extended && rtr == other.rtr && error == other.error &&
         dlc == other.dlc && std::equal(data.begin(), data.begin() + dlc, other.data.begin());
}

std::string to_candump(const CanFrame& frame) {
  // candump uses 3 hex digits for standard ids and 8 for extended (and error) ids.
  char buf[32];
  if (frame.error) {
    std::snprintf(buf, sizeof buf, "%08X#", frame.id | 0x20000000u);
  } else if (frame.extended) {
    std::snprintf(buf, sizeof buf, "%08X#", frame.id);
  } else {
    std::snprintf(buf, sizeof buf, "%03X#", frame.id);
  }
  std::string out = buf;
  if (frame.rtr) {
    out += 'R';
    if (frame.dlc != 0) out += static_cast<char>('0' + frame.dlc);
    return out;
  }
  static constexpr char kHex[] = "0123456789ABCDEF";
  for (std::uint8_t i = 0; i < frame.dlc; ++i) {
    out += kHex[frame.data[i] >> 4];
    out += kHex[frame.data[i] & 0xF];
  }
  return out;
}

namespace {
int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}
}  // namespace

std::optional<CanFrame> from_candump(std::string_view text) {
  auto hash = text.find('#');
  if (hash == std::string_view::npos || hash == 0 || hash > 8) return std::nullopt;
  CanFrame f;
  std::uint32_t id = 0;
  for (char c : text.substr(0, hash)) {
    int d = hex_digit(c);
    if (d < 0) return std::nullopt;
    id = (id << 4) | static_cast<std::uint32_t>(d);
  }
  f.extended = hash == 8;
  if (f.extended && (id & 0x20000000u) != 0) {
    f.error = true;
    id &= ~0x20000000u;
  }
  if (id > (f.extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId)) return std::nullopt;
  f.id = id;
  auto rest = text.substr(hash + 1);
  if (!rest.empty() && (rest[0] == 'R' || rest[0] == 'r')) {
    f.rtr = true;
    if (rest.size() == 2 && rest[1] >= '0' && rest[1] <= '8') {
      f.dlc = static_cast<std::uint8_t>(rest[1] - '0');
    } else if (rest.size() != 1) {
      return std::nullopt;
    }
    return f;
  }
  if (rest.size() % 2 != 0 || rest.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < rest.size(); i += 2) {
    int hi = hex_digit(rest[i]);
    int lo = hex_digit(rest[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    f.data[i / 2] = static_cast<std::uint8_t>(hi << 4 | lo);
  }
  f.dlc = static_cast<std::uint8_t>(rest.size() / 2);
  return f;
}

}  // namespace nmt
