#include "nmt/protocol/frame.hpp"

#include <algorithm>
#include <type_traits>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"

namespace nmt {

// The mix-ups distinct TimePoint and Duration types exist to catch (engine.hpp rule 1):
// a Duration is no TimePoint, and two points in time do not add up.
template <class A, class B>
concept Addable = requires(A a, B b) {
  a + b;
};
static_assert(!std::is_convertible_v<Duration, TimePoint>);
static_assert(!Addable<TimePoint, TimePoint>);
static_assert(std::is_same_v<decltype(TimePoint{} - TimePoint{}), Duration>);
static_assert(std::is_same_v<decltype(TimePoint{} + Duration{}), TimePoint>);

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
  std::string out = frame.error      ? cfg::hex_digits(frame.id | CanFrame::kErrorFlag, 8)
                    : frame.extended ? cfg::hex_digits(frame.id, 8)
                                     : cfg::hex_digits(frame.id, 3);
  out += '#';
  if (frame.rtr) {
    out += 'R';
    if (frame.dlc != 0) out += static_cast<char>('0' + frame.dlc);
    return out;
  }
  for (std::uint8_t i = 0; i < frame.dlc; ++i) out += cfg::hex_digits(frame.data[i], 2);
  return out;
}

std::optional<CanFrame> from_candump(std::string_view text) {
  auto hash = text.find('#');
  if (hash == std::string_view::npos || hash == 0 || hash > 8) return std::nullopt;
  const auto parsed_id = cfg::parse_hex_number(text.substr(0, hash), 8);
  if (!parsed_id) return std::nullopt;
  auto id = static_cast<std::uint32_t>(*parsed_id);
  CanFrame f;
  f.extended = hash == 8;
  if (f.extended && (id & CanFrame::kErrorFlag) != 0) {
    f.error = true;
    id &= ~CanFrame::kErrorFlag;
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
    const auto byte = cfg::parse_hex_number(rest.substr(i, 2), 2);
    if (!byte) return std::nullopt;
    f.data[i / 2] = static_cast<std::uint8_t>(*byte);
  }
  f.dlc = static_cast<std::uint8_t>(rest.size() / 2);
  return f;
}

}  // namespace nmt
