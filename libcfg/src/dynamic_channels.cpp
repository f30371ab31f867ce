// Dynamic index assignment (CiA DSP 302 §8.2); the choices are listed in cfg/dynamic_channels.hpp.
#include "cfg/dynamic_channels.hpp"

#include <algorithm>
#include <array>
#include <map>
#include <set>

#include "cfg/data_type.hpp"
#include "cfg/integer_literal.hpp"
#include "dynamic_channels_read.hpp"

namespace cfg {
namespace {

constexpr std::uint32_t kSubsPerIndex = 254;  // §8.2: sub-index 01h..FEh

bool is_boolean(const DynamicSegment& s) {
  return s.data_type == static_cast<std::uint16_t>(DataType::Boolean);
}

std::string type_name(std::uint16_t data_type) {
  if (const DataTypeInfo* info = find_data_type(data_type)) return std::string(info->name);
  return "type " + object_name(data_type);
}

std::string plural(VariableDirection d) {
  return d == VariableDirection::Input ? "inputs" : "outputs";
}

std::string segment_text(const DynamicChannels& channels, std::size_t i) {
  const DynamicSegment& s = channels.segments[i];
  return "segment " + std::to_string(i + 1) + " (" + object_name(s.first_index) + "-" +
         object_name(s.last_index) + ")";
}

// The bits allocated in one process picture: disjoint [start, end) intervals by start.
class Occupied {
 public:
  // The end of an allocated interval overlapping [start, start + width), or nullopt.
  std::optional<std::uint64_t> overlap(std::uint64_t start, std::uint64_t width) const {
    auto it = intervals_.lower_bound(start + width);
    if (it == intervals_.begin()) return std::nullopt;
    --it;  // the last interval starting before the end: the only one that can overlap
    if (it->second > start) return it->second;
    return std::nullopt;
  }
  void add(std::uint64_t start, std::uint64_t width) { intervals_.emplace(start, start + width); }

