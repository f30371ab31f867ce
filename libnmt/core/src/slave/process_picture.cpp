// Object 1F70h "Process picture" (CiA DSP 302 §8.3); the behaviour is documented in
// process_picture.hpp, the layout rules of §8.2 in cfg/dynamic_channels.hpp.
#include "slave/process_picture.hpp"

#include <algorithm>
#include <memory>
#include <optional>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/dynamic_channels.hpp"
#include "cfg/object_index.hpp"

namespace nmt::detail {
namespace {

constexpr std::uint16_t kPicture = cfg::object::kDynamicChannelsProcessPicture;
constexpr std::uint8_t kSelectedRange = 1;
constexpr std::uint8_t kDomain = 2;

// Where one variable lies in the process picture.
struct VariableBits {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint64_t bit = 0;    // offset in the picture
  std::uint32_t width = 0;  // bits it covers
};

// What 1F70h serves, shared by its hooks.
class ProcessPicture {
 public:
  ProcessPicture(LocalDictionary& dict, cfg::DynamicChannels channels)
      : dict_(dict), channels_(std::move(channels)) {}

  // Sub 1: an index of some usable segment, or 0.
  SdoAbort check_selection(std::span<const std::uint8_t> data) const {
    if (data.size() != 4) return SdoAbort::None;  // the dictionary's size check answers
    const auto word = cfg::load_le32(data);
    const auto index = static_cast<std::uint16_t>(word >> 16);
    if (index == 0 || segment_of(index)) return SdoAbort::None;
    return SdoAbort::ValueRangeExceeded;
  }

  // Sub 2 read: the selected part of the picture into the entry.
  SdoAbort refresh() {
    const auto window = selected();
    if (!window) return SdoAbort::NoDataAvailable;
    std::vector<std::uint8_t> bytes(window->size, 0);
    for_each_variable(*window, false, [&](const VariableBits& v) {
      const auto value = dict_.get_bytes(v.index, v.sub);
      if (!value) return;
      std::uint64_t bits = 0;
      for (std::size_t i = 0; i < value->size() && i < 8; ++i) {
        bits |= std::uint64_t{(*value)[i]} << (8 * i);
      }
      for (std::uint32_t i = 0; i < v.width; ++i) {
        const std::uint64_t at = v.bit - window->first_bit + i;
        if (at >= bytes.size() * 8) break;  // the part of a variable cut by the length
        const auto mask = static_cast<std::uint8_t>(1U << (at % 8));
        if ((bits >> i & 1U) != 0) {
          bytes[at / 8] |= mask;
        } else {
          bytes[at / 8] &= static_cast<std::uint8_t>(~mask);
        }
      }
    });
    dict_.set_bytes(kPicture, kDomain, bytes);
    return SdoAbort::None;
  }

  // Sub 2 write: every variable wholly inside the bytes written takes its bits from them.
  SdoAbort store(std::span<const std::uint8_t> data) {
    auto window = selected();
    if (!window) return SdoAbort::NoDataAvailable;
    if (data.size() > window->size) return SdoAbort::LengthTooHigh;
    window->size = data.size();
    for_each_variable(*window, true, [&](const VariableBits& v) {
      const DictionaryEntry* e = dict_.entry(v.index, v.sub);
      if (e == nullptr) return;
      std::uint64_t bits = 0;
      for (std::uint32_t i = 0; i < v.width; ++i) {
        const std::uint64_t at = v.bit - window->first_bit + i;
        bits |= std::uint64_t{(data[at / 8] >> (at % 8)) & 1U} << i;
      }
      // A BOOLEAN in a byte cell is true when the cell is not 0.
      if (e->basic_type == cfg::DataType::Boolean) bits = bits != 0 ? 1 : 0;
      dict_.set_unsigned(v.index, v.sub, bits);
    });
    return SdoAbort::None;
  }

 private:
  struct Window {
    cfg::VariableDirection direction;
    std::uint64_t first_bit = 0;
    std::size_t size = 0;  // bytes
  };

  std::optional<std::size_t> segment_of(std::uint16_t index) const {
    for (std::size_t i = 0; i < channels_.segments.size(); ++i) {
      const cfg::DynamicSegment& s = channels_.segments[i];
      if (cfg::is_usable(s) && index >= s.first_index && index <= s.last_index) return i;
    }
    return std::nullopt;
  }

  // The bytes sub 1 selects, nullopt when it selects nothing.
  std::optional<Window> selected() const {
    const std::uint64_t word = dict_.get_unsigned(kPicture, kSelectedRange).value_or(0);
    const auto index = static_cast<std::uint16_t>(word >> 16);
    const auto length = static_cast<std::size_t>(word & 0xFFFF);
    const auto segment = index == 0 ? std::nullopt : segment_of(index);
    if (!segment) return std::nullopt;
    const cfg::DynamicSegment& s = channels_.segments[*segment];
    const DictionaryEntry* domain = dict_.entry(kPicture, kDomain);
    std::uint64_t size = cfg::segment_size_bytes(s);
    if (length != 0) size = std::min<std::uint64_t>(size, length);  // §8.3: "maximum amount"
    if (domain != nullptr) size = std::min<std::uint64_t>(size, domain->max_size);
    return Window{cfg::direction_of(s), std::uint64_t{s.pp_offset} * 8,
                  static_cast<std::size_t>(size)};
  }

  // Every variable of the window's picture present in the dictionary that starts in it (and,
  // when `whole`, ends in it too).
  template <class F>
  void for_each_variable(const Window& w, bool whole, F&& f) const {
    const std::uint64_t end_bit = w.first_bit + std::uint64_t{w.size} * 8;
    for (const cfg::DynamicSegment& s : channels_.segments) {
      if (!cfg::is_usable(s) || cfg::direction_of(s) != w.direction) continue;
      const auto& entries = dict_.entries();
      auto it = entries.lower_bound(LocalDictionary::key(s.first_index, 1));
      const auto last = entries.upper_bound(LocalDictionary::key(s.last_index, 0xFF));
      for (; it != last; ++it) {
        const DictionaryEntry& e = it->second;
        const auto p = cfg::segment_position(s, {e.index, e.sub_index});
        if (!p) continue;
        const std::uint64_t bit = cfg::process_picture_bit_offset(s, *p);
        const std::uint32_t width = cfg::width_bits(s);
        if (bit < w.first_bit || bit >= end_bit || (whole && bit + width > end_bit)) continue;
        f(VariableBits{e.index, e.sub_index, bit, width});
      }
    }
  }

  LocalDictionary& dict_;
  cfg::DynamicChannels channels_;
};

}  // namespace

void install_process_picture(LocalDictionary& dict, const cfg::DeviceDescription& device) {
  std::optional<cfg::DynamicChannels> channels = cfg::dynamic_channels_of(device);
  if (!channels || dict.entry(kPicture, kSelectedRange) == nullptr ||
      dict.entry(kPicture, kDomain) == nullptr) {
    return;
  }
  auto picture = std::make_shared<ProcessPicture>(dict, std::move(*channels));
  dict.add_write_hook([picture](std::uint16_t index, std::uint8_t sub,
                                std::span<const std::uint8_t> data, TimePoint) {
    if (index != kPicture) return SdoAbort::None;
    if (sub == kSelectedRange) return picture->check_selection(data);
    if (sub == kDomain) return picture->store(data);
    return SdoAbort::None;
  });
  dict.add_read_hook([picture](std::uint16_t index, std::uint8_t sub, TimePoint) {
    if (index != kPicture || sub != kDomain) return SdoAbort::None;
    return picture->refresh();
  });
}

}  // namespace nmt::detail
