// [DynamicChannels] and [DeviceInfo] DynamicChannelsSupported (CiA DSP 302 §8.4): the reader
// keeps the section as written (a RawSection) and collects its keys, read and checked after the
// last line, when DeviceInfo is known; cfg::dynamic_channels_of reads the kept section the same
// way. What makes a segment unusable for dynamic index assignment (a missing or unreadable key,
// a range that is reversed, overlaps another or lies outside the manufacturer/profile areas, a
// type no process picture can hold) is an error in both modes; a segment the model cannot
// represent (a missing key, unreadable values) is left out of the segments.
#include <algorithm>
#include <array>
#include <limits>
#include <map>

#include "cfg/data_type.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "device_reader.hpp"
#include "dynamic_channels_read.hpp"

namespace cfg::detail {
namespace {

constexpr std::string_view kSection = "[DynamicChannels] ";

// The keys of one segment, in SegmentKey order (line 0: not given).
enum class SegmentKey : std::uint8_t { Type, Dir, Range, PPOffset, MaxCnt, MSpecific };
constexpr std::size_t kSegmentKeyCount = 6;
struct SegmentKeys {
  std::array<DynamicChannelsKey, kSegmentKeyCount> keys{};
  int first_line = 0;
};

// CiA DSP 302 §8.4 keywords counted with an entry index, in SegmentKey order.
constexpr std::array<std::string_view, kSegmentKeyCount> kSegmentKeyNames = {
    "Type", "Dir", "Range", "PPOffset", "MaxCnt", "MSpecific"};

// The entry index after a keyword: "a decimal unsigned32 value starting with 1" (§8.4).
std::optional<std::uint64_t> entry_index(std::string_view digits) {
  if (digits.empty() || digits.size() > 10 || digits[0] == '0') return std::nullopt;
  std::uint64_t n = 0;
  for (char c : digits) {
    if (c < '0' || c > '9') return std::nullopt;
    n = n * 10 + static_cast<std::uint64_t>(c - '0');
  }
  if (n > std::numeric_limits<std::uint32_t>::max()) return std::nullopt;
  return n;
}

std::string key_name(SegmentKey key, std::uint64_t entry) {
  return std::string(kSegmentKeyNames[static_cast<std::size_t>(key)]) + std::to_string(entry);
}

bool has_0x(std::string_view text) {
  return text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X');
}

// The segment's keys as the model holds them, and the lines the checks name.
struct ReadSegment {
  DynamicSegment segment;
  std::uint64_t entry = 0;
  int type_line = 0, range_line = 0, pp_line = 0, max_line = 0;
};

// The area of an index for dynamic channels: 0 manufacturer (2000h-5FFFh), 1 device profile
// (6000h-9FFFh), 2 network variables (A000h-AFFFh: CiA 301 v4.2's standardized network variable
// area, where CiA 405 devices allocate them), -1 none of these.
int area_of(std::uint16_t index) {
  if (index >= 0x2000 && index <= 0x5FFF) return 0;
  if (index >= 0x6000 && index <= 0x9FFF) return 1;
  if (index >= 0xA000 && index <= 0xAFFF) return 2;
  return -1;
}

std::string range_text(const DynamicSegment& s) {
  return object_name(s.first_index) + "-" + object_name(s.last_index);
}

}  // namespace

DynamicChannels read_dynamic_channels(std::span<const DynamicChannelsKey> raw_keys,
                                      int section_line, const DynamicChannelsReport& report) {
  auto error = [&](int line, std::string message) {
    if (report.error) report.error(line, std::move(message));
  };
  auto warn = [&](int line, std::string message) {
    if (report.warn) report.warn(line, std::move(message));
  };
  // The keys by entry index; numbers and words lose an inline comment (MSpecific is text).
  struct Count {
    std::string_view value;
    int line = 0;
  } count_key;
  std::map<std::uint64_t, SegmentKeys> entries;
  for (const DynamicChannelsKey& k : raw_keys) {
    std::string_view value = k.value;
    if (iequals(k.key, "NrOfSeg")) {
      const std::size_t c = find_inline_comment(value);
      if (c != std::string_view::npos) value = trim_blanks(value.substr(0, c));
      count_key = {value, k.line};
      continue;
    }
    bool known = false;
    for (std::size_t i = 0; i < kSegmentKeyCount && !known; ++i) {
      const std::string_view name = kSegmentKeyNames[i];
      if (!reader::istarts_with(k.key, name)) continue;
      known = true;
      const std::optional<std::uint64_t> n = entry_index(k.key.substr(name.size()));
      if (!n) {
        warn(k.line, std::string(kSection) + "key " + std::string(k.key) +
                         ": the entry index after " + std::string(name) +
                         " is a decimal number from 1 (CiA DSP 302 §8.4); ignored");
        break;
      }
      if (static_cast<SegmentKey>(i) != SegmentKey::MSpecific) {
        const std::size_t c = find_inline_comment(value);
        if (c != std::string_view::npos) value = trim_blanks(value.substr(0, c));
      }
      SegmentKeys& entry = entries[*n];
      entry.keys[i] = {k.key, value, k.line};
      if (entry.first_line == 0) entry.first_line = k.line;
    }
    if (!known) {
      warn(k.line, std::string(kSection) + "key " + std::string(k.key) +
                       " is not a [DynamicChannels] key (NrOfSeg, TypeN, DirN, RangeN, "
                       "PPOffsetN, MaxCntN, MSpecificN: CiA DSP 302 §8.4); ignored");
    }
  }

  DynamicChannels out;
  std::optional<std::uint64_t> count;
  if (count_key.line == 0) {
    error(section_line, "[DynamicChannels] has no NrOfSeg (CiA DSP 302 §8.4)");
  } else {
    const std::string_view text = trim_blanks(count_key.value);
    auto n = reader::parse_number(text);
    if (!n || n->h_suffix || n->value > std::numeric_limits<std::uint32_t>::max()) {
      error(count_key.line, std::string(kSection) + "NrOfSeg " + reader::shown(text) +
                                " is not a decimal or 0x number (CiA DSP 302 §8.4)");
    } else {
      count = n->value;
    }
  }

  std::vector<ReadSegment> segments;
  for (const auto& item : entries) {
    // Named, not a structured binding: clang 14 does not let lambdas capture those.
    const std::uint64_t entry = item.first;
    const SegmentKeys& keys = item.second;
    auto given = [&](SegmentKey k) -> const DynamicChannelsKey* {
      const DynamicChannelsKey& r = keys.keys[static_cast<std::size_t>(k)];
      return r.line == 0 ? nullptr : &r;
    };
    if (count && entry > *count) {
      error(keys.first_line, std::string(kSection) + "segment " + std::to_string(entry) +
                                 " is beyond NrOfSeg " + std::to_string(*count) + " (line " +
                                 std::to_string(count_key.line) + ")");
    }
    bool usable = true;
    for (SegmentKey k : {SegmentKey::Type, SegmentKey::Dir, SegmentKey::Range, SegmentKey::PPOffset,
                         SegmentKey::MaxCnt}) {
      if (given(k) == nullptr) {
        error(keys.first_line, std::string(kSection) + "segment " + std::to_string(entry) +
                                   " has no " + key_name(k, entry) +
                                   " (CiA DSP 302 §8.4); the segment is left out");
        usable = false;
      }
    }
    if (!usable) continue;
    ReadSegment r;
    r.entry = entry;
    DynamicSegment& s = r.segment;
    auto bad = [&](const DynamicChannelsKey& k, const std::string& why) {
      error(k.line, std::string(kSection) + std::string(k.key) + " " +
                        reader::shown(trim_blanks(k.value)) + " " + why +
                        " (CiA DSP 302 §8.4); the segment is left out");
      usable = false;
    };
    auto unsigned_number = [&](const DynamicChannelsKey& k, std::string_view text,
                               std::uint64_t max) -> std::optional<std::uint64_t> {
      auto n = reader::parse_number(trim_blanks(text));
      if (!n || n->h_suffix || n->value > max) {
        bad(k, "is not an unsigned number (decimal or 0x hex) up to " + std::to_string(max));
        return std::nullopt;
      }
      return n->value;
    };

    const DynamicChannelsKey& type = *given(SegmentKey::Type);
    r.type_line = type.line;
    if (auto n = unsigned_number(type, type.value, 0xFFFF)) {
      s.data_type = static_cast<std::uint16_t>(*n);
    }

    const DynamicChannelsKey& dir = *given(SegmentKey::Dir);
    const std::string_view dir_text = trim_blanks(dir.value);
    if (auto d = segment_direction_from_string(dir_text)) {
      s.direction = *d;
      if (dir_text != to_string(*d)) {
        warn(dir.line, std::string(kSection) + std::string(dir.key) + " " +
                           reader::shown(dir_text) + ": CiA DSP 302 §8.4 writes it in lower case");
      }
    } else {
      bad(dir, "is not ro, wo or rww");
    }

    // §8.4: "pair of numbers ... unsigned16 hexadecimal with leading 0x", "0x7001-0x7017".
    const DynamicChannelsKey& range = *given(SegmentKey::Range);
    r.range_line = range.line;
    const std::string_view range_value = trim_blanks(range.value);
    const std::size_t dash = range_value.find('-');
    if (dash == std::string_view::npos) {
      bad(range, "is not a range start-end, like 0x7001-0x7017");
    } else {
      const std::string_view first = trim_blanks(range_value.substr(0, dash));
      const std::string_view last = trim_blanks(range_value.substr(dash + 1));
      if (!has_0x(first) || !has_0x(last)) {
        bad(range, "has a number without the leading 0x of hexadecimal");
      } else {
        auto a = unsigned_number(range, first, 0xFFFF);
        auto b = a ? unsigned_number(range, last, 0xFFFF) : std::nullopt;
        if (a && b) {
          s.first_index = static_cast<std::uint16_t>(*a);
          s.last_index = static_cast<std::uint16_t>(*b);
        }
      }
    }

    // §8.4: the offset, and for BOOLEAN segments ",bit distance".
    const DynamicChannelsKey& pp = *given(SegmentKey::PPOffset);
    r.pp_line = pp.line;
    const std::string_view pp_value = trim_blanks(pp.value);
    const std::size_t comma = pp_value.find(',');
    if (auto n = unsigned_number(pp, pp_value.substr(0, comma), 0xFFFFFFFF)) {
      s.pp_offset = static_cast<std::uint32_t>(*n);
    }
    if (comma != std::string_view::npos) {
      if (auto n = unsigned_number(pp, pp_value.substr(comma + 1), 0xFFFFFFFF)) {
        s.bit_distance = static_cast<std::uint32_t>(*n);
      }
    }

    const DynamicChannelsKey& max = *given(SegmentKey::MaxCnt);
    r.max_line = max.line;
    if (auto n = unsigned_number(max, max.value, 0xFFFFFFFF)) {
      s.max_count = static_cast<std::uint32_t>(*n);
    }
    if (const DynamicChannelsKey* m = given(SegmentKey::MSpecific)) s.m_specific.emplace(m->value);
    if (usable) segments.push_back(std::move(r));
  }
  if (count && *count != entries.size()) {
    error(count_key.line, std::string(kSection) + "NrOfSeg is " + std::to_string(*count) + " but " +
                              std::to_string(entries.size()) +
                              (entries.size() == 1 ? " segment is" : " segments are") +
                              " described (CiA DSP 302 §8.4: entries 1..NrOfSeg)");
  }

  for (ReadSegment& r : segments) {
    DynamicSegment& s = r.segment;
    const std::string seg = std::string(kSection) + "segment " + std::to_string(r.entry) + ": ";
    const DataTypeInfo* info = find_data_type(s.data_type);
    if (info == nullptr) {
      error(r.type_line, seg + "Type " + hex(s.data_type, 4) +
                             " is not a basic data type of CiA 301 (DataType coding)");
    } else if (info->size_bytes == 0) {
      error(r.type_line, seg + "Type " + std::string(info->name) +
                             " has no fixed size: a process picture cannot hold it");
    }
    const bool boolean = s.data_type == static_cast<std::uint16_t>(DataType::Boolean);
    if (s.bit_distance && !boolean) {
      error(r.pp_line, seg + "PPOffset gives a bit distance, which only BOOLEAN segments have");
      s.bit_distance.reset();
    } else if (boolean && !s.bit_distance) {
      error(r.pp_line, seg +
                           "a BOOLEAN segment's PPOffset needs the bit distance, "
                           "\"offset,distance\" (CiA DSP 302 §8.4)");
    } else if (boolean && *s.bit_distance == 0) {
      error(r.pp_line, seg + "bit distance 0 would put every BOOLEAN variable at one bit");
    }
    if (s.first_index > s.last_index) {
      error(r.range_line, seg + "range starts at " + object_name(s.first_index) +
                              ", after its end " + object_name(s.last_index));
    } else if (area_of(s.first_index) < 0 || area_of(s.last_index) < 0) {
      error(r.range_line, seg + "range " + range_text(s) +
                              " is outside the manufacturer (2000h-5FFFh), profile "
                              "(6000h-9FFFh) and network variable (A000h-AFFFh) areas");
    } else if (area_of(s.first_index) != area_of(s.last_index)) {
      error(r.range_line, seg + "range " + range_text(s) +
                              " spans two areas (2000h-5FFFh manufacturer, 6000h-9FFFh "
                              "profile, A000h-AFFFh network variables)");
    } else {
      // §8.2: arrays of sub-index 01h..FEh, so a range holds 254 variables per index.
      const std::uint64_t capacity =
          (static_cast<std::uint64_t>(s.last_index) - s.first_index + 1) * 254;
      if (s.max_count > capacity) {
        warn(r.max_line, seg + "MaxCnt " + std::to_string(s.max_count) + " but range " +
                             range_text(s) + " holds at most " + std::to_string(capacity) +
                             " variables (254 per index)");
      }
    }
  }

  // §8.2: "These segments must not overlap." Sorted by start, each range is checked against the
  // one reaching furthest before it.
  std::vector<const ReadSegment*> by_start;
  for (const ReadSegment& r : segments) {
    if (r.segment.first_index <= r.segment.last_index) by_start.push_back(&r);
  }
  std::stable_sort(by_start.begin(), by_start.end(), [](const auto* a, const auto* b) {
    return a->segment.first_index < b->segment.first_index;
  });
  const ReadSegment* furthest = nullptr;
  for (const ReadSegment* r : by_start) {
    if (furthest != nullptr && r->segment.first_index <= furthest->segment.last_index) {
      const ReadSegment& later = r->entry > furthest->entry ? *r : *furthest;
      const ReadSegment& earlier = r->entry > furthest->entry ? *furthest : *r;
      error(later.range_line, std::string(kSection) + "segment " + std::to_string(later.entry) +
                                  ": range " + range_text(later.segment) + " overlaps segment " +
                                  std::to_string(earlier.entry) + " (" +
                                  range_text(earlier.segment) + ", line " +
                                  std::to_string(earlier.range_line) +
                                  "); segments must not overlap (CiA DSP 302 §8.2)");
    }
    if (furthest == nullptr || r->segment.last_index > furthest->segment.last_index) furthest = r;
  }
  for (ReadSegment& r : segments) out.segments.push_back(std::move(r.segment));
  return out;
}

namespace reader {

void Reader::finish_dynamic_channels() {
  const std::optional<std::uint32_t> supported = dynamic_channels_supported(model_);
  auto supported_it = device_info_.index.find(std::string_view("DynamicChannelsSupported"));
  const int supported_line =
      supported_it == device_info_.index.end() ? 0 : supported_it->second.second;
  if (!dynamic_.present) {
    // §8.4: "If the entry DynamicChannelsSupported is non-zero, the section DynamicChannels
    // describes the usable segments" (bit 2: DS-405 predefines them instead).
    if (supported && *supported != 0 &&
        (*supported & dynamic_channels_bit::kPredefinedSegments) == 0) {
      warn(supported_line, "[DeviceInfo] DynamicChannelsSupported is " + hex(*supported, 0) +
                               " but the file has no [DynamicChannels] section to describe the "
                               "segments (CiA DSP 302 §8.4)");
    }
    return;
  }
  // Unreadable (reported where it is read): taken as used, so the section's faults stay errors.
  const bool used = !supported || *supported != 0;
  if (!used) {
    warn(dynamic_.line, "[DynamicChannels] is given but [DeviceInfo] DynamicChannelsSupported is " +
                            std::string(supported_line == 0 ? "absent (0)" : "0") +
                            ": the segments are not used (CiA DSP 302 §8.4)");
  }
  DynamicChannelsReport report;
  // A section the device says it does not use changes nothing it is configured with: vendor
  // tools write placeholders there (NrOfSeg=1, Type1=0x0000, Range1=0x0000-0x0000). Its faults
  // are warnings in tolerant mode and errors under strict, as any deviation from the standard.
  report.error = [this, used](int line, std::string message) {
    if (used) {
      error(line, std::move(message));
    } else {
      warn(line, std::move(message) + " (the device does not use the section)");
    }
  };
  report.warn = [this](int line, std::string message) { warn(line, std::move(message)); };
  const DynamicChannels channels = read_dynamic_channels(dynamic_.keys, dynamic_.line, report);
  // §8.4: the segments' objects come into being when network variables are allocated (the DCF
  // of the programmed device, §8.5, has them); an EDS must not define any there. A file without
  // [DeviceComissioning] is taken as an EDS (CiA 306 §4.1: a DCF has that section).
  if (!used || model_.commissioning) return;
  for (std::size_t i = 0; i < channels.segments.size(); ++i) {
    const DynamicSegment& segment = channels.segments[i];
    for (auto it = model_.objects.lower_bound(segment.first_index);
         it != model_.objects.end() && it->first <= segment.last_index; ++it) {
      warn(it->second.line, "object " + object_name(it->first) +
                                " lies in dynamic channel segment " + std::to_string(i + 1) + " (" +
                                object_name(segment.first_index) + "-" +
                                object_name(segment.last_index) + ")" +
                                ": an EDS must not define objects in a segment, they are made "
                                "when network variables are allocated (CiA DSP 302 §8.4)");
    }
  }
}

}  // namespace reader
}  // namespace cfg::detail