 private:
  std::map<std::uint64_t, std::uint64_t> intervals_;
};

}  // namespace

std::string_view to_string(SegmentDirection direction) {
  switch (direction) {
    case SegmentDirection::Ro:
      return "ro";
    case SegmentDirection::Wo:
      return "wo";
    case SegmentDirection::Rww:
      return "rww";
  }
  return "?";
}

std::optional<SegmentDirection> segment_direction_from_string(std::string_view text) {
  for (auto d : {SegmentDirection::Ro, SegmentDirection::Wo, SegmentDirection::Rww}) {
    if (iequals(text, to_string(d))) return d;
  }
  return std::nullopt;
}

std::optional<DynamicChannels> dynamic_channels_of(const DeviceDescription& device) {
  for (const RawSection& section : device.other_sections) {
    if (!iequals(section.name, "DynamicChannels")) continue;
    std::vector<detail::DynamicChannelsKey> keys;
    keys.reserve(section.keys.entries.size());
    // Line numbers mark a key as given; nothing is reported, so any positive number does.
    int line = 0;
    for (const auto& [key, value] : section.keys.entries) keys.push_back({key, value, ++line});
    return detail::read_dynamic_channels(keys, 0, {});
  }
  return std::nullopt;
}

std::optional<std::uint32_t> dynamic_channels_supported(const DeviceDescription& device) {
  const std::string* text = device.device_info.find("DynamicChannelsSupported");
  if (text == nullptr) return 0;  // CiA DSP 302 §8.4: "If the entry does not exist, it is 0"
  const IntegerLiteralResult n = parse_integer_literal(*text);
  if (!n.literal || n.literal->value > 0xFFFFFFFFU) return std::nullopt;
  return static_cast<std::uint32_t>(n.literal->value);
}

std::string_view to_string(VariableDirection direction) {
  return direction == VariableDirection::Input ? "in" : "out";
}

std::optional<VariableDirection> variable_direction_from_string(std::string_view text) {
  for (std::string_view in : {"in", "input", "ro"}) {
    if (iequals(text, in)) return VariableDirection::Input;
  }
  for (std::string_view out : {"out", "output", "wo", "rww"}) {
    if (iequals(text, out)) return VariableDirection::Output;
  }
  return std::nullopt;
}

VariableDirection direction_of(const DynamicSegment& segment) {
  return segment.direction == SegmentDirection::Ro ? VariableDirection::Input
                                                   : VariableDirection::Output;
}

bool is_usable(const DynamicSegment& segment) {
  const DataTypeInfo* info = find_data_type(segment.data_type);
  if (info == nullptr || info->size_bytes == 0) return false;
  if (segment.first_index > segment.last_index) return false;
  return !is_boolean(segment) || segment.bit_distance.value_or(0) >= 1;
}

std::uint32_t capacity(const DynamicSegment& segment) {
  if (segment.first_index > segment.last_index) return 0;
  const std::uint64_t by_range =
      (static_cast<std::uint64_t>(segment.last_index) - segment.first_index + 1) * kSubsPerIndex;
  return static_cast<std::uint32_t>(std::min<std::uint64_t>(segment.max_count, by_range));
}

ObjectAddress segment_address(const DynamicSegment& segment, std::uint32_t position) {
  return {static_cast<std::uint16_t>(segment.first_index + position / kSubsPerIndex),
          static_cast<std::uint8_t>(position % kSubsPerIndex + 1)};
}

std::optional<std::uint32_t> segment_position(const DynamicSegment& segment,
                                              const ObjectAddress& address) {
  if (address.index < segment.first_index || address.index > segment.last_index) {
    return std::nullopt;
  }
  if (address.sub_index == 0 || address.sub_index > kSubsPerIndex) return std::nullopt;
  const std::uint32_t p =
      static_cast<std::uint32_t>(address.index - segment.first_index) * kSubsPerIndex +
      address.sub_index - 1;
  if (p >= capacity(segment)) return std::nullopt;
  return p;
}

std::uint32_t stride_bits(const DynamicSegment& segment) {
  if (is_boolean(segment)) return segment.bit_distance.value_or(1);
  const DataTypeInfo* info = find_data_type(segment.data_type);
  return info == nullptr ? 0 : 8U * info->size_bytes;
}

std::uint32_t width_bits(const DynamicSegment& segment) {
  // §8.4: Booleans "packed in bytes one bit after the other" (1) or "each stored in a byte cell".
  if (is_boolean(segment)) return std::min<std::uint32_t>(segment.bit_distance.value_or(1), 8);
  return stride_bits(segment);
}

std::uint64_t process_picture_bit_offset(const DynamicSegment& segment, std::uint32_t position) {
  return std::uint64_t{segment.pp_offset} * 8 + std::uint64_t{position} * stride_bits(segment);
}

std::uint64_t segment_size_bytes(const DynamicSegment& segment) {
  const std::uint32_t n = capacity(segment);
  if (n == 0 || !is_usable(segment)) return 0;
  const std::uint64_t end_bits = std::uint64_t{n - 1} * stride_bits(segment) + width_bits(segment);
  return (end_bits + 7) / 8;
}

Result<std::vector<NetworkVariable>> parse_network_variables(std::string_view text,
                                                             std::string_view file_name) {
  std::vector<NetworkVariable> out;
  int line_number = 0;
  auto trim = [](std::string_view t) {
    while (!t.empty() && (t.front() == ' ' || t.front() == '\t')) t.remove_prefix(1);
    while (!t.empty() && (t.back() == ' ' || t.back() == '\t' || t.back() == '\r')) {
      t.remove_suffix(1);
    }
    return t;
  };
  while (!text.empty()) {
    ++line_number;
    const std::size_t eol = text.find('\n');
    const std::string_view line = trim(text.substr(0, eol));
    text = eol == std::string_view::npos ? std::string_view() : text.substr(eol + 1);
    auto fail = [&](const std::string& what) {
      return Error{std::string(file_name) + ":" + std::to_string(line_number) + ": " + what};
    };
    if (line.empty() || line.front() == '#') continue;
    std::vector<std::string_view> fields;
    std::size_t from = 0;
    for (std::size_t comma = line.find(','); comma != std::string_view::npos;
         comma = line.find(',', from)) {
      fields.push_back(trim(line.substr(from, comma - from)));
      from = comma + 1;
    }
    fields.push_back(trim(line.substr(from)));
    if (fields.size() != 3) {
      return fail("expected name,type,direction (3 fields), found " +
                  std::to_string(fields.size()));
    }
    if (out.empty() && iequals(fields[0], "name") && iequals(fields[1], "type") &&
        iequals(fields[2], "direction")) {
      continue;  // a header line
    }
    if (fields[0].empty()) return fail("the variable has no name");
    for (char c : fields[0]) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) {
        return fail("the name has a control character");
      }
    }
    std::optional<std::uint16_t> type;
    if (auto named = data_type_from_name(fields[1])) {
      type = static_cast<std::uint16_t>(*named);
    } else if (auto n = parse_integer_literal(fields[1]).literal; n && n->value <= 0xFFFF) {
      type = static_cast<std::uint16_t>(n->value);
    }
    const DataTypeInfo* info = type ? find_data_type(*type) : nullptr;
    if (info == nullptr || info->size_bytes == 0) {
      return fail("'" + std::string(fields[1]) +
                  "' is not a fixed-size CiA 301 data type (BOOLEAN, UNSIGNED8, INTEGER16, "
                  "REAL32, ... or its number, 0x0005)");
    }
    const std::optional<VariableDirection> direction = variable_direction_from_string(fields[2]);
    if (!direction) return fail("direction '" + std::string(fields[2]) + "' is not in or out");
    out.push_back({std::string(fields[0]), *type, *direction});
  }
  return out;
}

Result<std::vector<AllocatedVariable>> allocate_variables(
    const DynamicChannels& channels, std::span<const NetworkVariable> variables) {
  std::vector<AllocatedVariable> out;
  out.reserve(variables.size());
  std::array<Occupied, 2> pictures;  // by VariableDirection
  std::vector<std::uint32_t> next(channels.segments.size(), 0);
  std::set<std::string_view> names;
  for (const NetworkVariable& v : variables) {
    const std::string what = "variable '" + v.name + "'";
    if (v.name.empty()) return Error{"a network variable has no name"};
    if (!names.insert(v.name).second) return Error{what + " is given twice"};
    const DataTypeInfo* info = find_data_type(v.data_type);
    if (info == nullptr || info->size_bytes == 0) {
      return Error{what + ": " + type_name(v.data_type) +
                   " is not a fixed-size basic data type (CiA 301)"};
    }
    const std::string kind = std::string(info->name) + " " + plural(v.direction);
    Occupied& picture = pictures[static_cast<std::size_t>(v.direction)];
    bool any_segment = false;
    std::string full;
    std::optional<AllocatedVariable> placed;
    for (std::size_t i = 0; i < channels.segments.size() && !placed; ++i) {
      const DynamicSegment& s = channels.segments[i];
      if (s.data_type != v.data_type || direction_of(s) != v.direction || !is_usable(s)) continue;
      any_segment = true;
      const std::uint32_t limit = capacity(s);
      const std::uint64_t base = std::uint64_t{s.pp_offset} * 8;
      const std::uint32_t stride = stride_bits(s);
      const std::uint32_t width = width_bits(s);
      std::uint64_t p = next[i];
      while (p < limit) {
        const std::uint64_t bit = base + p * stride;
        const std::optional<std::uint64_t> end = picture.overlap(bit, width);
        if (!end) break;
        // §8.2: leave out the positions that would overlap; the next candidate starts at or
        // after the end of the variable in the way.
        p = std::max(p + 1, (*end - base + stride - 1) / stride);
      }
      if (p >= limit) {
        next[i] = limit;
        if (!full.empty()) full += "; ";
        full += segment_text(channels, i) + " is full (" +
                (limit == s.max_count ? "MaxCnt " + std::to_string(s.max_count) + " reached"
                                      : "its index range holds " + std::to_string(limit)) +
                ")";
        continue;
      }
      const auto position = static_cast<std::uint32_t>(p);
      next[i] = position + 1;
      AllocatedVariable a;
      a.variable = v;
      a.segment = i;
      a.position = position;
      a.address = segment_address(s, position);
      a.pp_bit_offset = process_picture_bit_offset(s, position);
      picture.add(a.pp_bit_offset, width);
      placed = std::move(a);
    }
    if (!any_segment) {
      std::string message = what;
      message += ": the device has no segment for ";
      message += kind;
      message += " ([DynamicChannels], CiA DSP 302 §8.2)";
      return Error{std::move(message)};
    }
    if (!placed) {
      std::string message = what;
      message += ": no room for ";
      message += kind;
      message += ": ";
      message += full;
      return Error{std::move(message)};
    }
    out.push_back(std::move(*placed));
  }
  return out;
}

Status add_variable_objects(DeviceDescription& device, const DynamicChannels& channels,
                            std::span<const AllocatedVariable> allocation) {
  for (const AllocatedVariable& a : allocation) {
    if (a.segment >= channels.segments.size()) {
      return Error{"variable '" + a.variable.name + "' names segment " +
                   std::to_string(a.segment + 1) + ", which the device does not have"};
    }
    if (device.object(a.address.index) != nullptr) {
      return Error{"variable '" + a.variable.name + "': object " + object_name(a.address.index) +
                   " exists already (is the device programmed? allocate into its EDS)"};
    }
  }
  std::map<std::uint16_t, Object> objects;
  for (const AllocatedVariable& a : allocation) {
    const DynamicSegment& s = channels.segments[a.segment];
    auto [it, inserted] = objects.try_emplace(a.address.index);
    Object& obj = it->second;
    if (inserted) {
      obj.index = a.address.index;
      obj.name = type_name(s.data_type) + " " + plural(direction_of(s));
      obj.object_type = ObjectType::Array;
    }
    SubObject sub;
    sub.sub_index = a.address.sub_index;
    sub.name = a.variable.name;
    sub.data_type = s.data_type;
    sub.access = s.direction == SegmentDirection::Ro   ? AccessType::Ro
                 : s.direction == SegmentDirection::Wo ? AccessType::Wo
                                                       : AccessType::Rww;
    sub.pdo_mapping = true;
    sub.default_value = OptionalText(std::string("0"));
    obj.subs.insert_or_assign(a.address.sub_index, std::move(sub));
  }
  for (auto& [index, obj] : objects) {
    SubObject count;
    count.name = "Highest sub-index supported";
    count.data_type = static_cast<std::uint16_t>(DataType::Unsigned8);
    count.access = AccessType::Ro;
    count.default_value = OptionalText(std::to_string(obj.subs.rbegin()->first));
    obj.subs.emplace(0, std::move(count));
    obj.sub_number = static_cast<std::uint8_t>(obj.subs.size());
    device.objects.insert_or_assign(index, std::move(obj));
  }
  return {};
}

}  // namespace cfg
